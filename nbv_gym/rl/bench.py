"""Bench suite of RL training: ``train_steps_per_s`` on pp1-trees.

Environment steps per second of MaskablePPO training (rollouts and updates) with the default
config's ``n_envs`` and hyper-parameters, measured over two updates after one warm-up update
(worker start-up, compilation and world loading excluded).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

WORLD = "pp1-trees"
UPDATES = 2


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """``train_steps_per_s``: steps per second of MaskablePPO training on pp1-trees."""
    from nbv_gym.rl.config import TrainConfig
    from nbv_gym.rl.train import _create, make_vec_env, require_rl

    require_rl()
    import os

    os.environ["NUMBA_NUM_THREADS"] = "1"
    config = replace(TrainConfig(), train_worlds=(WORLD,), eval_worlds=())
    per_update = config.learning.n_steps * config.n_envs
    envs = make_vec_env(config)
    try:
        model = _create(config, envs, verbose=0)
        progress(f"MaskablePPO warm-up on {WORLD}: {config.n_envs} envs × {per_update} steps")
        model.learn(per_update)
        progress(f"MaskablePPO training on {WORLD}: {UPDATES} updates of {per_update} steps")
        start, steps = time.perf_counter(), model.num_timesteps
        model.learn(UPDATES * per_update, reset_num_timesteps=False)
        elapsed = time.perf_counter() - start
    finally:
        envs.close()
    return {"train_steps_per_s": (model.num_timesteps - steps) / elapsed}


if __name__ == "__main__":
    import sys

    print(run(lambda message: print(message, file=sys.stderr)))
