"""Training environments: ``Explore-v0`` cycling over a list of worlds, one world per episode, or
drawing from a world distribution (``random:…``) at every reset.

Workers of a ``VecEnv`` build these by name (:func:`make_world_cycle`), so they import nbv-gym
themselves; Embree's thread pool does not survive ``fork``, hence ``forkserver``. Nothing here
imports torch or stable-baselines3 (but SB3's ``Monitor`` when asked for), so the training
workers (:class:`~nbv_gym.rl.vecenv.LeanSubprocVecEnv`) stay without them.
"""

from __future__ import annotations

import time
from typing import Any

import gymnasium
import numpy as np

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.worlds import load_world


class WorldCycleEnv(gymnasium.Env):
    """``Explore-v0`` (or the ``task``'s environment) over ``worlds`` in turn: reset ``k`` explores
    ``worlds[k % len(worlds)]``; a single world distribution (``("random:mixed",)``) draws a world
    at every reset instead.

    Rewards are multiplied by ``reward_scale``. One environment serves every world: switching
    worlds swaps the scene and the ground truth and keeps the simulator's arrays.
    ``info["world"]`` names the episode's world. ``env_kwargs`` are
    :class:`~nbv_gym.env.ExploreEnv`'s keywords (``task``, ``noise``, ``max_steps`` — None: the
    time task's scan cap —, ``observation_layers``, ``invalid_action``: ``"snap"`` for learners
    that do not read ``action_masks()``, ``world_pool_size``, ``episodes_per_world``, the effort
    model's ``speed_mps`` and ``scan_time_s``, the time task's ``time_budget_s``, ``lidar``;
    :meth:`~nbv_gym.rl.config.TrainConfig.env_kwargs` gives a training's).
    """

    metadata = {"render_modes": []}  # noqa: RUF012 (gymnasium.Env declares it an instance attribute)

    def __init__(
        self, worlds: tuple[str, ...] | list[str], reward_scale: float = 1.0, **env_kwargs: Any
    ):
        self.worlds = tuple(worlds)
        self.reward_scale = reward_scale
        self.env = ExploreEnv(world=self.worlds[0], **env_kwargs)
        self._world, self._episodes = self.worlds[0], 0
        self.action_space = self.env.action_space
        self.observation_space = self.env.observation_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset on the next world of the cycle."""
        super().reset(seed=seed)
        world = self.worlds[self._episodes % len(self.worlds)]
        self._episodes += 1
        if world != self._world:
            self.env.sim.set_world(load_world(world))
            self._world = world
        return self.env.reset(seed=int(self.np_random.integers(2**31 - 1)))

    def step(self, action):
        """Step the wrapped environment; the reward times ``reward_scale``."""
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, self.reward_scale * reward, terminated, truncated, info

    def action_masks(self) -> np.ndarray:
        """(n_goals,) int8: the valid goals of the current episode."""
        return self.env.action_masks()


class EpisodeMonitor(gymnasium.Wrapper):
    """SB3's ``Monitor`` without SB3 (whose import brings torch): at an episode's end
    ``info["episode"]`` holds the return ``r`` (rounded to 6 digits), the length ``l``, the
    seconds ``t`` since this wrapper was made, and ``info[key]`` for each of ``info_keywords``.
    SB3 logs ``r`` and ``l``; :class:`~nbv_gym.rl.callbacks.EpisodeLog` writes them out."""

    def __init__(self, env: gymnasium.Env, info_keywords: tuple[str, ...] = ()):
        super().__init__(env)
        self.info_keywords = info_keywords
        self.t_start = time.time()
        self.rewards: list[float] = []

    def reset(self, **kwargs):
        """Reset the wrapped environment and the episode's rewards."""
        self.rewards = []
        return self.env.reset(**kwargs)

    def step(self, action):
        """Step the wrapped environment; at an episode's end add ``info["episode"]``."""
        observation, reward, terminated, truncated, info = self.env.step(action)
        self.rewards.append(float(reward))
        if terminated or truncated:
            info["episode"] = {
                "r": round(sum(self.rewards), 6),  # summed as SB3's Monitor sums
                "l": len(self.rewards),
                "t": round(time.time() - self.t_start, 6),
                **{key: info[key] for key in self.info_keywords},
            }
        return observation, reward, terminated, truncated, info


#: What :func:`make_world_cycle` wraps its environment in: ``"lean"`` (:class:`EpisodeMonitor`,
#: for training workers), ``"sb3"`` (SB3's ``Monitor``, which SB3's evaluation recognises), None.
MONITORS = ("lean", "sb3", None)
#: The step infos copied into ``info["episode"]``.
EPISODE_INFO_KEYS = ("q", "discovered")


def make_world_cycle(monitor: str | None = "lean", **kwargs: Any) -> gymnasium.Env:
    """A :class:`WorldCycleEnv` (``kwargs`` go to it) wrapped in the episode monitor ``monitor``
    (one of :data:`MONITORS`), so episode returns and lengths reach the logs."""
    if monitor not in MONITORS:
        raise ValueError(f"monitor: expected one of {MONITORS}, got {monitor!r}")
    env = WorldCycleEnv(**kwargs)
    if monitor is None:
        return env
    if monitor == "lean":
        return EpisodeMonitor(env, info_keywords=EPISODE_INFO_KEYS)
    from stable_baselines3.common.monitor import Monitor

    return Monitor(env, info_keywords=EPISODE_INFO_KEYS)
