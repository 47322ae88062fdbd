"""Perf suite of RL training on pp1-trees: ``train_steps_per_s`` and where its time goes.

MaskablePPO training with the default config's ``n_envs`` and hyper-parameters, measured over
:data:`UPDATES` updates after one warm-up update (worker start-up, compilation and world loading
excluded):

- ``train_steps_per_s``: environment steps per second of wall time, rollouts and updates;
- ``train_env_ms_per_step``: wall ms per environment step waiting for the environments (steps,
  resets and action masks, computed in the workers and sent through the pipes);
- ``train_policy_ms_per_step``: the rest of the rollouts (the policy's forward passes, the
  rollout buffer);
- ``train_update_ms_per_step``: the PPO updates (the environments idle meanwhile).

The last three add up to ``1000 / train_steps_per_s`` (up to SB3's bookkeeping between updates).

- ``train_step_raw``: ``1000 / train_steps_per_s`` in raw casts: over the CPU ms of one raw
  Embree cast of a scan's rays from the world's start pose (median of :data:`RAW_CASTS`, as
  ``env_raw_cast_ms`` of the env suite), so that it compares across machines.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

from nbv_gym.perf import PERF_WORLD

UPDATES = 2
RAW_CASTS = 9


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """The suite's figures (module docstring) for MaskablePPO training on :data:`PERF_WORLD`."""
    from nbv_gym.rl.config import TrainConfig
    from nbv_gym.rl.learner import prepare_learner
    from nbv_gym.rl.train import create_model, make_vec_env, require_rl

    require_rl()
    from nbv_gym.rl.callbacks import PhaseTimer, TimedVecEnv, TorchThreads

    config = replace(TrainConfig(), train_worlds=(PERF_WORLD,), eval_worlds=())
    threads = TorchThreads(*prepare_learner(config.torch_threads, config.n_envs))
    per_update = config.learning.n_steps * config.n_envs
    envs = TimedVecEnv(make_vec_env(config))
    try:
        model = create_model(config, envs, verbose=0)
        progress(f"MaskablePPO warm-up on {PERF_WORLD}: {config.n_envs} envs × {per_update} steps")
        model.learn(per_update, callback=threads)
        progress(f"MaskablePPO training on {PERF_WORLD}: {UPDATES} updates of {per_update} steps")
        phases, envs.seconds = PhaseTimer(), 0.0
        start, steps = time.perf_counter(), model.num_timesteps
        model.learn(UPDATES * per_update, reset_num_timesteps=False, callback=[phases, threads])
        elapsed = time.perf_counter() - start
    finally:
        envs.close()
    steps = model.num_timesteps - steps
    raw_ms = _raw_cast_ms(config)
    return {
        "train_steps_per_s": steps / elapsed,
        "train_step_raw": 1000 * elapsed / steps / raw_ms,
        "train_env_ms_per_step": 1000 * envs.seconds / steps,
        "train_policy_ms_per_step": 1000 * (phases.rollout_s - envs.seconds) / steps,
        "train_update_ms_per_step": 1000 * phases.update_s / steps,
    }


def _raw_cast_ms(config) -> float:
    """CPU ms of a raw cast from the start pose of an environment of ``config`` (median)."""
    import numpy as np

    from nbv_gym.perf.env import raw_cast_s
    from nbv_gym.rl.train import _env_factory

    env = _env_factory(config, config.train_worlds)
    try:
        env.reset(seed=config.seed)
        sim = env.unwrapped.env.sim  # the world cycle's ExploreEnv
        return 1000 * float(np.median([raw_cast_s(sim) for _ in range(RAW_CASTS)]))
    finally:
        env.close()


if __name__ == "__main__":
    import sys

    print(run(lambda message: print(message, file=sys.stderr)))
