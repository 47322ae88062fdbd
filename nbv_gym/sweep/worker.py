"""One run of a sweep, as executed in a worker process (local pool or Dask worker).

This module imports only the standard library at the top, so that a worker can cap numba's thread
count before numba is first imported. :func:`execute_run` never raises for a failing run: it
returns a failure record with the error and its traceback, and the parent decides on retries.
:func:`serve` is the main loop of a local pool's worker process; it exits when the sweep's main
process dies, however it dies.
"""

from __future__ import annotations

import os
import platform
import signal
import time
import traceback
from dataclasses import dataclass
from typing import Any

from nbv_gym.core.processes import WORKER_ENVIRONMENT, exit_with_parent
from nbv_gym.core.progress import speak_if_asked
from nbv_gym.policies.registry import add_policy_folders
from nbv_gym.sweep.config import RunSpec


@dataclass(frozen=True)
class RunTask:
    """What a worker needs for one run: the run, its ``EnvConfig`` as a plain dict, folders to
    add to ``sys.path`` (for ``module:Class`` policies) and the attempt number (1, 2, …)."""

    spec: RunSpec
    env: dict[str, Any]
    python_path: tuple[str, ...] = ()
    attempt: int = 1
    timeout_s: float | None = None


class RunTimeoutError(TimeoutError):
    """A run took longer than the sweep's ``run_timeout_s``."""

    def __init__(self, timeout_s: float):
        super().__init__(f"timed out after {timeout_s:g} s (the sweep's run_timeout_s)")


class WorkerDiedError(RuntimeError):
    """The process running a run ended before the run did."""


def timed_out(timeout_s: float) -> dict[str, Any]:
    """The failure record of a run stopped after ``timeout_s`` seconds."""
    return failure(RunTimeoutError(timeout_s))


#: What a pool worker sends when it starts a run (its outcome follows when the run ends).
STARTED = "started"


def serve(connection, alive) -> None:
    """Main loop of a pool worker: import what runs need, then for each :class:`RunTask`
    received on ``connection`` send :data:`STARTED`, run it and send its outcome, until the
    connection closes. ``alive``: the read end of a pipe whose write end only the sweep's main
    process holds; when it reaches end-of-file (the main process ended, even by ``kill -9``)
    this process exits at once, mid-run or not."""
    exit_with_parent(alive)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the main process's to handle
    speak_if_asked()
    _warm_up()

    while True:
        try:
            task = connection.recv()
            connection.send(STARTED)
        except (EOFError, OSError):
            return
        outcome = execute_run(task)
        try:
            connection.send(outcome)
        except (EOFError, OSError):
            return
        except Exception as error:  # the outcome cannot be pickled
            connection.send(failure(error, traceback.format_exc()))


def _warm_up() -> None:
    """Import what a run needs before the first run's clock starts (an import error is left
    for the run to report)."""
    try:
        _prepare_process(())
        import nbv_gym.episode  # noqa: F401
    except Exception:
        pass


def execute_run(task: RunTask) -> dict[str, Any]:
    """Run one episode; returns ``{"ok": True, "run": row, "steps": rows, "cuboids": arrays}``
    or ``{"ok": False, "error": str, "traceback": str}``."""
    start = time.perf_counter()
    try:
        _prepare_process(task.python_path)
        outcome = _run(task, _deadline(task.timeout_s, start))
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
    add_policy_folders(python_path)
    import numba

    numba.set_num_threads(1)


def _deadline(timeout_s: float | None, start: float):
    """A per-step check that raises :class:`RunTimeoutError` once ``timeout_s`` has passed
    since ``start`` (a run that is slow but not stuck stops on any backend; a stuck one is
    stopped by the backend)."""

    def check(row, env) -> None:
        if timeout_s is not None and time.perf_counter() - start > timeout_s:
            raise RunTimeoutError(timeout_s)

    return check


def run_here(task: RunTask) -> dict[str, Any]:
    """One run in the calling process, as a worker runs it (the same outcome as
    :func:`execute_run`'s) but leaving the process as it is — its numba threads, ``sys.path``
    — and raising what the run raises (a re-run of a scorecard's run, a test)."""
    return _run(task, None)


def _run(task: RunTask, on_step) -> dict[str, Any]:
    from nbv_gym.core.config import from_dict
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env, run_episode
    from nbv_gym.policies import load_policy
    from nbv_gym.worlds.spec import asset_type

    spec = task.spec
    policy = load_policy(spec.policy)
    env = make_env(from_dict(EnvConfig, task.env), policy)
    clock = DecisionClock(policy)
    try:
        result = run_episode(env, policy, spec.seed, on_step)
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
        "oracle": result.oracle,  # as the episode read it: what the run used
        "status": "ok",
        "steps": len(result.steps) - 1,
        "end_reason": result.end_reason,
        "discovered": final["discovered"],
        "q": final["q"],
        "q_paper": final["q_paper"],
        "path_length_m": final["path_length_m"],
        "elapsed_s": final["elapsed_s"],
        "wall_time_s": result.wall_time_s,
        "decision_time_s": clock.mean_s,
        "attempts": task.attempt,
        "host": platform.node(),
    }
    return {"ok": True, "run": run, "steps": result.steps, "cuboids": cuboids}


class DecisionClock:
    """The time ``policy.act`` takes, measured around each call without changing what the policy
    receives or returns: the instance's ``act`` is replaced by a timing wrapper (its class is left
    as it is). A policy whose instance takes no attributes (``__slots__``) is not timed."""

    def __init__(self, policy: Any):
        self.seconds = 0.0
        self.calls = 0
        act = policy.act

        def timed(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return act(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start
                self.calls += 1

        try:
            policy.act = timed
        except AttributeError:
            pass

    @property
    def mean_s(self) -> float:
        """Mean seconds per ``act`` call; NaN before the first call (or when not timed)."""
        return self.seconds / self.calls if self.calls else float("nan")


def cov_column(p: float, d_m: float) -> str:
    """Column name of the coverage setting (p, d), e.g. ``cov_p0.7_d0.15``."""
    return f"cov_p{p:g}_d{d_m:g}"


def cuboid_arrays(env) -> dict[str, Any]:
    """End-of-run per-cuboid statistics and quality of the cuboids that were observed (map
    evidence or at least one viewpoint), as 1-D arrays of equal length (see the results layout
    in :mod:`nbv_gym.sweep.folder`)."""
    import numpy as np

    metrics = env.sim.quality.metrics()
    stats = env.sim.statistics
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
