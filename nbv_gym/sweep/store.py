"""The results folder of a sweep: atomic per-run files, failure records and consolidated tables.

Layout of ``DIR``::

    sweep.toml            the resolved sweep config (a report can be rebuilt from the folder alone)
    versions.json         Python and library versions of the last invocation
    runs/<stem>.json      one finished run: its row of runs.csv and its steps (written last)
    runs/<stem>.cuboids.npz   its per-cuboid end-of-run table
    failures/<stem>.json  every failed attempt of a run: error, traceback, host, time
    runs.csv              one row per run (finished or failed), columns :data:`RUN_COLUMNS`
    steps.csv             one row per step of every finished run, :data:`STEP_TABLE_COLUMNS`
    cuboids.parquet       one row per observed cuboid of every finished run, :data:`CUBOID_COLUMNS`
    report/               figures, tables and report.md (``nbv-gym report``)

Every file is written to a temporary name and renamed into place, so a killed sweep leaves either
a whole run or none. A run counts as finished iff ``runs/<stem>.json`` exists.
"""

from __future__ import annotations

import json
import os
import platform
import socket
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.config import to_dict
from nbv_gym.errors import NbvGymError
from nbv_gym.sweep.config import RunSpec, SweepConfig, dumps_toml
from nbv_gym.sweep.schema import end_reason_code, with_column_docs

IDENTITY_COLUMNS = ("key", "world", "asset", "noise", "policy", "repeat")
#: Columns of ``runs.csv``.
RUN_COLUMNS = (
    *IDENTITY_COLUMNS,
    "seed",
    "status",
    "steps",
    "end_reason",
    "discovered",
    "q",
    "q_paper",
    "path_length_m",
    "wall_time_s",
    "total_time_s",
    "attempts",
    "host",
    "error",
)
#: Columns of ``steps.csv`` (the step columns of :data:`nbv_gym.episode.STEP_COLUMNS`).
STEP_TABLE_COLUMNS = (
    *IDENTITY_COLUMNS,
    "step",
    "goal",
    "discovered",
    "q",
    "q_paper",
    "reward",
    "path_length_m",
    "time_s",
)
#: Columns of ``cuboids.parquet`` (``cov_p*_d*``: one per coverage setting of the run's config).
CUBOID_COLUMNS = (
    *IDENTITY_COLUMNS,
    "cuboid",
    "ix",
    "iy",
    "iz",
    "u_occ",
    "observed",
    "n_obs",
    "r_min",
    "n_omega",
    "sigma_theta",
    "cov_p0.8_d0.05",
    "cov_p0.8_d0.1",
    "cov_p0.7_d0.1",
    "cov_p0.7_d0.15",
    "cov_q",
    "l1",
    "quality",
)


class SweepError(NbvGymError):
    """A sweep cannot start or its results folder is not usable; the message says what to do."""


class ResultStore:
    """The results folder ``root`` of a sweep (see the module docstring for its layout)."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.runs_dir = self.root / "runs"
        self.failures_dir = self.root / "failures"

    # -- starting and resuming ------------------------------------------------------------------

    def prepare(self, config: SweepConfig) -> None:
        """Create the folder, refuse results of a different config, write sweep.toml and
        versions.json, take the lock and drop temporary files of a killed sweep."""
        self.runs_dir.mkdir(parents=True, exist_ok=True)
        self.failures_dir.mkdir(exist_ok=True)
        self._check_same_results(config)
        self._lock()
        for stray in (*self.runs_dir.glob("*.tmp*"), *self.failures_dir.glob("*.tmp*")):
            stray.unlink(missing_ok=True)
        write_text(self.root / "sweep.toml", dumps_toml(to_dict(config)))
        from nbv_gym.episode import versions

        info = {**versions(), "host": platform.node(), "started": _now()}
        write_text(self.root / "versions.json", json.dumps(info, indent=2))

    def release(self) -> None:
        """Release the lock taken by :meth:`prepare`."""
        (self.root / ".lock").unlink(missing_ok=True)

    def finished_stems(self) -> set[str]:
        """File stems of the finished runs."""
        return {p.name.removesuffix(".json") for p in self.runs_dir.glob("*.json")}

    def _check_same_results(self, config: SweepConfig) -> None:
        path = self.root / "sweep.toml"
        if not path.exists() or not any(self.runs_dir.glob("*.json")):
            return
        from nbv_gym.config import from_dict, read_toml

        try:
            previous = from_dict(SweepConfig, read_toml(path, "sweep.toml"))
        except NbvGymError as error:
            raise SweepError(f"{path} is not a valid sweep config ({error}); remove it.") from None
        old, new = previous.results_fingerprint(), config.results_fingerprint()
        changed = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
        if changed:
            raise SweepError(
                f"{self.root} holds results of a sweep with different {', '.join(changed)} "
                f"({', '.join(f'{k}: {old.get(k)!r} → {new.get(k)!r}' for k in changed)}). "
                "Write to another --out folder. (Adding worlds, noise levels, policies or "
                "repeats to a config and rerunning into the same folder is fine.)"
            )

    def _lock(self) -> None:
        lock = self.root / ".lock"
        if lock.exists():
            try:
                host, pid = lock.read_text().split()
                same_host = host == socket.gethostname()
                if same_host and int(pid) != os.getpid() and _alive(int(pid)):
                    raise SweepError(
                        f"Another sweep (pid {pid}) is writing to {self.root}; wait for it or "
                        f"stop it first (delete {lock} if that process is not a sweep)."
                    )
            except ValueError:
                pass
        write_text(lock, f"{socket.gethostname()} {os.getpid()}")

    # -- writing one run ------------------------------------------------------------------------

    def write_run(self, spec: RunSpec, outcome: dict[str, Any]) -> None:
        """Write a finished run: cuboids first, then the JSON that marks it finished."""
        stem = spec.file_stem
        with _atomic(self.runs_dir / f"{stem}.cuboids.npz", "wb") as f:
            np.savez_compressed(f, **outcome["cuboids"])
        record = {"run": outcome["run"], "steps": outcome["steps"]}
        write_text(self.runs_dir / f"{stem}.json", json.dumps(record, default=_plain))

    def write_failure(self, spec: RunSpec, attempt: int, outcome: dict[str, Any]) -> int:
        """Append a failed attempt to the run's failure record; the number of failed attempts."""
        path = self.failures_dir / f"{spec.file_stem}.json"
        record = json.loads(path.read_text()) if path.exists() else {"attempts": []}
        record.update(
            key=spec.key,
            world=spec.world,
            noise=spec.noise,
            policy=spec.policy,
            repeat=spec.repeat,
            seed=spec.seed,
        )
        entry = {k: outcome.get(k) for k in ("error", "traceback", "host", "pid")}
        record["attempts"].append({"attempt": attempt, "time": _now(), **entry})
        write_text(path, json.dumps(record, indent=2))
        return len(record["attempts"])

    def failed_attempts(self, spec: RunSpec) -> int:
        """How many attempts of ``spec`` failed so far (all invocations)."""
        path = self.failures_dir / f"{spec.file_stem}.json"
        return len(json.loads(path.read_text())["attempts"]) if path.exists() else 0

    # -- consolidated tables --------------------------------------------------------------------

    def consolidate(self) -> dict[str, Path]:
        """Rebuild runs.csv, steps.csv and cuboids.parquet from the per-run files; their paths."""
        import pandas as pd

        run_rows, step_rows = [], []
        finished = sorted(self.runs_dir.glob("*.json"))
        for path in finished:
            record = json.loads(path.read_text())
            run = record["run"]
            run_rows.append(run)
            identity = {c: run[c] for c in IDENTITY_COLUMNS}
            step_rows.extend({**identity, **step} for step in record["steps"])
        done = {p.name for p in finished}
        for path in sorted(self.failures_dir.glob("*.json")):
            if path.name not in done:
                run_rows.append(_failed_row(json.loads(path.read_text())))
        runs = pd.DataFrame(run_rows, columns=list(RUN_COLUMNS))
        codes = runs["end_reason"].map(end_reason_code)
        runs.insert(runs.columns.get_loc("end_reason") + 1, "end_code", codes)
        runs = runs.sort_values(["world", "noise", "policy", "repeat"], kind="stable")
        steps = pd.DataFrame(step_rows, columns=list(STEP_TABLE_COLUMNS))
        paths = {"runs": self.root / "runs.csv", "steps": self.root / "steps.csv"}
        with _atomic(paths["runs"], "w") as f:
            runs.to_csv(f, index=False)
        with _atomic(paths["steps"], "w") as f:
            steps.to_csv(f, index=False)
        paths["cuboids"] = self._write_cuboids(runs[runs["status"] == "ok"])
        return paths

    def _write_cuboids(self, runs) -> Path:
        """Stream each finished run's cuboid table into cuboids.parquet (one row group per run)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = self.root / "cuboids.parquet"
        writer = None
        with _atomic(path, "wb") as f:
            for run in runs.itertuples(index=False):
                spec_stem = _stem_of(run)
                with np.load(self.runs_dir / f"{spec_stem}.cuboids.npz") as data:
                    columns = {name: data[name] for name in data.files}
                n = len(columns["cuboid"])
                identity = {c: pa.array([getattr(run, c)] * n) for c in IDENTITY_COLUMNS}
                table = pa.table({**identity, **columns})
                if writer is None:
                    writer = pq.ParquetWriter(f, with_column_docs(table.schema), compression="zstd")
                writer.write_table(table.cast(writer.schema))
            if writer is None:
                empty = {c: pa.array([], pa.string()) for c in IDENTITY_COLUMNS}
                pq.write_table(pa.table(empty), f)
            else:
                writer.close()
        return path


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (temporary file, then rename)."""
    with _atomic(path, "w") as f:
        f.write(text)


class _atomic:
    """Open a temporary sibling of ``path`` for writing and rename it onto ``path`` on success."""

    def __init__(self, path: Path, mode: str):
        self.path, self.mode = Path(path), mode
        self.temporary = self.path.with_name(f"{self.path.name}.tmp{os.getpid()}")

    def __enter__(self):
        self.file = open(self.temporary, self.mode)
        return self.file

    def __exit__(self, kind, value, trace) -> None:
        self.file.close()
        if kind is None:
            os.replace(self.temporary, self.path)
        else:
            self.temporary.unlink(missing_ok=True)


def _stem_of(run) -> str:
    spec = RunSpec(run.world, run.world, int(run.noise), run.policy, int(run.repeat), 0)
    return spec.file_stem


def _failed_row(record: dict[str, Any]) -> dict[str, Any]:
    last = record["attempts"][-1]
    row = {k: record[k] for k in ("key", "world", "noise", "policy", "repeat", "seed")}
    return {
        **row,
        "asset": "",
        "status": "failed",
        "attempts": len(record["attempts"]),
        "host": last.get("host"),
        "error": last.get("error"),
    }


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot write {type(value).__name__} to JSON")


def stems(specs: Iterable[RunSpec]) -> dict[str, RunSpec]:
    """The runs by their file stem."""
    return {spec.file_stem: spec for spec in specs}
