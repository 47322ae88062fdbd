"""Score one policy on a suite: run the suite's parts with the sweep's runner, read every run
back, and write the scorecard.

Layout of ``OUT``::

    worlds/<name>.toml      the generated test worlds' specs (a suite's worlds are data)
    parts/<split>/          one sweep results folder per part (see :mod:`nbv_gym.sweep.folder`):
                            resumable, each finished run written atomically
    scorecard.json          the scorecard (:mod:`nbv_gym.benchmark.scorecard`)
    scorecard.md            its short summary

Killed, the same command resumes: finished runs are kept and only the missing ones run. A run
that fails after the sweep's retries leaves no scorecard (an incomplete suite is not comparable).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from nbv_gym.benchmark.cardtypes import RunEntry, Scorecard, Timing
from nbv_gym.benchmark.scorecard import build_scorecard, policy_identity, write_scorecard
from nbv_gym.benchmark.suites import Part, Suite
from nbv_gym.core.errors import NbvGymError
from nbv_gym.worlds.spec import WorldSpec


class ScoreError(NbvGymError):
    """A suite could not be scored completely; the message says what to do."""


def score_policy(
    policy: str,
    suite: Suite,
    out: str | Path,
    workers: int | None = None,
    progress: bool = True,
    python_path: tuple[str, ...] = (),
    say: Callable[[str], None] | None = None,
    scheduler: str | None = None,
) -> Scorecard:
    """Run every run of ``suite`` for ``policy`` not yet finished in ``out``, then write
    ``out/scorecard.json`` and ``out/scorecard.md``; the scorecard. ``workers``: local worker
    processes (default: all cores), or LocalCluster workers; ``scheduler``: a Dask scheduler
    address or ``"local"`` (as for sweeps; the runs and so the scorecard are the same as a
    local scoring's); ``python_path``: folders where a ``module:Class`` policy is found;
    ``say``: where phase messages go (default: stderr)."""
    from nbv_gym.benchmark.teamrun import score_team, team_policy_identity
    from nbv_gym.core.outputs import claim_folder
    from nbv_gym.sweep.runner import default_workers

    say = say or _stderr
    start = time.perf_counter()
    _check_kind(policy, suite)
    identity = team_policy_identity(policy) if suite.team else policy_identity(policy)
    out = claim_folder(Path(out), "score")  # not a run's, sweep's or training's folder
    _check_same_policy(out, policy)
    sources = write_world_specs(suite, out / "worlds")
    say(f"scoring {policy} on suite {suite.name} ({suite.runs} runs) → {out}")
    if suite.team:
        specs = partial(_part_specs, suite, policy=policy, sources=sources)
        runs = score_team(policy, suite, out, workers or default_workers(), specs, say)
    else:
        how = (workers, scheduler, python_path, progress)
        runs = _score_parts(policy, suite, out, sources, how, say)
        identity["oracle"] = ran_as_oracle(out, suite)  # what the runs used, not what it declares
    timing: Timing = {
        "wall_time_s": time.perf_counter() - start,
        "workers": workers or default_workers(),
    }
    card = build_scorecard(suite, identity, runs, timing)
    write_scorecard(card, out)
    return card


def _score_parts(
    policy: str,
    suite: Suite,
    out: Path,
    sources: dict[str, str],
    how: tuple,
    say: Callable[[str], None],
) -> list[RunEntry]:
    """Sweep every part of a single-robot ``suite`` for ``policy`` into ``out`` (``how``:
    workers, scheduler, python path, progress, as :func:`~nbv_gym.sweep.runner.run_sweep`
    takes them); the runs' figures, in the suite's order."""
    from nbv_gym.sweep.runner import run_sweep

    workers, scheduler, python_path, progress = how
    for part in suite.parts:
        say(f"{part.split}: {part.task.name} task, {part.runs} runs on {len(part.worlds)} worlds")
        summary = run_sweep(
            part_config(suite, part, policy, sources), out / "parts" / part.split,
            workers, scheduler, python_path, progress,
        )  # fmt: skip
        if summary.failed:
            raise ScoreError(
                f"{len(summary.failed)} run(s) of part {part.split} failed after retries (see "
                f"{out / 'parts' / part.split / 'failures'}); no scorecard was written. Rerun the "
                "same command to retry them: finished runs are kept."
            )
    return [row for part in suite.parts for row in part_runs(suite, part, policy, sources, out)]


def _part_specs(suite: Suite, part: Part, policy: str, sources: dict[str, str]) -> list:
    """The runs of the team ``part`` for ``policy`` as the sweep orders and seeds them (a
    sweep names single-robot policies only; its seeds never depend on the policy)."""
    from dataclasses import replace

    specs = part_config(suite, part, _SEEDING_POLICY, sources).runs()
    return [replace(spec, policy=policy) for spec in specs]


#: A single-robot policy's name that stands for a team policy's where the sweep's run seeds are
#: drawn (they depend on the suite's seed, the world, the noise level and the repeat only).
_SEEDING_POLICY = "closest-frontier"


def _check_kind(policy: str, suite: Suite) -> None:
    """:class:`ScoreError` for a team policy's name on a single-robot suite."""
    from nbv_gym.team.policies import TEAM_POLICIES

    if not suite.team and policy in TEAM_POLICIES:
        raise ScoreError(
            f"{policy} is a team policy; score it on the team suite (`nbv-gym score {policy} "
            "--suite team`)"
        )


def _check_same_policy(out: Path, policy: str) -> None:
    """Refuse ``out`` when it holds the scorecard of another policy (one folder per policy)."""
    from nbv_gym.benchmark.scorecard import load_scorecard

    path = out / "scorecard.json"
    if path.is_file():
        other = load_scorecard(path)["policy"]["name"]
        if other != policy:
            raise ScoreError(
                f"{out} holds the scorecard of {other!r}; score {policy!r} into another --out "
                "folder (one folder per policy)."
            )


def write_world_specs(suite: Suite, folder: Path) -> dict[str, str]:
    """Write the generated worlds of ``suite`` as spec files into ``folder``; world name → what
    a sweep config names it by (a benchmark name, your spec file, or the written file's path)."""
    from nbv_gym.core.config import to_dict
    from nbv_gym.core.outputs import write_text
    from nbv_gym.sweep.config import dumps_toml

    sources = {}
    for part in suite.parts:
        for name, world in zip(part.world_names, part.worlds, strict=True):
            if isinstance(world, WorldSpec):
                folder.mkdir(parents=True, exist_ok=True)
                path = folder / f"{name}.toml"
                write_text(path, dumps_toml(to_dict(world)))
                sources[name] = str(path.resolve())
            else:
                sources[name] = world
    return sources


def part_config(suite: Suite, part: Part, policy: str, sources: dict[str, str]):
    """The :class:`~nbv_gym.sweep.config.SweepConfig` of ``part`` for ``policy``."""
    from nbv_gym.sweep.config import SweepConfig

    config = SweepConfig(
        name=f"{suite.name}-{part.split}",
        worlds=tuple(sources[name] for name in part.world_names),
        noise=part.noise,
        policies=(policy,),
        repeats=part.repeats,
        seed=suite.seed,
        task=part.task,
    )
    return config


def part_runs(
    suite: Suite, part: Part, policy: str, sources: dict[str, str], out: Path
) -> list[RunEntry]:
    """The figures (:func:`run_figures`) of every run of ``part`` in ``out``, in the suite's
    order; :class:`ScoreError` if one is missing."""
    from nbv_gym.sweep.folder import ResultStore

    records = {
        rec["run"]["key"]: rec
        for _, rec in ResultStore(out / "parts" / part.split).finished_records()
    }
    specs = part_config(suite, part, policy, sources).runs()
    missing = [spec.key for spec in specs if spec.key not in records]
    if missing:
        raise ScoreError(
            f"{len(missing)} run(s) of part {part.split} are missing in {out} (e.g. {missing[0]}); "
            "rerun the same command to finish them."
        )
    return [run_figures(part, records[spec.key]) for spec in specs]


def ran_as_oracle(out: Path, suite: Suite) -> bool:
    """Whether any run of ``suite`` in ``out`` ran its policy as an oracle (with the full
    ``info``): the flag each episode read and its sweep record keeps."""
    from nbv_gym.sweep.folder import ResultStore

    return any(
        bool(record["run"].get("oracle", False))
        for part in suite.parts
        for _, record in ResultStore(out / "parts" / part.split).finished_records()
    )


def run_figures(part: Part, record: dict[str, Any]) -> RunEntry:
    """One run's entry of the scorecard from its sweep record (``run`` row and ``steps``): the
    final figures, Q at 70 % discovered, and Q over effort (:mod:`nbv_gym.benchmark.curves`):
    on the time and path grids, and the normalised area under Q(t) over the time task's
    budget (None in the other tasks)."""
    import numpy as np

    from nbv_gym.benchmark.curves import PATH_GRID_M, TIME_GRID_S, grid_curve
    from nbv_gym.core.protocol import DISCOVERED_TARGET
    from nbv_gym.metrics.effort import area_under
    from nbv_gym.reporting.inference import q_curve

    run, steps = record["run"], record["steps"]
    q = np.array([step["q"] for step in steps], float)
    elapsed = np.array([step["elapsed_s"] for step in steps], float)
    path = np.array([step["path_length_m"] for step in steps], float)
    auc = area_under(elapsed, q, part.task.time_budget_s) if part.task.name == "time" else None
    target = DISCOVERED_TARGET
    discovered = np.array([step["discovered"] for step in steps], float)
    q_paper = np.array([step["q_paper"] for step in steps], float)
    q_paper_70 = q_curve(discovered, q_paper, np.array([target], float))[0]
    return {
        "split": part.split,
        "task": part.task.name,
        "world": run["world"],
        "asset": run["asset"],
        "noise": run["noise"],
        "repeat": run["repeat"],
        "seed": run["seed"],
        "steps": run["steps"],
        "end_reason": run["end_reason"],
        "q": run["q"],
        "q_paper": run["q_paper"],
        "q_paper_70": float(q_paper_70),
        "discovered": run["discovered"],
        "path_length_m": run["path_length_m"],
        "elapsed_s": steps[-1]["elapsed_s"],
        "q_time_auc": auc,
        "q_time": grid_curve(elapsed, q, TIME_GRID_S),
        "q_path": grid_curve(path, q, PATH_GRID_M),
        "decision_time_s": run.get("decision_time_s"),
        "wall_time_s": run["wall_time_s"],
    }


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)
