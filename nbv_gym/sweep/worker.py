"""One run of a sweep, as executed in a worker process (local pool or Dask worker).

This module imports only the standard library at the top, so that a worker can cap numba's thread
count before numba is first imported. :func:`execute_run` never raises for a failing run: it
returns a failure record with the error and its traceback, and the parent decides on retries.
"""

from __future__ import annotations

import os
import platform
import sys
import time
import traceback
from dataclasses import dataclass
from typing import Any

from nbv_gym.sweep.config import RunSpec

#: Environment a worker process needs: one numba thread per worker (the pool is the parallelism).
WORKER_ENVIRONMENT = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


@dataclass(frozen=True)
class RunTask:
    """What a worker needs for one run: the run, its ``EnvConfig`` as a plain dict, folders to
    add to ``sys.path`` (for ``module:Class`` policies) and the attempt number (1, 2, …)."""

    spec: RunSpec
    env: dict[str, Any]
    python_path: tuple[str, ...] = ()
    attempt: int = 1


def execute_run(task: RunTask) -> dict[str, Any]:
    """Run one episode; returns ``{"ok": True, "run": row, "steps": rows, "cuboids": arrays}``
    or ``{"ok": False, "error": str, "traceback": str}``."""
    start = time.perf_counter()
    try:
        _prepare_process(task.python_path)
        outcome = _run(task)
    except Exception as error:
        return failure(error, traceback.format_exc())
    outcome["run"]["total_time_s"] = time.perf_counter() - start
    return outcome


def failure(error: BaseException, trace: str = "") -> dict[str, Any]:
    """A failure record for ``error``."""
    return {
        "ok": False,
        "error": f"{type(error).__name__}: {error}",
        "traceback": trace or "".join(traceback.format_exception_only(type(error), error)),
        "host": platform.node(),
        "pid": os.getpid(),
    }


def _prepare_process(python_path: tuple[str, ...]) -> None:
    for name, value in WORKER_ENVIRONMENT.items():
        os.environ.setdefault(name, value)
    for folder in python_path:
        if folder not in sys.path:
            sys.path.append(folder)
    import numba

    numba.set_num_threads(1)


def _run(task: RunTask) -> dict[str, Any]:
    from nbv_gym.config import from_dict
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env, run_episode
    from nbv_gym.policies import load_policy

    spec = task.spec
    policy = load_policy(spec.policy)
    env = make_env(from_dict(EnvConfig, task.env), policy)
    try:
        result = run_episode(env, policy, spec.seed)
        cuboids = cuboid_arrays(env)
        asset = asset_type(env.sim.world.spec)
    finally:
        env.close()
    final = result.final
    run = {
        "key": spec.key,
        "world": spec.world,
        "asset": asset,
        "noise": spec.noise,
        "policy": spec.policy,
        "repeat": spec.repeat,
        "seed": spec.seed,
        "status": "ok",
        "steps": len(result.steps) - 1,
        "end_reason": result.end_reason,
        "discovered": final["discovered"],
        "q": final["q"],
        "q_paper": final["q_paper"],
        "path_length_m": final["path_length_m"],
        "wall_time_s": result.wall_time_s,
        "attempts": task.attempt,
        "host": platform.node(),
    }
    return {"ok": True, "run": run, "steps": result.steps, "cuboids": cuboids}


def asset_type(spec) -> str:
    """The asset type of a world spec, or ``"mixed"`` when it mixes several."""
    kinds = [kind for kind, weight in spec.assets.mix.items() if weight > 0]
    return kinds[0] if len(kinds) == 1 else "mixed"


def cov_column(p: float, d_m: float) -> str:
    """Column name of the coverage setting (p, d), e.g. ``cov_p0.7_d0.15``."""
    return f"cov_p{p:g}_d{d_m:g}"


def cuboid_arrays(env) -> dict[str, Any]:
    """End-of-run per-cuboid statistics and quality of the cuboids that were observed (map
    evidence or at least one viewpoint), as 1-D arrays of equal length (see the results layout
    in :mod:`nbv_gym.sweep.store`)."""
    import numpy as np

    metrics = env.sim.quality.metrics()
    stats = env.sim.state.statistics
    n_obs = stats.n_obs
    if n_obs.shape != metrics.u_occ.shape:
        raise ValueError(
            f"statistics grid {n_obs.shape} and cuboid grid {metrics.u_occ.shape} differ; "
            "per-cuboid tables need RES = cuboid size"
        )
    keep = ((n_obs > 0) | metrics.observed).ravel()
    index = np.flatnonzero(keep)
    ix, iy, iz = np.unravel_index(index, n_obs.shape)
    config = metrics.config
    columns = {
        "cuboid": index.astype(np.int32),
        "ix": ix.astype(np.int16),
        "iy": iy.astype(np.int16),
        "iz": iz.astype(np.int16),
        "u_occ": metrics.u_occ.ravel()[keep],
        "observed": metrics.observed.ravel()[keep],
        "n_obs": n_obs.ravel()[keep].astype(np.int32),
        "r_min": stats.r_min.ravel()[keep].astype(np.float32),
        "n_omega": stats.n_omega.ravel()[keep].astype(np.int16),
        "sigma_theta": stats.sigma_theta.ravel()[keep].astype(np.float32),
    }
    for (p, d), cov in zip(config.cov_settings, metrics.cov, strict=True):
        columns[cov_column(p, d)] = cov.ravel()[keep].astype(np.float32)
    columns["cov_q"] = metrics.cov[config.q_setting].ravel()[keep].astype(np.float32)
    columns["l1"] = metrics.l1.ravel()[keep].astype(np.float32)
    columns["quality"] = metrics.quality.ravel()[keep].astype(np.float32)
    return columns
