"""Training environments: ``Explore-v0`` cycling over a list of worlds, one world per episode.

Workers of a ``SubprocVecEnv`` build these by name (:func:`make_world_cycle`), so they import
nbv-gym themselves; Embree's thread pool does not survive ``fork``, hence ``forkserver``.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from nbv_gym.env.explore import ExploreEnv


class WorldCycleEnv(gymnasium.Env):
    """``Explore-v0`` over ``worlds`` in turn: reset ``k`` explores ``worlds[k % len(worlds)]``.

    Rewards are multiplied by ``reward_scale``. With ``snap_invalid`` an invalid goal is replaced
    by the nearest valid one (for learners that do not read ``action_masks()``). ``info["world"]``
    names the episode's world. Each world's environment is built on first use and kept.
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        worlds: tuple[str, ...] | list[str],
        noise: int = 1,
        max_steps: int = 100,
        observation_layers: tuple[str, ...] | list[str] = (),
        reward_scale: float = 1.0,
        snap_invalid: bool = False,
    ):
        self.worlds = tuple(worlds)
        self.reward_scale = reward_scale
        self.snap_invalid = snap_invalid
        self._kwargs = {
            "noise": noise,
            "max_steps": max_steps,
            "observation_layers": tuple(observation_layers),
        }
        self._envs: dict[str, ExploreEnv] = {}
        self._episodes = 0
        self.env = self._env(self.worlds[0])
        self.action_space = self.env.action_space
        self.observation_space = self.env.observation_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        world = self.worlds[self._episodes % len(self.worlds)]
        self._episodes += 1
        self.env = self._env(world)
        observation, info = self.env.reset(seed=int(self.np_random.integers(2**31 - 1)))
        return observation, {**info, "world": world}

    def step(self, action):
        goal = int(action)
        if self.snap_invalid:
            goal = nearest_valid_goal(goal, self.env.action_masks())
        observation, reward, terminated, truncated, info = self.env.step(goal)
        info = {**info, "world": self.env.config.simulator.world}
        return observation, self.reward_scale * reward, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """(n_goals,) bool: the valid goals of the current episode."""
        return self.env.action_masks()

    def _env(self, world: str) -> ExploreEnv:
        if world not in self._envs:
            self._envs[world] = ExploreEnv(world=world, **self._kwargs)
        return self._envs[world]


def nearest_valid_goal(goal: int, mask: np.ndarray) -> int:
    """``goal`` if valid, else the valid goal nearest to it on the square goal grid."""
    mask = np.asarray(mask, bool).ravel()
    if mask[goal] or not mask.any():
        return int(goal)
    side = int(np.sqrt(mask.size))
    valid = np.flatnonzero(mask)
    rows, cols = np.divmod(valid, side)
    row, col = divmod(int(goal), side)
    return int(valid[np.argmin((rows - row) ** 2 + (cols - col) ** 2)])


def make_world_cycle(monitor: bool = True, **kwargs: Any) -> gymnasium.Env:
    """A :class:`WorldCycleEnv` (``kwargs`` go to it), wrapped in SB3's ``Monitor`` so episode
    returns and lengths reach the logs."""
    env = WorldCycleEnv(**kwargs)
    if not monitor:
        return env
    from stable_baselines3.common.monitor import Monitor

    return Monitor(env, info_keywords=("q", "discovered"))
