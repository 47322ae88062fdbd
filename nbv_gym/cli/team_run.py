"""``nbv-gym run --robots N`` (N ≥ 2): one team episode into a run folder (docs/team.md)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import typer

from nbv_gym.cli.options import task_config
from nbv_gym.core.jsonfiles import dumps_json


def run_team(
    robots: int,
    given: dict[str, Any],
    out: Path,
    animation: bool,
    check_folder: Callable[[tuple[str, ...]], tuple[str, ...]],
    as_json: bool,
) -> None:
    """Run ``given["policy"]`` as a team of ``robots`` (a team policy's name, or a single-robot
    policy every robot runs) with ``run``'s other options ``given``; write the run folder
    (:mod:`nbv_gym.team.runfolder`) and report as ``run`` does. The team task is the time task:
    another --task, --budget-scans or --max-steps is refused. ``check_folder(names)``: ``run``'s
    check that ``out`` can take the files ``names`` (the names to replace)."""
    from nbv_gym.core.outputs import claim_folder, staged_folder
    from nbv_gym.core.trajectory import TRAJECTORY_NAME
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.episode import RUN_FILES
    from nbv_gym.team import TeamEnv, load_team_policy, run_team_episode
    from nbv_gym.team.runfolder import TEAM_RUN_FILES, write_team_run_folder
    from nbv_gym.worlds import load_spec

    policy, world, noise, seed = given["policy"], given["world"], given["noise"], given["seed"]
    _check_task(robots, given)
    settings = task_config(policy, noise, "time", None, None, given["time_budget_s"],
                           given["speed_mps"], given["scan_time_s"], given["lidar"])  # fmt: skip
    lidar = settings.lidar
    single = (*RUN_FILES, TRAJECTORY_NAME)  # a single run's files in --out: an earlier run too
    names = check_folder(tuple(dict.fromkeys((*TEAM_RUN_FILES, *single))))
    team = load_team_policy(policy, robots)
    load_spec(world)  # a bad world name or spec fails before the world is built
    env = TeamEnv(settings.env_config(world), n_robots=robots)
    claim_folder(out, "run")
    frames: list = []
    reported = [0]

    def report(env: TeamEnv) -> None:
        for scan in env.sim.scans[reported[0] :]:
            typer.echo(
                f"scan {reported[0]:>3}  robot {scan.robot}  time {scan.time_s:6.1f} s  "
                f"discovered {scan.discovered:6.1%}  Q {scan.q:.4f}  Q_paper {scan.q_paper:.4f}",
                err=True,
            )
            reported[0] += 1
        if animation:
            from nbv_gym.team.render import render_team_rgb

            frames.append(render_team_rgb(env.sim))

    with staged_folder(out, names) as staging:  # a crash leaves an earlier run intact
        result = run_team_episode(env, team, seed, on_step=report)
        meta = {"world": world, "policy": policy, "robots": robots, "noise": noise,
                "seed": seed, "task": "time", "lidar": lidar}  # fmt: skip
        summary = write_team_run_folder(staging, env, result, meta)
        if frames:
            from nbv_gym.env.render import save_animation

            fps = ExploreEnv.metadata["render_fps"]  # a frame per decision, as one robot's
            save_animation(frames, staging / "exploration.gif", fps)
    if as_json:
        typer.echo(dumps_json({**summary, "run_folder": str(out)}))
        return
    figures = result.figures
    typer.echo(
        f"{policy} × {robots} robots on {world} (time task, noise {noise}, seed {seed}, lidar "
        f"{lidar}): {len(result.scans)} scans, discovered {figures['discovered']:.1%}, "
        f"Q {figures['q']:.4f}, area under Q(t) {figures['q_time_auc']:.4f}, team time "
        f"{figures['elapsed_s']:.1f} s, overlap {figures['overlap_rate']:.2f}, "
        f"{result.wall_time_s:.1f} s wall — {figures['end_reason']}"
    )
    typer.echo(f"run folder: {out}")


def _check_task(robots: int, given: dict[str, Any]) -> None:
    """ConfigError for an option of another task than the team's (the time task)."""
    from nbv_gym.core.errors import ConfigError

    other = {"--task": given["task"] if given["task"] != "time" else None,
             "--budget-scans": given["budget_scans"], "--max-steps": given["max_steps"]}  # fmt: skip
    for option, value in other.items():
        if value is not None:
            raise ConfigError(
                f"{option} {value}: --robots {robots} runs the team task, the time task "
                f"(--time-budget-s); leave {option} out."
            )
