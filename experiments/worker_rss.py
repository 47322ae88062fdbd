"""Resident memory of the training workers (issue 14: ≤ 400 MiB after five worlds): the training
``VecEnv`` of a config (``make_vec_env``), stepped with random valid goals until every worker has
explored ``--worlds`` worlds; each worker's VmRSS, RssAnon and RssFile (MiB, from /proc) and
whether it mapped torch's library, at start and at every world switch. Linux only.

    python experiments/worker_rss.py --config nbv_gym/configs/train/ppo.toml --worlds 5
    python experiments/worker_rss.py --vecenv sb3   # SB3's SubprocVecEnv and Monitor, as before

This file imports neither torch nor SB3 at the top: the workers import the main module (as
``nbv-gym train``'s workers import its tiny console script), and it must not bring torch.
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import numpy as np


def status(pid: int) -> dict:
    """VmRSS, RssAnon, RssFile (MiB) of process ``pid`` and whether it mapped libtorch."""
    fields = {}
    for line in open(f"/proc/{pid}/status"):
        key, _, value = line.partition(":")
        if key in ("VmRSS", "RssAnon", "RssFile"):
            fields[key] = int(value.split()[0]) // 1024
    fields["torch"] = "libtorch" in open(f"/proc/{pid}/maps").read()
    return fields


def make_envs(config, vecenv: str):
    """The training ``VecEnv`` of ``config``; ``vecenv="sb3"``: SB3's ``SubprocVecEnv`` with SB3's
    ``Monitor`` in the workers (the training workers before issue 14)."""
    from nbv_gym.rl import train

    if vecenv == "lean":
        return train.make_vec_env(config)
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from nbv_gym.sweep.worker import worker_environment

    worlds = [train._share(config.train_worlds, i, config.n_envs) for i in range(config.n_envs)]
    factories = [partial(train._env_factory, config, w, monitor="sb3") for w in worlds]
    with worker_environment():
        envs = SubprocVecEnv(factories, start_method="forkserver")
    envs.seed(config.seed)
    return envs


def run(config_path: str, n_worlds: int, vecenv: str, seed: int) -> list[dict]:
    """Step until every worker has explored ``n_worlds`` worlds; print and return the workers'
    status then."""
    from sb3_contrib.common.maskable.utils import get_action_masks

    from nbv_gym.rl.config import load_train_config

    envs = make_envs(load_train_config(config_path, {"seed": seed}), vecenv)
    pids = [process.pid for process in envs.processes]
    print("start", [status(pid) for pid in pids], flush=True)
    rng, start = np.random.default_rng(seed), time.perf_counter()
    seen: list[list[str]] = [[] for _ in pids]
    envs.reset()
    try:
        while min(map(len, seen)) <= n_worlds:  # until every worker switched past its n-th
            actions = [rng.choice(np.flatnonzero(mask)) for mask in get_action_masks(envs)]
            *_, infos = envs.step(np.array(actions))
            for i, info in enumerate(infos):
                if not seen[i] or seen[i][-1] != info["world"]:
                    seen[i].append(info["world"])
                    print(f"worker {i} world {len(seen[i])} {info['world']}", status(pids[i]))
        final = [status(pid) for pid in pids]
    finally:
        envs.close()
    print(f"after {n_worlds} worlds ({time.perf_counter() - start:.0f} s):", final)
    return final


def main() -> None:
    """Parse the command line and run the measurement (``--help`` lists the options)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default="nbv_gym/configs/train/ppo.toml")
    parser.add_argument("--worlds", type=int, default=5)
    parser.add_argument("--vecenv", choices=("lean", "sb3"), default="lean")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    run(args.config, args.worlds, args.vecenv, args.seed)


if __name__ == "__main__":
    main()
