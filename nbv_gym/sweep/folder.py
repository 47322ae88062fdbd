"""The results folder of a sweep: atomic per-run files, failure records and consolidated tables.

Layout of ``DIR``::

    sweep.toml            the resolved sweep config (a report can be rebuilt from the folder alone)
    versions.json         Python and library versions of the last invocation
    worlds.json           world name → content digest of its spec (an edited spec is refused)
    .lock                 locked (``flock``) by the sweep writing the folder; the OS releases it
                          when that process ends, however it ends
    runs/<stem>.json      one finished run: its row of runs.csv and its steps (written last)
    runs/<stem>.cuboids.npz   its per-cuboid end-of-run table
    failures/<stem>.json  every failed attempt of a run: error, traceback, host, time
    corrupt/              unreadable run or failure files, moved aside (their runs are redone)
    runs.csv              one row per run (finished or failed), columns :data:`RUN_COLUMNS`
    steps.csv             one row per step of every finished run, :data:`STEP_TABLE_COLUMNS`
    cuboids.parquet       one row per observed cuboid of every finished run, :data:`CUBOID_COLUMNS`
    report/               figures, tables and report.md (``nbv-gym report``)

Every file is written to a temporary name (``NAME.tmpPID``) and renamed into place, so a killed
sweep leaves either a whole run or none. A run counts as finished iff ``runs/<stem>.json`` is a
readable run record and its ``.cuboids.npz`` a readable archive; anything else found there is
moved to ``corrupt/`` (named in :attr:`ResultStore.set_aside`) and the run is done again.
"""

from __future__ import annotations

import json
import os
import platform
import re
import time
import zipfile
from pathlib import Path
from typing import IO, Any

import numpy as np

from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.inputs import InputFileError, open_input, read_json
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.core.outputs import atomic, claim_folder, write_text, write_together
from nbv_gym.sweep.config import RunSpec, SweepConfig, dumps_toml, sweep_config, world_name
from nbv_gym.sweep.schema import (
    CUBOIDS,
    IDENTITY,
    RUNS,
    STEPS,
    end_reason_code,
    names,
    with_column_docs,
)

IDENTITY_COLUMNS = names(IDENTITY)
#: Columns of ``runs.csv`` as a run record holds them; ``end_code`` is derived from
#: ``end_reason`` when the table is written.
RUN_COLUMNS = tuple(name for name in names(RUNS) if name != "end_code")
#: Run columns a run record may lack (``oracle``, ``decision_time_s``: records of versions before
#: they existed).
OPTIONAL_RUN_COLUMNS = ("total_time_s", "decision_time_s", "error", "oracle")
#: Columns of ``steps.csv``: the identity, then the episode's step columns.
STEP_TABLE_COLUMNS = names(STEPS)
#: Columns of ``cuboids.parquet`` (``cov_p*_d*``: one per coverage setting of the run's config).
CUBOID_COLUMNS = names(CUBOIDS)
#: Names of this module's temporary files: ``<name>.tmp<pid>`` (:func:`~nbv_gym.core.outputs.temporary`).
_TEMPORARY = re.compile(r"^.+\.(json|npz|csv|parquet|toml)\.tmp(\d+)$")


class SweepError(NbvGymError):
    """A sweep cannot start or its results folder is not usable; the message says what to do."""


class CorruptFileError(NbvGymError):
    """A run or failure record that cannot be read; the message says what is wrong with it."""


class ResultStore:
    """The results folder ``root`` of a sweep (see the module docstring for its layout).

    :attr:`set_aside` lists, one line each, the unreadable files this store moved to
    ``corrupt/`` (for the caller to show)."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self.runs_dir = self.root / "runs"
        self.failures_dir = self.root / "failures"
        self.corrupt_dir = self.root / "corrupt"
        self.set_aside: list[str] = []
        self._lock_file: IO[str] | None = None

    # -- starting and resuming ------------------------------------------------------------------

    def prepare(self, config: SweepConfig) -> None:
        """Create the folder, take the lock, refuse results of a different config or of an
        edited world, drop temporary files of a killed sweep and write sweep.toml, worlds.json
        and versions.json. Raises :class:`SweepError` saying what to do."""
        self.make_folders()
        self.lock()
        self._check_same_results(config)
        digests = self._check_same_worlds(config)
        self._drop_temporaries()
        write_text(self.root / "sweep.toml", dumps_toml(config.file_dict()))
        write_text(self.root / "worlds.json", dumps_json(digests, sort_keys=True))
        from nbv_gym.core.provenance import versions

        info = {**versions(), "host": platform.node(), "started": _now()}
        write_text(self.root / "versions.json", dumps_json(info))

    def make_folders(self) -> None:
        """Create ``root``, ``runs/`` and ``failures/``; :class:`SweepError` if ``root`` is a
        file or cannot be written."""
        if self.root.exists() and not self.root.is_dir():
            raise SweepError(f"--out {self.root} is a file; give a folder for the results.")
        claim_folder(self.root, "sweep")  # not a run's folder, nor another command's
        try:
            self.runs_dir.mkdir(parents=True, exist_ok=True)
            self.failures_dir.mkdir(exist_ok=True)
        except OSError as error:
            raise SweepError(_cannot_write(self.root, error)) from None
        if not os.access(self.root, os.W_OK) or not os.access(self.runs_dir, os.W_OK):
            raise SweepError(f"Cannot write to {self.root}: permission denied. Give another --out.")

    def lock(self) -> None:
        """Lock the folder for this process (an exclusive ``flock`` on ``.lock``, held until
        :meth:`release` or the end of the process); :class:`SweepError` if another process
        holds it."""
        import fcntl

        path = self.root / ".lock"
        try:
            handle = open(path, "a+", encoding="utf-8")
        except OSError as error:
            raise SweepError(_cannot_write(path, error)) from None
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            holder = handle.read().strip() or "another process"
            handle.close()
            raise SweepError(
                f"Another sweep ({holder}) is writing to {self.root}; wait for it to end or stop "
                "it, then rerun (the lock is released when that process ends)."
            ) from None
        handle.seek(0)
        handle.truncate()
        handle.write(f"pid {os.getpid()} on {platform.node()}\n")
        handle.flush()
        self._lock_file = handle

    def release(self) -> None:
        """Release the lock taken by :meth:`lock` (the ``.lock`` file stays: it is not the lock)."""
        if self._lock_file is not None:
            self._lock_file.close()
            self._lock_file = None

    def finished_stems(self) -> set[str]:
        """File stems of the finished runs; unreadable run files are moved aside."""
        return {path.name.removesuffix(".json") for path, _ in self.finished_records()}

    def finished_records(self) -> list[tuple[Path, dict[str, Any]]]:
        """``(path, record)`` of every readable run file, sorted by name; unreadable ones (and
        their cuboid tables) are moved to ``corrupt/``."""
        found = []
        for path in sorted(self.runs_dir.glob("*.json")):
            try:
                found.append((path, _read_run(path)))
            except CorruptFileError as error:
                self._set_aside(path, str(error), "the run will be done again")
                cuboids = _cuboids_path(path)
                if cuboids.exists():
                    self._move_aside(cuboids)
        return found

    def _check_same_results(self, config: SweepConfig) -> None:
        path = self.root / "sweep.toml"
        if not path.exists() or not any(self.runs_dir.glob("*.json")):
            return
        from nbv_gym.core.config import read_toml

        try:
            previous = sweep_config(read_toml(path, "sweep.toml"))
        except NbvGymError as error:
            raise SweepError(f"{path} is not a valid sweep config ({error}); remove it.") from None
        if previous.name != config.name:
            raise SweepError(
                f"{self.root} holds the results of sweep {previous.name!r}; this is sweep "
                f"{config.name!r}, whose runs would be mixed with them. Write to another --out "
                "folder (or give the config the same name to extend that sweep)."
            )
        old, new = previous.results_fingerprint(), config.results_fingerprint()
        changed = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
        if changed:
            raise SweepError(
                f"{self.root} holds results of a sweep with different {', '.join(changed)} "
                f"({', '.join(f'{k}: {old.get(k)!r} → {new.get(k)!r}' for k in changed)}). "
                "Write to another --out folder. (Adding worlds, noise levels, policies or "
                "repeats to a config and rerunning into the same folder is fine.)"
            )

    def _check_same_worlds(self, config: SweepConfig) -> dict[str, str]:
        """The world digests to record (the folder's, updated with ``config``'s); refuses a
        world whose spec changed since runs of it were written."""
        previous = self._read_digests()
        current = config.world_digests()
        worlds_run = {record["run"]["world"] for _, record in self.finished_records()}
        for name, digest in current.items():
            if name in worlds_run and previous.get(name, digest) != digest:
                source = dict(zip(map(world_name, config.worlds), config.worlds, strict=True))
                raise SweepError(
                    f"World {name!r} ({source.get(name, name)}) changed since its runs in "
                    f"{self.root} were made (spec digest {previous[name]} → {digest}). Write to "
                    "another --out folder, or restore the spec (or give the new world a new name)."
                )
        return {**previous, **current}

    def _read_digests(self) -> dict[str, str]:
        path = self.root / "worlds.json"
        if not path.exists():
            return {}
        try:
            digests = read_json(path, "World digests")
            if not isinstance(digests, dict):
                raise ValueError("not a table")
            return digests
        except (ValueError, OSError) as error:
            self._set_aside(path, f"unreadable ({error})", "world digests start afresh")
            return {}

    def _drop_temporaries(self) -> None:
        """Delete the temporary files (``NAME.tmpPID``) a killed sweep of this folder left."""
        for folder in (self.root, self.runs_dir, self.failures_dir):
            for path in folder.iterdir():
                if _TEMPORARY.match(path.name) and path.is_file():
                    path.unlink(missing_ok=True)

    # -- writing one run ------------------------------------------------------------------------

    def write_run(self, spec: RunSpec, outcome: dict[str, Any]) -> None:
        """Write a finished run: cuboids first, then the JSON that marks it finished."""
        stem = spec.file_stem
        with atomic(self.runs_dir / f"{stem}.cuboids.npz", "wb") as f:
            np.savez_compressed(f, **outcome["cuboids"])
        record = {"run": outcome["run"], "steps": outcome["steps"]}
        write_text(self.runs_dir / f"{stem}.json", dumps_json(record, indent=None))

    def write_failure(self, spec: RunSpec, attempt: int, outcome: dict[str, Any]) -> int:
        """Append a failed attempt to the run's failure record; the number of failed attempts."""
        path = self.failures_dir / f"{spec.file_stem}.json"
        record = self._failure_record(path) or {"attempts": []}
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
        write_text(path, dumps_json(record))
        return len(record["attempts"])

    def failed_attempts(self, spec: RunSpec) -> int:
        """How many attempts of ``spec`` failed so far (all invocations)."""
        record = self._failure_record(self.failures_dir / f"{spec.file_stem}.json")
        return len(record["attempts"]) if record else 0

    def _failure_record(self, path: Path) -> dict[str, Any] | None:
        """The failure record at ``path``; None if there is none or it was unreadable (then it
        is moved aside)."""
        if not path.exists():
            return None
        try:
            return _read_failure(path)
        except CorruptFileError as error:
            self._set_aside(path, str(error), "its attempts are counted afresh")
            return None

    # -- consolidated tables --------------------------------------------------------------------

    def consolidate(self) -> dict[str, Path]:
        """Rebuild runs.csv, steps.csv and cuboids.parquet from the per-run files (unreadable
        ones are moved aside first, so the three tables always agree); their paths. Raises
        :class:`SweepError` if the folder holds no run at all."""
        import pandas as pd

        self._check_is_results_folder()
        listed = self._listed()
        finished = self.finished_records()
        run_rows: list[dict[str, Any]] = []
        step_rows: list[dict[str, Any]] = []
        unlisted: list[str] = []
        for path, record in finished:
            run = record["run"]
            if not listed(run):
                unlisted.append(run.get("key", path.name))
                continue
            run_rows.append(run)
            identity = {c: run[c] for c in IDENTITY_COLUMNS}
            step_rows.extend({**identity, **step} for step in record["steps"])
        done = {path.name for path, _ in finished}
        for path in sorted(self.failures_dir.glob("*.json")):
            failed = self._failure_record(path) if path.name not in done else None
            if failed is not None and listed(failed):
                run_rows.append(_failed_row(failed))
            elif failed is not None:
                unlisted.append(failed.get("key", path.name))
        if unlisted:
            self.set_aside.append(
                f"{len(unlisted)} run(s) in {self.root} are of worlds, noise levels, policies or "
                f"repeats that sweep.toml no longer lists (e.g. {unlisted[0]}); they are left "
                "out of the tables and the report (their files stay)"
            )
        if not run_rows:
            raise SweepError(
                f"{self.root} holds no readable run (runs/ and failures/ are empty). Run "
                f"`nbv-gym sweep CONFIG --out {self.root}` first."
            )
        runs = pd.DataFrame(run_rows, columns=list(RUN_COLUMNS))
        codes = runs["end_reason"].map(end_reason_code)
        runs.insert(runs.columns.get_loc("end_reason") + 1, "end_code", codes)
        runs = runs.sort_values(["world", "noise", "policy", "repeat"], kind="stable")
        steps = pd.DataFrame(step_rows, columns=list(STEP_TABLE_COLUMNS))
        paths = {name: self.root / f"{name}.{ext}" for name, ext in _TABLES}
        manifest: dict[str, Any] = {"files": self._record_files()}
        write_together(
            {
                paths["cuboids"]: (
                    "wb",
                    lambda f: self._write_cuboids(f, runs[runs["status"] == "ok"]),
                ),
                paths["runs"]: ("w", lambda f: runs.to_csv(f, index=False)),
                paths["steps"]: ("w", lambda f: steps.to_csv(f, index=False)),
            }
        )
        manifest["sizes"] = {path.name: path.stat().st_size for path in paths.values()}
        write_text(self.root / MANIFEST_NAME, json.dumps(manifest))
        return paths

    def _listed(self):
        """A test of whether a run record (its world, noise, policy, repeat) is one that the
        folder's sweep.toml lists (everything passes without a readable sweep.toml)."""
        from nbv_gym.core.config import read_toml

        try:
            config = sweep_config(read_toml(self.root / "sweep.toml", "sweep.toml"))
        except NbvGymError:
            return lambda record: True
        worlds = {_name_or_stem(world) for world in config.worlds}
        return lambda record: (
            record.get("world") in worlds
            and record.get("noise") in config.noise
            and record.get("policy") in config.policies
            and isinstance(record.get("repeat"), int)
            and record["repeat"] < config.repeats
        )

    def _record_files(self) -> list[str]:
        """Names of the run and failure files the tables are built from."""
        return sorted(
            [f"runs/{p.name}" for p in self.runs_dir.glob("*.json")]
            + [f"failures/{p.name}" for p in self.failures_dir.glob("*.json")]
        )

    def ensure_tables(self) -> None:
        """Consolidate the tables if runs.csv is missing or older than a run or failure file
        (under the lock; while a sweep holds it, its last tables are used if there are any).
        Raises :class:`SweepError` for a path that is not a sweep's results folder."""
        tables = self.root / "runs.csv"
        if tables.is_file() and not self._tables_outdated(tables):
            return
        self._check_is_results_folder()
        try:
            self.lock()
        except SweepError:
            if tables.is_file():
                return
            raise
        try:
            self.consolidate()
        finally:
            self.release()

    def _tables_outdated(self, tables: Path) -> bool:
        """Whether the tables must be rebuilt: a run or failure file newer than runs.csv, or
        not what the tables were built from (files added or removed, a table truncated or
        replaced since: its size differs from the one recorded in :data:`MANIFEST_NAME`)."""
        built = tables.stat().st_mtime
        files = (*self.runs_dir.glob("*.json"), *self.failures_dir.glob("*.json"))
        if any(path.stat().st_mtime > built for path in files):
            return True
        try:
            manifest = read_json(self.root / MANIFEST_NAME, "Table manifest")
            sizes = {name: (self.root / name).stat().st_size for name in manifest["sizes"]}
            return sizes != manifest["sizes"] or manifest["files"] != self._record_files()
        except (OSError, ValueError, KeyError, TypeError, NbvGymError):
            return True

    def _check_is_results_folder(self) -> None:
        if not self.root.is_dir():
            kind = "a file" if self.root.exists() else "not there"
            raise SweepError(f"{self.root} is {kind}; give the results folder of a sweep.")
        if not self.runs_dir.is_dir() and not self.failures_dir.is_dir():
            hint = (
                " It looks like the folder of `nbv-gym run` (summary.json): a report needs a "
                "sweep's folder."
                if (self.root / "summary.json").exists() or any(self.root.glob("*/summary.json"))
                else ""
            )
            raise SweepError(
                f"{self.root} holds no sweep results (no runs.csv, no runs/).{hint} Run "
                "`nbv-gym sweep CONFIG --out DIR` first, then `nbv-gym report DIR`."
            )

    def _write_cuboids(self, f, runs) -> None:
        """Stream each finished run's cuboid table into ``f`` (one parquet row group per run)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        writer = None
        for run in runs.itertuples(index=False):
            with np.load(self.runs_dir / f"{_stem_of(run)}.cuboids.npz") as data:
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

    # -- unreadable files -----------------------------------------------------------------------

    def _set_aside(self, path: Path, problem: str, consequence: str) -> None:
        target = self._move_aside(path)
        self.set_aside.append(
            f"{path.relative_to(self.root)} {problem}; moved to "
            f"{target.relative_to(self.root)}, {consequence}"
        )

    def _move_aside(self, path: Path) -> Path:
        self.corrupt_dir.mkdir(exist_ok=True)
        target = self.corrupt_dir / path.name
        n = 1
        while target.exists():
            target, n = self.corrupt_dir / f"{path.name}.{n}", n + 1
        os.replace(path, target)
        return target


_TABLES = (("runs", "csv"), ("steps", "csv"), ("cuboids", "parquet"))
#: What the tables were built from (run and failure files) and their sizes then.
MANIFEST_NAME = "tables.json"


def _name_or_stem(world: str) -> str:
    """The name of a world (its spec's, for a spec file; the file's stem if it is gone)."""
    try:
        return world_name(world)
    except NbvGymError:
        return Path(world).stem


def _cannot_write(path: Path, error: OSError) -> str:
    return f"Cannot write to {path}: {error.strerror or error}. Give another --out folder."


def _read_run(path: Path) -> dict[str, Any]:
    """The run record of ``path``, checked: its row names the run of this file and carries the
    run columns, its steps are rows, and its cuboid table is a readable archive."""
    record = _read_json(path)
    run = record.get("run") if isinstance(record, dict) else None
    if not isinstance(run, dict) or not isinstance(record.get("steps"), list):
        raise CorruptFileError("is not a run record (no 'run' row or 'steps' list)")
    missing = [c for c in RUN_COLUMNS if c not in run and c not in OPTIONAL_RUN_COLUMNS]
    if missing:
        raise CorruptFileError(f"lacks run column(s) {', '.join(missing)}")
    try:
        stem = _stem_of_row(run)
    except (TypeError, ValueError):
        stem = None
    if f"{stem}.json" != path.name:
        raise CorruptFileError(f"holds run {run.get('key')!r}, not the run of its file name")
    if not all(isinstance(s, dict) and "step" in s for s in record["steps"]):
        raise CorruptFileError("has a step that is not a row")
    _check_archive(_cuboids_path(path))
    return record


def _read_failure(path: Path) -> dict[str, Any]:
    record = _read_json(path)
    attempts = record.get("attempts") if isinstance(record, dict) else None
    if not isinstance(attempts, list) or not attempts:
        raise CorruptFileError("is not a failure record (no 'attempts' list)")
    missing = [k for k in ("key", "world", "noise", "policy", "repeat", "seed") if k not in record]
    if missing or not all(isinstance(a, dict) for a in attempts):
        raise CorruptFileError(
            f"is not a failure record (lacks {', '.join(missing) or 'attempts'})"
        )
    return record


def _read_json(path: Path) -> Any:
    try:
        return read_json(path, "Run record")
    except InputFileError as error:
        raise CorruptFileError(str(error).removeprefix(f"Run record {path} ")) from None


def _check_archive(path: Path) -> None:
    """Raise :class:`CorruptFileError` unless ``path`` is an npz archive (its directory is read,
    not its data) with a ``cuboid`` column."""
    from nbv_gym.core.arrayfiles import MAX_NPZ_BYTES

    if not path.exists():
        raise CorruptFileError(f"has no cuboid table ({path.name} is missing)")
    try:
        with open_input(path, "Cuboid table", MAX_NPZ_BYTES) as file, zipfile.ZipFile(file) as z:
            names = z.namelist()
    except InputFileError as error:
        raise CorruptFileError(f"has an unusable cuboid table ({error})") from None
    except (zipfile.BadZipFile, OSError, EOFError) as error:
        raise CorruptFileError(f"has an unreadable cuboid table {path.name} ({error})") from None
    if "cuboid.npy" not in names:
        raise CorruptFileError(f"has a cuboid table {path.name} without a cuboid column")


def _cuboids_path(run_path: Path) -> Path:
    return run_path.with_name(run_path.name.removesuffix(".json") + ".cuboids.npz")


def _stem_of_row(run: dict[str, Any]) -> str:
    spec = RunSpec(
        run["world"], run["world"], int(run["noise"]), run["policy"], int(run["repeat"]), 0
    )
    return spec.file_stem


def _stem_of(run) -> str:
    return _stem_of_row(run._asdict())


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


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")
