"""Run a sweep: resume from the results folder, farm the remaining runs out to a backend, record
each finished run atomically and each failure with its traceback, retry failures, consolidate.

Reads like the protocol: prepare the folder → list the runs not yet finished → keep the backend
busy → write every outcome as it comes → retry failures up to the limit → build the tables.
"""

from __future__ import annotations

import os
import time
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from nbv_gym.core.config import to_dict
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.progress import progress_bar
from nbv_gym.sweep.config import RunSpec, SweepConfig
from nbv_gym.sweep.folder import ResultStore, SweepError
from nbv_gym.sweep.worker import RunTask


@dataclass
class SweepSummary:
    """What one invocation did: runs in the config, already finished before, finished now,
    failed for good now (key → last error), wall time and the backend used."""

    total: int = 0
    resumed: int = 0
    finished: int = 0
    failed: dict[str, str] = field(default_factory=dict)
    failed_attempts: int = 0
    wall_time_s: float = 0.0
    backend: str = ""
    tables: dict[str, Path] = field(default_factory=dict)
    set_aside: list[str] = field(default_factory=list)


def run_sweep(
    config: SweepConfig,
    out: str | Path,
    workers: int | None = None,
    scheduler: str | None = None,
    python_path: tuple[str, ...] = (),
    progress: bool = True,
) -> SweepSummary:
    """Run every run of ``config`` not yet finished in ``out``; see :mod:`nbv_gym.sweep.folder`
    for the folder layout. ``workers``: local processes (default: all cores) or LocalCluster
    workers; ``scheduler``: a Dask scheduler address or ``"local"``; ``python_path``: folders
    where ``module:Class`` policies are found (added to ``sys.path`` here and in workers).

    Nothing is written to ``out`` before the policies loaded and the backend started; another
    sweep writing to ``out`` is refused. Unreadable run files found in ``out`` are moved aside
    and their runs done again (listed in the summary's ``set_aside``)."""
    from nbv_gym.sweep.backends import make_backend

    start = time.perf_counter()
    python_path = tuple(str(Path(p).resolve()) for p in python_path)
    _check_policies(config, python_path)
    store = ResultStore(out)
    backend = make_backend(workers, scheduler, config.run_timeout_s)
    try:
        store.prepare(config)
        runs = config.runs()
        finished = store.finished_stems()
        todo = [spec for spec in runs if spec.file_stem not in finished]
        summary = SweepSummary(total=len(runs), resumed=len(runs) - len(todo))
        if todo:
            summary.backend = backend.description
            _drive(backend, store, config, todo, python_path, summary, progress)
        summary.tables = store.consolidate()
    except OSError as error:  # e.g. the folder became read-only mid-sweep
        raise SweepError(
            f"Cannot write the results to {out}: {error}. Finished runs are kept; make the "
            "folder writable and rerun the same command."
        ) from None
    finally:
        backend.close()
        store.release()
    summary.set_aside = store.set_aside
    summary.wall_time_s = time.perf_counter() - start
    return summary


def _drive(backend, store, config, todo, python_path, summary, progress) -> None:
    """Keep ``backend`` busy with ``todo`` until every run finished or failed for good."""
    envs = {key: to_dict(config.env_config(*key)) for key in _env_keys(todo)}
    pending = deque(
        RunTask(
            spec,
            envs[(spec.world_source, spec.noise)],
            python_path,
            _attempt(store, spec),
            config.run_timeout_s,
        )
        for spec in todo
    )
    tries: dict[str, int] = {}
    bar = progress_bar(
        summary.total,
        config.name,
        "run",
        initial=summary.resumed,
        disable=not progress,
        smoothing=0.05,
    )
    with bar:
        while pending or backend.in_flight:
            while pending and backend.in_flight < backend.capacity:
                backend.submit(pending.popleft())
            task, outcome = backend.next_done()
            retry = _record(store, task, outcome, tries, config.retries, summary)
            if retry is not None:
                pending.append(retry)
            else:
                bar.update(1)
            bar.set_postfix(failed=len(summary.failed), failed_attempts=summary.failed_attempts)


def _record(store, task, outcome, tries, retries, summary) -> RunTask | None:
    """Write ``outcome``; the task to retry, if any."""
    spec = task.spec
    if outcome.get("ok"):
        store.write_run(spec, outcome)
        summary.finished += 1
        return None
    store.write_failure(spec, task.attempt, outcome)
    summary.failed_attempts += 1
    tries[spec.key] = tries.get(spec.key, 0) + 1
    if tries[spec.key] <= retries:
        return replace(task, attempt=task.attempt + 1)
    summary.failed[spec.key] = str(outcome.get("error"))
    return None


def _attempt(store: ResultStore, spec: RunSpec) -> int:
    return store.failed_attempts(spec) + 1


def _env_keys(specs: list[RunSpec]) -> list[tuple[str, int]]:
    return list(dict.fromkeys((spec.world_source, spec.noise) for spec in specs))


def _check_policies(config: SweepConfig, python_path: tuple[str, ...]) -> None:
    """Load each policy once here and check the observation layers it declares, so that a
    misspelt class or layer fails the sweep at once, not every run. Raises
    :class:`ConfigError` naming the ``policies`` entry."""
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.policies import load_policy, required_layers
    from nbv_gym.policies.registry import add_policy_folders

    add_policy_folders(python_path)
    for i, name in enumerate(config.policies):
        try:
            EnvConfig(observation_layers=required_layers(load_policy(name)))
        except NbvGymError as error:
            raise ConfigError(f"policies[{i}] ({name}): {error}") from None


def default_workers() -> int:
    """All cores of this machine."""
    return os.cpu_count() or 1


def summary_rows(out: str | Path, policies: tuple[str, ...] = ()) -> list[dict[str, Any]]:
    """Per policy: finished runs, failed runs, mean final Q, discovered, steps and wall time (from
    ``out/runs.csv``) in the order of ``policies``, for the table printed at the end of a sweep."""
    import pandas as pd

    from nbv_gym.core.inputs import MAX_TABLE_BYTES, open_input

    with open_input(Path(out) / "runs.csv", "Sweep table", MAX_TABLE_BYTES) as file:
        runs = pd.read_csv(file)
    order = [p for p in (*policies, *runs["policy"]) if p in set(runs["policy"])]
    rows = []
    for policy in dict.fromkeys(order):
        group = runs[runs["policy"] == policy]
        ok = group[group["status"] == "ok"]
        rows.append(
            {
                "policy": policy,
                "ok": len(ok),
                "failed": int((group["status"] != "ok").sum()),
                "q": ok["q"].mean(),
                "discovered": ok["discovered"].mean(),
                "steps": ok["steps"].mean(),
                "wall_time_s": ok["wall_time_s"].mean(),
            }
        )
    return rows
