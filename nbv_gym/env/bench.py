"""Bench suite of the environment: ``env_step_ms`` and ``episode_s`` on pp1-trees, noise 1."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

WORLD = "pp1-trees"
STEPS = 20


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """One env step without optional layers (median over random valid goals) and one full
    closest-frontier episode, both single thread."""
    from nbv_gym.env import ExploreEnv
    from nbv_gym.episode import run_episode
    from nbv_gym.policies import load_policy

    env = ExploreEnv(world=WORLD, noise=1, max_steps=STEPS + 5)
    progress(f"{STEPS} env steps on {WORLD}")
    env.reset(seed=0)  # compiles and builds everything once
    _, info = env.reset(seed=1)
    rng, times = np.random.default_rng(0), []
    for _ in range(STEPS):
        goal = int(rng.choice(np.flatnonzero(info["action_mask"])))
        start = time.perf_counter()
        _, _, terminated, truncated, info = env.step(goal)
        times.append(time.perf_counter() - start)
        if terminated or truncated:
            _, info = env.reset(seed=len(times))
    progress(f"a closest-frontier episode on {WORLD}")
    episode = ExploreEnv(world=WORLD, noise=1)
    result = run_episode(episode, load_policy("closest-frontier"), seed=0)
    return {
        "env_step_ms": 1e3 * float(np.median(times)),
        "episode_s": result.wall_time_s,
        "episode_steps": float(len(result.steps) - 1),
    }
