"""``nbv-gym study wd``: run the three parts of :mod:`nbv_gym.studies.wd_analysis` and write a study folder.

Layout of ``OUT``::

    study.json          the config, versions, run source and the wall time of each part
    ideal_cuboids.csv   part 1: one row per world, reconstruction and drawn cuboid (WD_occ, cov ×4)
    ideal_medians.csv   part 1: medians per world and reconstruction
    limits.csv          WD*_occ per world and resolution
    shares.csv          part 2: informative shares per run and resolution
    runs/               the exploration runs the study made (when no --runs folder was given)
    report/             report.md, its figures and tables (:mod:`nbv_gym.studies.wd_report`)

A rerun into the same ``OUT`` reuses the runs already there; the report is rebuilt from the CSV
files alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.core.inputs import read_json
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.core.outputs import claim_folder
from nbv_gym.core.progress import progress_bar
from nbv_gym.studies import StudyError
from nbv_gym.studies.runs import MAP_NAME, SCANS_NAME, SUMMARY_NAME, RunFolder, find_runs
from nbv_gym.studies.wd_analysis import (
    RECONSTRUCTIONS,
    IdealResult,
    ground_truth,
    ideal_study,
    keyed_rng,
    keyed_seed,
    map_share,
    random_limit,
    study_grid,
)
from nbv_gym.studies.wd_config import WdStudyConfig

STUDY_NAME = "study.json"


def run_wd_study(config: WdStudyConfig, out: Path, runs_dir: Path | None = None) -> Path:
    """Run the WD study into ``out`` (runs from ``runs_dir``, or made under ``out/runs``); the path
    of the report. Progress goes to stderr."""
    from nbv_gym.core.provenance import versions
    from nbv_gym.studies.wd_report import build_wd_report

    runs = _check_inputs(config, runs_dir)  # before minutes of work, not after
    claim_folder(out, "study")
    timings: dict[str, float] = {}
    with _timed(timings, "ideal_s"):
        ideal = _ideal_part(config, out)
    with _timed(timings, "runs_s"):
        runs = runs or ensure_runs(config, out / "runs")
    with _timed(timings, "shares_s"):
        _share_part(config, runs, ideal, out)
    study = {
        "config": asdict(config),
        "runs": str(runs_dir) if runs_dir else "made by the study (runs/)",
        "timings_s": timings,
        "versions": versions(),
    }
    (out / STUDY_NAME).write_text(dumps_json(study) + "\n", encoding="utf-8")
    return build_wd_report(out)


def _check_inputs(config: WdStudyConfig, runs_dir: Path | None) -> list[RunFolder] | None:
    """The run folders under ``runs_dir`` (None without it: the study makes its runs, so its
    policy must load); raises for an unknown world or policy or a folder without runs."""
    from nbv_gym.policies import load_policy
    from nbv_gym.worlds import load_spec

    for world in (*config.worlds, *config.share_worlds):
        load_spec(world)
    if runs_dir is not None:
        return find_runs(runs_dir)
    load_policy(config.policy)
    return None


class _timed:
    """Context manager adding its wall time to ``timings[key]``."""

    def __init__(self, timings: dict[str, float], key: str):
        self.timings, self.key = timings, key

    def __enter__(self):
        self.start = time.perf_counter()

    def __exit__(self, *exc):
        self.timings[self.key] = round(time.perf_counter() - self.start, 1)


def _bar(total: int, desc: str):
    return progress_bar(total, desc, "step", dynamic_ncols=True)


# -- part 1 --------------------------------------------------------------------------------------------


def _ideal_part(config: WdStudyConfig, out: Path) -> dict[str, IdealResult]:
    """Ideal and random reconstructions of every world; writes ideal_cuboids.csv and
    ideal_medians.csv; world name → :class:`IdealResult`."""
    from nbv_gym.worlds import load_world

    results = {}
    with _bar(len(config.worlds) * len(RECONSTRUCTIONS), "ideal vs random") as bar:
        for name in config.worlds:
            world = load_world(name)
            truth = ground_truth(world, world.ground_truth.res)
            step = _advance(bar)
            results[world.name] = ideal_study(world, truth, config.cuboids, config.seed, step)
    _write_csv(
        out / "ideal_cuboids.csv", [r for res in results.values() for r in _cuboid_rows(res)]
    )
    _write_csv(
        out / "ideal_medians.csv", [r for res in results.values() for r in _median_rows(res)]
    )
    return results


def _advance(bar) -> Callable[[str], None]:
    def step(label: str) -> None:
        bar.set_postfix_str(label)
        bar.update()

    return step


def _cuboid_rows(result: IdealResult) -> list[dict]:
    rows = []
    for name in RECONSTRUCTIONS:
        for b, (ci, cj, ck) in enumerate(result.index):
            row: dict[str, Any] = {
                "world": result.world,
                "asset": result.asset,
                "reconstruction": name,
            }
            row |= {"ci": int(ci), "cj": int(cj), "ck": int(ck), "wd_occ": result.wd[name][b]}
            row |= {f"cov_{k + 1}": c[b] for k, c in enumerate(result.cov[name])}
            rows.append(row)
    return rows


def _median_rows(result: IdealResult) -> list[dict]:
    return [
        {"world": result.world, "asset": result.asset, "reconstruction": name, **values}
        | {"n_cuboids": len(result.index)}
        for name, values in result.medians().items()
    ]


# -- runs ------------------------------------------------------------------------------------------------


def ensure_runs(config: WdStudyConfig, root: Path) -> list[RunFolder]:
    """The runs of ``config.share_worlds`` × ``config.noise_levels`` under ``root``: those already
    there (same policy, seed and steps) are reused, the others made."""
    from nbv_gym.studies.runs import make_run

    todo = [(w, n) for w in config.share_worlds for n in config.noise_levels]
    runs = []
    with _bar(len(todo), "exploration runs") as bar:
        for world, noise in todo:
            path = root / world / f"noise{noise}"
            seed = keyed_seed(config.seed, world, noise, "run")
            bar.set_postfix_str(f"{world} noise {noise}")
            if not _run_done(path, config, seed):
                make_run(world, noise, config.policy, seed, config.max_steps, path)
            runs.append(RunFolder(path, world, noise))
            bar.update()
    return runs


def _run_done(path: Path, config: WdStudyConfig, seed: int) -> bool:
    """Whether ``path`` holds a finished run of this policy, seed and step budget."""
    if not all((path / n).is_file() for n in (SUMMARY_NAME, MAP_NAME, SCANS_NAME)):
        return False
    summary = read_json(path / SUMMARY_NAME, "Run summary")
    budget = summary.get("config", {}).get("simulator", {}).get("episode", {}).get("max_steps")
    return (summary.get("policy"), summary.get("seed"), budget) == (
        config.policy,
        seed,
        config.max_steps,
    )


# -- part 2 ----------------------------------------------------------------------------------------------


def _share_part(
    config: WdStudyConfig, runs: list[RunFolder], ideal: dict[str, IdealResult], out: Path
) -> None:
    """Informative shares of every run's map at every resolution; writes limits.csv, shares.csv."""
    from nbv_gym.worlds import load_world

    limits, shares = _ideal_limits(ideal), []
    worlds = sorted({r.world for r in runs})
    with _bar(len(runs) * len(config.resolutions_m), "informative share") as bar:
        for name in worlds:
            world = load_world(name)
            mine = sorted((r for r in runs if r.world == name), key=lambda r: (r.noise, r.path))
            for res in config.resolutions_m:
                rows, limit = _world_shares(world, mine, res, config, ideal, bar)
                shares += rows
                limits.append(limit)
    _write_csv(out / "limits.csv", _unique_limits(limits))
    _write_csv(out / "shares.csv", shares)


def _world_shares(world, runs, res, config, ideal, bar) -> tuple[list[dict], dict]:
    """Share rows of ``runs`` (all of ``world``) at ``res`` and the WD*_occ row used."""
    from nbv_gym.studies.runs import run_map
    from nbv_gym.worlds.spec import asset_type

    truth = ground_truth(world, res)
    limit = _limit(world, truth, res, config, ideal)
    rows = []
    for run in runs:
        bar.set_postfix_str(f"{world.name} noise {run.noise} {res} m")
        occupancy = run_map(run, res)
        if occupancy is not None:
            prob = occupancy.probability(study_grid(res))
            del occupancy
            rng = keyed_rng(config.seed, run.path.name, run.world, run.noise, res, "share")
            share = map_share(prob, truth, res, limit["wd_star"], config.share_cuboids, rng)
            rows.append(_share_row(run, asset_type(world.spec), res, limit["wd_star"], share))
        bar.update()
    return rows, limit


def _limit(world, truth, res, config, ideal) -> dict:
    """The WD*_occ row of ``world`` at ``res``: part 1's value at the ground truth's own
    resolution, else random reconstructions of ``truth``."""
    from nbv_gym.worlds.spec import asset_type

    if world.name in ideal and np.isclose(res, world.ground_truth.res):
        return _ideal_limits({world.name: ideal[world.name]})[0]
    rng = keyed_rng(config.seed, world.name, res, "limit")
    wd_star, count = random_limit(truth, res, config.cuboids, rng)
    return _limit_row(world.name, asset_type(world.spec), res, wd_star, count)


def _ideal_limits(ideal: dict[str, IdealResult]) -> list[dict]:
    from nbv_gym.core.protocol import RESOLUTION_M

    return [
        _limit_row(r.world, r.asset, RESOLUTION_M, r.wd_star, len(r.index)) for r in ideal.values()
    ]


def _limit_row(world: str, asset: str, res: float, wd_star: float, count: int) -> dict:
    keys = ("world", "asset", "resolution_m", "wd_star", "n_cuboids")
    return dict(zip(keys, (world, asset, res, wd_star, count), strict=True))


def _unique_limits(limits: list[dict]) -> list[dict]:
    seen = {(row["world"], round(row["resolution_m"], 6)): row for row in limits}
    return list(seen.values())


def _share_row(run: RunFolder, asset: str, res: float, wd_star: float, share) -> dict:
    row = {
        "world": run.world,
        "asset": asset,
        "noise": run.noise,
        "resolution_m": res,
        "run": str(run.path),
        "wd_star": wd_star,
        "n_u_occ": share.n_u_occ,
        "n_observed": share.n_observed,
        "n_sampled": share.n_sampled,
        "share_wd": share.share_wd,
    }
    row |= {f"share_cov_{k + 1}": v for k, v in enumerate(share.share_cov)}
    row["observed_fraction"] = share.observed_fraction
    return row


def _write_csv(path: Path, rows: list[dict]) -> None:
    import pandas as pd

    if not rows:
        raise StudyError(f"nothing to write to {path.name}: no result rows")
    pd.DataFrame(rows).to_csv(path, index=False)
