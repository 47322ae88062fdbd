"""``nbv-gym score`` and ``nbv-gym leaderboard``: plain typer-annotated functions the CLI registers."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.cli.options import LidarOption
from nbv_gym.cli.params import COUNT


def score(
    policy: Annotated[
        str,
        typer.Argument(
            help="Policy name, module:Class, sb3:MODEL.zip or a shipped model (ppo-budget). "
            "module:Class and sb3: run code from their files: use only ones you trust."
        ),
    ],
    out: Annotated[Path, typer.Option(help="Folder for the runs and the scorecard.")],
    suite: Annotated[
        str,
        typer.Option(
            help="Evaluation suite: standard (the score), quick (for trying) or team (2 and 3 "
            "robots on one map; POLICY a team policy such as hungarian-frontier, or a "
            "single-robot policy every robot runs uncoordinated)."
        ),
    ] = "standard",
    workers: Annotated[
        int | None,
        typer.Option(
            help="Local worker processes, or LocalCluster workers, ≥ 1 [default: all cores]."
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Run on the Dask cluster at this address (tcp://host:8786; tls://host:8786 with "
            "Dask's TLS settings, see docs/security.md), or 'local' for a new Dask LocalCluster; "
            "the same scorecard as a local run. Needs nbv-gym[dist]."
        ),
    ] = None,
    lidar: LidarOption = None,
    world: Annotated[
        list[str] | None,
        typer.Option(
            help="Run the suite's parts on the benchmark worlds on this world instead (a spec file, "
            "e.g. your own scene; repeat for several); another suite, whose scorecards rank "
            "apart, by the time task on those worlds."
        ),
    ] = None,
    progress: Annotated[bool, typer.Option(help="Show progress bars on stderr.")] = True,
) -> None:
    """Score a policy on a fixed evaluation suite and write OUT/scorecard.json and scorecard.md.

    The standard suite runs the time task (600 s of robot time: travel at 1 m/s and 10 s per
    scan charged) and the budget task (12 scans, travel free) on the 16 generated test worlds and
    the 12 benchmark worlds, the time task on the 12 shift worlds (recipes outside every training
    distribution), and the paper's explore task on the 12 benchmark worlds, at noise 0, 1 and 2
    with fixed seeds (720 runs); quick is the same shape without the shift worlds, small (120
    runs). The
    scorecard holds every run's figures (with Q against elapsed time and path length) and, per
    split and asset type, the IQM and mean with 95 % stratified bootstrap intervals and the
    optimality gap, and Q at the time budget and at matched path (25–200 m). Killed, the same command resumes.
    Compare scorecards with `nbv-gym leaderboard`. A module:Class policy is imported from the
    current folder. The team suite runs the team task (600 s of team time) with 2 and 3 robots
    on the test and shift worlds and one robot with 2 × and 3 × 600 s on the test worlds (the
    same total robot time: a row on the team leaderboard); its scorecards rank apart. Another --lidar than os1-16 makes another suite (its scorecards rank apart).

    Examples:

    \b
      nbv-gym score closest-frontier --suite quick --out scores/cf-quick
      nbv-gym score my_policies:MyPolicy --out scores/mine --workers 2
      nbv-gym score nbv-sigma --out scores/sigma --scheduler tls://HOST:8786
      nbv-gym score closest-frontier --suite quick --world park.toml \\
          --out scores/cf-park
      nbv-gym score closest-frontier --suite quick --lidar vlp-16 \\
          --out scores/cf-vlp16
      nbv-gym score hungarian-frontier --suite team --out scores/hf-team
      nbv-gym leaderboard scores/mine/scorecard.json --references --out board
    """
    from nbv_gym.benchmark.scorecard import interval_text
    from nbv_gym.benchmark.suiterun import score_policy
    from nbv_gym.benchmark.suites import get_suite
    from nbv_gym.benchmark.teamrun import check_team_options
    from nbv_gym.cli.sweep import resumable
    from nbv_gym.core.config import check
    from nbv_gym.sweep.backends import reach_scheduler

    check(workers is None or workers >= 1, "--workers", f"must be ≥ 1, got {workers}")
    check_team_options(get_suite(suite), world, scheduler)
    reach_scheduler(scheduler)  # a bad or silent scheduler fails before any folder
    chosen = get_suite(suite) if lidar is None else get_suite(suite).with_lidar(lidar)
    chosen = chosen.with_worlds(_absolute(world)) if world else chosen
    _check_scored(world or [])
    with resumable(out / "parts"):
        card = score_policy(
            policy, chosen, out, workers, progress, (os.getcwd(),), scheduler=scheduler
        )
    for split, agg in card["aggregates"].items():
        typer.echo(f"{split:<14} {agg['metric']:<11} IQM {interval_text(agg['all'], 'iqm')}")
    typer.echo(f"scorecard: {out / 'scorecard.json'} ({card['timing']['wall_time_s']:.0f} s)")


def _check_scored(worlds: list[str]) -> None:
    """Build (or read from the cache) each own world and refuse, before any run, one without
    ground truth where map quality is scored (its runs would score Q as NaN)."""
    from nbv_gym.simulator import scored_voxels
    from nbv_gym.worlds import load_world

    for world in worlds:
        scored_voxels(load_world(world))


def _absolute(worlds: list[str]) -> tuple[str, ...]:
    """Spec file paths made absolute (benchmark names kept): the runs read them elsewhere."""
    return tuple(str(Path(w).resolve()) if w.endswith(".toml") else w for w in worlds)


def leaderboard(
    scorecards: Annotated[
        list[Path] | None,
        typer.Argument(help="scorecard.json files of `nbv-gym score` (or their folders)."),
    ] = None,
    references: Annotated[
        bool,
        typer.Option(
            "--references",
            help="Add the shipped policies' reference scorecards of the scorecards' suite "
            "(of the standard suite when no scorecard is given).",
        ),
    ] = False,
    out: Annotated[Path, typer.Option(help="Folder for leaderboard.md and .html.")] = Path(
        "leaderboard"
    ),
    suite: Annotated[
        str | None,
        typer.Option(
            help="With --references and no scorecard: the suite whose references are ranked "
            "(standard, quick; team has none yet) [default: standard]."
        ),
    ] = None,
    verify: Annotated[
        int,
        typer.Option(
            help="Re-run N runs of each given scorecard here (the same policy code needed) and "
            "refuse a card whose runs do not reproduce.",
            parser=COUNT,
        ),
    ] = 0,
    verify_seed: Annotated[
        int | None,
        typer.Option(
            help="Seed of --verify's choice of runs [default: drawn at random and printed].",
            parser=COUNT,
        ),
    ] = None,
) -> None:
    """Rank scorecards of one suite in one table (leaderboard.md and leaderboard.html); the
    ranking is printed too.

    Ranked by the IQM of the area under Q(t) over the time budget (equal robot time: travel
    and scans charged) on the test split; columns per split and task, each naming what it
    charges (equal scans with travel free; the paper's protocol), the probability that the
    policy scores higher than the best reference, with 95 % stratified-bootstrap intervals; Q at
    the budget and at matched path, the Pareto front of (Q, path); Q(t) and performance
    profiles as figures. Oracles (policies reading privileged values) are ranked apart.
    Scorecards of different suites or protocol versions are refused; shipped references of
    another protocol version are left out, and the board says they are pending.

    Team scorecards (`nbv-gym score POLICY --suite team`) rank on their own board, never with
    single-robot ones: by the IQM of the area under the team's Q(t), with the overlap rate and
    the longest robot path beside it, and a row per policy run as one robot with N × the budget
    (the same total robot time): is a team worth it?

    Every scorecard is checked against the schema, its suite and itself (its aggregates from
    its runs; each run's clock, curves and area under Q(t)). That cannot catch a forgery
    consistent with itself: --verify N re-runs N runs of each given scorecard, chosen with a
    stated seed, and refuses it unless they reproduce (docs/security.md).

    Examples:

    \b
      nbv-gym leaderboard --references --out board
      nbv-gym leaderboard --references --suite quick --out board-quick
      nbv-gym leaderboard scores/mine/scorecard.json --references --out board
      nbv-gym leaderboard scores/a scores/b --out board
      nbv-gym leaderboard scores/theirs --references --verify 3 --out board
      nbv-gym leaderboard scores/hf-team scores/uf-team --out board-team
    """
    import secrets

    from nbv_gym.benchmark.leaderboard import build_leaderboard

    if verify and verify_seed is None:
        verify_seed = secrets.randbelow(2**32)
        typer.echo(f"--verify {verify}: runs chosen with --verify-seed {verify_seed}", err=True)
    board = build_leaderboard(
        list(scorecards or []), references, out, suite, verify, verify_seed or 0
    )
    typer.echo(board.summary)
    typer.echo(f"leaderboard: {board.markdown} and {board.html}")
