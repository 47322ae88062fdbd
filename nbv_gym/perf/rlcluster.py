"""Perf suite of training environments on a Dask cluster: env steps/s of a localhost
LocalCluster of 2 worker processes (:class:`~nbv_gym.rl.daskvec.DaskVecEnv`, one actor per
worker) against the local lean workers (:class:`~nbv_gym.rl.vecenv.LeanSubprocVecEnv`) with the
same :data:`N_ENVS` environments of the default training config on pp1-trees.

Both step the same trajectories (same seeds, the same random valid goals, the action masks asked
for before every step as MaskablePPO does) in :data:`ROUNDS` interleaved rounds of
:data:`ROUND_STEPS` vector steps after one warm-up round (start-up and world loading excluded):

- ``cluster_env_steps_per_s``, ``local_env_steps_per_s``: environment steps per second of wall
  time of each;
- ``cluster_over_local``: their ratio (1: the cluster costs nothing over local workers).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from nbv_gym.perf import PERF_WORLD

N_ENVS = 2
ROUNDS = 4
ROUND_STEPS = 12


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """The suite's figures (module docstring)."""
    from nbv_gym.rl.config import TrainConfig
    from nbv_gym.rl.train import make_vec_env, require_rl

    require_rl()
    config = replace(TrainConfig(), train_worlds=(PERF_WORLD,), eval_worlds=(), n_envs=N_ENVS)
    progress(f"starting {N_ENVS} local lean workers and a LocalCluster of {N_ENVS} workers")
    paths = {
        "local": make_vec_env(config),
        "cluster": make_vec_env(replace(config, scheduler="local")),
    }
    try:
        rngs = {name: np.random.default_rng(0) for name in paths}
        for name, envs in paths.items():
            envs.seed(config.seed)
            envs.reset()
            _steps(envs, ROUND_STEPS, rngs[name])  # warm-up
        seconds = dict.fromkeys(paths, 0.0)
        for k in range(ROUNDS):
            progress(f"round {k + 1}/{ROUNDS}: {ROUND_STEPS} vector steps on each")
            for name, envs in paths.items():
                seconds[name] += _steps(envs, ROUND_STEPS, rngs[name])
    finally:
        for envs in paths.values():
            envs.close()
    rate = {name: ROUNDS * ROUND_STEPS * N_ENVS / s for name, s in seconds.items()}
    return {
        "cluster_env_steps_per_s": rate["cluster"],
        "local_env_steps_per_s": rate["local"],
        "cluster_over_local": rate["cluster"] / rate["local"],
    }


def _steps(envs, steps: int, rng) -> float:
    """Wall seconds of ``steps`` vector steps of random valid goals drawn from ``rng``."""
    start = time.perf_counter()
    for _ in range(steps):
        masks = envs.env_method("action_masks")
        envs.step(np.array([rng.choice(np.flatnonzero(mask)) for mask in masks]))
    return time.perf_counter() - start


if __name__ == "__main__":
    import sys

    print(run(lambda message: print(message, file=sys.stderr)))
