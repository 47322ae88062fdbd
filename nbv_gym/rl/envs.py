"""Training environments: ``Explore-v0`` cycling over a list of worlds, one world per episode, or
drawing from a world distribution (``random:…``) at every reset.

Workers of a ``SubprocVecEnv`` build these by name (:func:`make_world_cycle`), so they import
nbv-gym themselves; Embree's thread pool does not survive ``fork``, hence ``forkserver``.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.tasks import EXPLORE_MAX_STEPS
from nbv_gym.worlds import load_world
from nbv_gym.worlds.distribution import POOL_SIZE


class WorldCycleEnv(gymnasium.Env):
    """``Explore-v0`` (or the ``task``'s environment) over ``worlds`` in turn: reset ``k`` explores
    ``worlds[k % len(worlds)]``; a single world distribution (``("random:mixed",)``) draws a world
    at every reset instead.

    Rewards are multiplied by ``reward_scale``. ``invalid_action`` is the environment's option
    (``"snap"`` for learners that do not read ``action_masks()``). One environment serves every
    world: switching worlds swaps the scene and the ground truth and keeps the simulator's
    arrays. ``info["world"]`` names the episode's world; ``world_pool_size`` and
    ``episodes_per_world`` are the distribution's options (:class:`~nbv_gym.env.EnvConfig`).
    """

    metadata = {"render_modes": []}

    def __init__(
        self,
        worlds: tuple[str, ...] | list[str],
        noise: int = 1,
        max_steps: int = EXPLORE_MAX_STEPS,
        observation_layers: tuple[str, ...] | list[str] = (),
        reward_scale: float = 1.0,
        invalid_action: str = "raise",
        task: str = "explore",
        world_pool_size: int = POOL_SIZE,
        episodes_per_world: int = 1,
    ):
        self.worlds = tuple(worlds)
        self.reward_scale = reward_scale
        self.env = ExploreEnv(
            task=task,
            world=self.worlds[0],
            noise=noise,
            max_steps=max_steps,
            observation_layers=tuple(observation_layers),
            invalid_action=invalid_action,
            world_pool_size=world_pool_size,
            episodes_per_world=episodes_per_world,
        )
        self._world, self._episodes = self.worlds[0], 0
        self.action_space = self.env.action_space
        self.observation_space = self.env.observation_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        world = self.worlds[self._episodes % len(self.worlds)]
        self._episodes += 1
        if world != self._world:
            self.env.sim.set_world(load_world(world))
            self._world = world
        return self.env.reset(seed=int(self.np_random.integers(2**31 - 1)))

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, self.reward_scale * reward, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """(n_goals,) int8: the valid goals of the current episode."""
        return self.env.action_masks()


def make_world_cycle(monitor: bool = True, **kwargs: Any) -> gymnasium.Env:
    """A :class:`WorldCycleEnv` (``kwargs`` go to it), wrapped in SB3's ``Monitor`` so episode
    returns and lengths reach the logs."""
    env = WorldCycleEnv(**kwargs)
    if not monitor:
        return env
    from stable_baselines3.common.monitor import Monitor

    return Monitor(env, info_keywords=("q", "discovered"))
