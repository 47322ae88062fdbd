"""Score a policy on the team protocol's parts (the ``team`` suite): each run one team episode
(:func:`~nbv_gym.team.run_team_episode`), its figures a scorecard run with the team's.

The policy is a team policy's name (:data:`~nbv_gym.team.policies.TEAM_POLICIES`) or a
single-robot policy's, which every robot runs uncoordinated, its own copy
(:class:`~nbv_gym.team.EachRobot`). Runs have the seeds the sweep gives the same world, noise
level and repeat under the suite's seed (paired with every other policy's).

Layout of ``OUT`` (as :mod:`nbv_gym.benchmark.suiterun`'s, the runs' files aside)::

    worlds/<name>.toml         the generated worlds' specs
    parts/<split>/<run>.json   one finished run's scorecard entry (written atomically: killed,
                               the same command resumes with the runs still missing)
    scorecard.json, scorecard.md

A team run's entry holds the single-robot run's figures — ``elapsed_s`` the team's clock at its
last scan, ``steps`` and ``path_length_m`` the sums over robots, ``q_time`` on
:data:`~nbv_gym.benchmark.curves.TEAM_TIME_GRID_S` — and the team's: ``time_to_q_s``,
``per_robot`` (scans, path, change of Q), ``overlap_rate``, ``longest_path_m`` and
``contribution_spread`` (:mod:`nbv_gym.team.episode`).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

from nbv_gym.benchmark.cardtypes import PolicyEntry, RunEntry
from nbv_gym.benchmark.suites import Part, Suite
from nbv_gym.core.errors import ConfigError

#: What the scorecard names as the class of a single-robot policy every robot runs.
EACH_ROBOT = "nbv_gym.team.policies:EachRobot"


def team_policy_identity(name: str) -> PolicyEntry:
    """The ``policy`` entry of a team scorecard (the policy loaded once here, so a bad name, an
    oracle or a policy a team cannot run fails before any run): a team policy's class and
    module source, or a single-robot policy's code run by :class:`~nbv_gym.team.EachRobot`."""
    import inspect

    from nbv_gym.benchmark.scorecard import file_hash, policy_file
    from nbv_gym.policies import policy_name
    from nbv_gym.team.policies import EachRobot, load_team_policy

    team = load_team_policy(name, 1)
    if isinstance(team, EachRobot):
        path, kind = policy_file(name), f"{EACH_ROBOT}({policy_name(team.policies[0])})"
    else:
        source = inspect.getsourcefile(type(team))
        path, kind = Path(source) if source else None, policy_name(team)
    return {
        "name": name,
        "class": kind,
        "oracle": False,  # a team runs agent policies only (EachRobot refuses an oracle)
        "hashed_file": path.name if path else None,
        "code_hash": file_hash(path) if path else None,
    }


def score_team(
    policy: str,
    suite: Suite,
    out: Path,
    workers: int,
    specs: Callable[[Part], list[Any]],
    say: Callable[[str], None],
) -> list[RunEntry]:
    """Run every run of ``suite`` (all its parts of the team protocol) for ``policy`` not yet
    finished in ``out`` on ``workers`` local processes; every run's entry, in the suite's
    order. ``specs(part)``: the part's runs as the sweep orders and seeds them
    (:class:`~nbv_gym.sweep.config.RunSpec`)."""
    from nbv_gym.benchmark.scorecard import dumps_strict
    from nbv_gym.core.outputs import write_text

    runs: list[RunEntry] = []
    for part in suite.parts:
        folder = out / "parts" / part.split
        todo = [spec for spec in specs(part) if not _run_path(folder, spec).is_file()]
        say(f"{part.split}: {part.robots} robot(s), time task of {part.task.time_budget_s:g} s, "
            f"{part.runs} runs ({part.runs - len(todo)} done)")  # fmt: skip
        folder.mkdir(parents=True, exist_ok=True)
        jobs = [(part, spec, policy) for spec in todo]
        for spec, entry in zip(todo, _map(_team_run, jobs, workers), strict=True):
            write_text(_run_path(folder, spec), dumps_strict(entry))
        runs += [_read_run(_run_path(folder, spec)) for spec in specs(part)]
    return runs


def _run_path(folder: Path, spec) -> Path:
    return folder / f"{spec.file_stem}.json"


def _read_run(path: Path) -> RunEntry:
    from nbv_gym.core.inputs import read_json

    return read_json(path, "Team run")


def _map(function: Callable[[Any], RunEntry], jobs: list, workers: int):
    """``function`` over ``jobs`` in order: here with one worker, else in a process pool."""
    if workers <= 1 or len(jobs) <= 1:
        yield from map(function, jobs)
        return
    with ProcessPoolExecutor(max_workers=min(workers, len(jobs))) as pool:
        yield from pool.map(function, jobs)


def _team_run(job: tuple[Part, Any, str]) -> RunEntry:
    """One run of a team part: ``(part, spec, policy)`` → its scorecard entry."""
    from nbv_gym.team import TeamEnv, load_team_policy, run_team_episode
    from nbv_gym.worlds.spec import asset_type, load_spec

    part, spec, policy = job
    config = part.env_config()
    simulator = replace(config.simulator, world=spec.world_source, noise=spec.noise)
    robots = part.robots if part.robots is not None else 1  # a team part's: always set
    env = TeamEnv(replace(config, simulator=simulator), n_robots=robots)
    result = run_team_episode(env, load_team_policy(policy, robots), spec.seed)
    asset = asset_type(load_spec(spec.world_source))
    return team_entry(part, spec, asset, result)


def team_entry(part: Part, spec: Any, asset: str, result: Any) -> RunEntry:
    """The scorecard entry of a team episode's ``result`` (a
    :class:`~nbv_gym.team.TeamEpisodeResult`) of run ``spec`` of ``part``."""
    import numpy as np

    from nbv_gym.benchmark.curves import PATH_GRID_M, TEAM_TIME_GRID_S, grid_curve
    from nbv_gym.core.protocol import DISCOVERED_TARGET
    from nbv_gym.reporting.inference import q_curve

    figures, scans = result.figures, result.scans
    column = {name: np.array([row[name] for row in scans], float)
              for name in ("time_s", "path_length_m", "q", "q_paper", "discovered")}  # fmt: skip
    target = np.array([DISCOVERED_TARGET], float)
    q_paper_70 = float(q_curve(column["discovered"], column["q_paper"], target)[0])
    return {
        "split": part.split,
        "task": part.task.name,
        "world": spec.world,
        "asset": asset,
        "noise": spec.noise,
        "repeat": spec.repeat,
        "seed": spec.seed,
        "steps": figures["steps"],
        "end_reason": figures["end_reason"],
        "q": figures["q"],
        "q_paper": figures["q_paper"],
        "q_paper_70": None if np.isnan(q_paper_70) else q_paper_70,
        "discovered": figures["discovered"],
        "path_length_m": figures["path_length_m"],
        "elapsed_s": figures["elapsed_s"],
        "q_time_auc": figures["q_time_auc"],
        "q_time": grid_curve(column["time_s"], column["q"], TEAM_TIME_GRID_S),
        "q_path": grid_curve(column["path_length_m"], column["q"], PATH_GRID_M),
        "decision_time_s": None,
        "wall_time_s": result.wall_time_s,
        "time_to_q_s": figures["time_to_q_s"],
        "per_robot": [
            {"steps": r["steps"], "path_length_m": r["path_length_m"], "delta_q": r["delta_q"]}
            for r in result.robots
        ],
        "overlap_rate": figures["overlap_rate"],
        "longest_path_m": figures["longest_path_m"],
        "contribution_spread": figures["contribution_spread"],
    }


def check_team_options(suite: Suite, world: object, scheduler: object) -> None:
    """ConfigError for ``nbv-gym score`` options a team suite cannot take: ``--world`` (its
    parts run on the generated test and shift splits) and ``--scheduler`` (local workers)."""
    if not any(part.team for part in suite.parts):
        return
    if world:
        raise ConfigError(
            f"--world: suite {suite.name} runs the team task on its own test and shift worlds; "
            "leave --world out"
        )
    if scheduler:
        raise ConfigError(
            f"--scheduler: suite {suite.name} (the team task) runs on local workers only; use "
            "--workers"
        )
