"""``nbv-gym run``: one episode of a policy into a self-describing run folder."""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.cli.options import (
    AgentLidarOption,
    BudgetScansOption,
    MaxStepsOption,
    ScanTimeOption,
    SpeedOption,
    TaskOption,
    TimeBudgetOption,
    task_config,
)
from nbv_gym.cli.params import COUNT, NOISE_HELP, NOISE_LEVEL, POSITIVE_COUNT
from nbv_gym.core.jsonfiles import dumps_json


def run(
    world: Annotated[str, typer.Option(help="World name or spec file.")] = "pp1-trees",
    policy: Annotated[
        str,
        typer.Option(
            help="Policy name, module:Class or sb3:MODEL.zip. The last two run code from their "
            "files (a model zip is a pickle): use only ones you trust."
        ),
    ] = "closest-frontier",
    noise: Annotated[int, typer.Option(help=NOISE_HELP, parser=NOISE_LEVEL)] = 1,
    seed: Annotated[int, typer.Option(help="Episode seed.", parser=COUNT)] = 0,
    task: TaskOption = None,
    budget_scans: BudgetScansOption = None,
    max_steps: MaxStepsOption = None,
    time_budget_s: TimeBudgetOption = None,
    speed_mps: SpeedOption = None,
    scan_time_s: ScanTimeOption = None,
    lidar: AgentLidarOption = None,
    robots: Annotated[
        int,
        typer.Option(
            help="Robots exploring the world together: 2 or more run the team task (the time "
            "task on one map and one clock; --policy a team policy such as hungarian-frontier or "
            "utility-frontier, or a single-robot one run by every robot).",
            parser=POSITIVE_COUNT,
        ),
    ] = 1,
    out: Annotated[Path, typer.Option(help="Run folder to write.")] = Path("runs/episode"),
    animation: Annotated[bool, typer.Option(help="Write exploration.gif (slower).")] = True,
    force: Annotated[
        bool, typer.Option(help="Replace the files of an earlier run in --out (when it finished).")
    ] = False,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print the summary as one JSON object on stdout.")
    ] = False,
) -> None:
    """Run one episode of a policy and write a self-describing run folder.

    The folder holds steps.csv (step, goal, discovered, q, q_paper, reward, path_length_m,
    elapsed_s: the robot's time under the effort model, time_s: wall time), summary.json (config, final figures, wall time, versions), map.npz,
    statistics.npz and exploration.gif. A folder holding an earlier run is refused unless
    --force is given; the new run's files then replace the old ones only when it finished (a
    crash leaves the earlier run intact). A sweep's folder is always refused.

    Examples:

    \b
      nbv-gym run --world pp1-trees --policy closest-frontier --noise 1 \\
          --seed 0 --out runs/cf
      nbv-gym run --policy ppo-budget --world pp3-trees  # budget: 12 scans
      nbv-gym run --policy sb3:runs/t/final_model.zip  # as trained
      nbv-gym run --policy nbv-nobs --task budget --budget-scans 20
      nbv-gym run --policy ig-unknown --task time --time-budget-s 300
      nbv-gym run --policy my_module:MyPolicy --world my_world.toml \\
          --no-animation --json
      nbv-gym run --world pp1-trees --out runs/cf --force
      nbv-gym run --world pp1-trees --lidar vlp-16 --out runs/vlp16
      nbv-gym run --robots 3 --policy hungarian-frontier --world pp1-cuboids \\
          --out runs/team3

    With --robots N (N ≥ 2) the folder holds scans.csv (robot, time_s: the team's clock,
    path_length_m: the team's summed path, q, q_paper, discovered), summary.json (figures: the
    team's; per_robot: a row per robot), map.npz, statistics.npz, paths.png (every robot's path
    in its own colour) and exploration.gif.
    """
    from nbv_gym.core.outputs import claim_folder, staged_folder
    from nbv_gym.episode import make_env, run_episode, write_run_folder
    from nbv_gym.policies import load_policy
    from nbv_gym.sensor.presets import lidar_config
    from nbv_gym.worlds import load_spec

    if lidar is not None:
        lidar_config(lidar)  # an unknown preset fails first
    if robots > 1:
        from nbv_gym.cli.team_run import run_team

        given = {"world": world, "policy": policy, "noise": noise, "seed": seed, "task": task,
                 "budget_scans": budget_scans, "max_steps": max_steps,
                 "time_budget_s": time_budget_s, "speed_mps": speed_mps,
                 "scan_time_s": scan_time_s, "lidar": lidar}  # fmt: skip
        run_team(robots, given, out, animation, partial(_check_run_folder, out, force), as_json)
        return
    settings = task_config(policy, noise, task, budget_scans, max_steps, time_budget_s,
                           speed_mps, scan_time_s, lidar)  # fmt: skip
    task, lidar = settings.name, settings.lidar
    run_files = _check_run_folder(out, force)  # a bad --out fails before the world is built
    agent = load_policy(policy)
    load_spec(world)  # a bad world name or spec fails before the world is built
    env = make_env(settings.env_config(world), agent, render=animation)
    claim_folder(out, "run")
    frames = []

    def report(row: dict, env) -> None:
        typer.echo(
            f"step {row['step']:>3}  discovered {row['discovered']:6.1%}  Q {row['q']:.4f}  "
            f"Q_paper {row['q_paper']:.4f}  path {row['path_length_m']:6.1f} m  "
            f"time {row['elapsed_s']:6.1f} s",
            err=True,
        )
        if animation:
            frames.append(env.render())  # full resolution: halving it aliased

    with staged_folder(out, run_files) as staging:  # a crash leaves an earlier run intact
        result = _episode_of(run_episode, env, agent, seed, report, policy)
        oracle = result.oracle  # the flag as the episode read it: what the run used
        meta = {"world": world, "policy": policy, "oracle": oracle, "noise": noise,
                "seed": seed, "task": task, "lidar": lidar}  # fmt: skip
        summary = write_run_folder(staging, env, result, meta)
        if frames:
            from nbv_gym.env.render import save_animation

            save_animation(frames, staging / "exploration.gif", env.metadata["render_fps"])
    if as_json:
        typer.echo(dumps_json({**summary, "run_folder": str(out)}))
        return
    final = result.final
    typer.echo(
        f"{policy}{' (oracle)' if oracle else ''} on {world} ({task} task, noise {noise}, "
        f"seed {seed}, lidar {lidar}): {final['step']} steps, "
        f"discovered {final['discovered']:.1%}, Q {final['q']:.4f}, "
        f"Q_paper {final['q_paper']:.4f}, path {final['path_length_m']:.1f} m, "
        f"robot time {final['elapsed_s']:.1f} s, {result.wall_time_s:.1f} s wall — "
        f"{result.end_reason}"
    )
    typer.echo(f"run folder: {out}")


def _check_run_folder(
    out: Path, force: bool, names: tuple[str, ...] | None = None
) -> tuple[str, ...]:
    """The names of the files a run writes (``names``, else the single robot's), after checking
    that ``out`` can take them: not another command's folder, and no earlier run's files
    unless ``force``."""
    from nbv_gym.core.outputs import OutputError, check_owner
    from nbv_gym.core.trajectory import TRAJECTORY_NAME
    from nbv_gym.episode import RUN_FILES

    check_owner(out, "run")
    names = names or (*RUN_FILES, TRAJECTORY_NAME)
    earlier = [name for name in names if (out / name).exists()]
    if earlier and not force:
        raise OutputError(
            f"--out {out} holds an earlier run ({', '.join(earlier[:3])}"
            f"{', …' if len(earlier) > 3 else ''}); pass --force to replace it (its files stay "
            "until the new run finished), or give another folder."
        )
    return names


def _episode_of(run_episode, env, agent, seed: int, report, policy: str):
    """``run_episode(env, agent, seed, report)``; a policy that calls ``sys.exit()`` fails the
    run with :class:`PolicyError` instead of ending the command as if it had succeeded."""
    from nbv_gym.policies import PolicyError

    try:
        return run_episode(env, agent, seed, report)
    except SystemExit as exit:
        raise PolicyError(
            f"Policy {policy!r} called sys.exit({exit.code!r}) during its episode; a policy "
            "must return a goal from act(), not end the process. Nothing was written."
        ) from None
