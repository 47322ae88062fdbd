"""The ``nbv-gym`` command line: one app with subcommands (heavy imports inside each command)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path
from typing import Annotated, NoReturn

import typer

from nbv_gym.cli.options import (
    BudgetScansOption,
    LidarOption,
    MaxStepsOption,
    ScanTimeOption,
    SpeedOption,
    TaskOption,
    TimeBudgetOption,
    task_episode_config,
    task_of,
)
from nbv_gym.cli.params import COUNT, NOISE_HELP, NOISE_LEVEL, POSITIVE
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.core.outputs import describe_os_error
from nbv_gym.core.progress import kernel_cache_error, progress_bar, speak_on_stderr


class _App(typer.Typer):
    """The CLI's one error boundary: nbv-gym's errors, bad options (Click's usage errors) and
    unusable files or folders (``OSError``: a full disk, no permission, a file where a folder
    should be) and an unreadable numba kernel cache become a one-line message and exit code 2;
    Ctrl-C a message and exit code 130."""

    def __call__(self, *args, **kwargs):
        try:
            code = super().__call__(*args, **{**kwargs, "standalone_mode": False})
        except NbvGymError as error:
            _fail(str(error), getattr(error, "exit_code", 2))
        except typer.Abort:
            _fail("aborted.", 1)
        except typer.TyperException as error:  # a bad option or argument (Click's usage errors)
            if type(error).__name__ == "NoArgsIsHelpError":  # `nbv-gym`, `nbv-gym worlds`: help
                error.show()
                raise SystemExit(error.exit_code) from None
            _fail(_usage_message(error), getattr(error, "exit_code", 2) or 2)
        except OSError as error:
            _fail(describe_os_error(error))
        except Exception as error:  # numba's own cache unreadable: say what to delete
            message = kernel_cache_error(error)
            if message is None:
                raise
            _fail(message)
        if code == 130:  # Click's answer to KeyboardInterrupt
            _fail("interrupted (Ctrl-C); what was finished is kept.", 130)
        raise SystemExit(code if isinstance(code, int) else 0)


def _fail(message: str, code: int = 2) -> NoReturn:
    typer.secho(f"Error: {' '.join(message.split())}", fg="red", err=True)
    raise SystemExit(code) from None


def _usage_message(error: Exception) -> str:
    """``nbv-gym view: Invalid value for '--max-points': expected …`` (Pydantic's "Value
    error, " prefix of a parser's message dropped)."""
    context = getattr(error, "ctx", None)
    where = f"{context.command_path}: " if context is not None else ""
    message = getattr(error, "format_message", lambda: str(error))()
    return where + message.replace("Value error, ", "")


app = _App(
    name="nbv-gym",
    help="A benchmark for autonomous lidar exploration and Next-Best-View research.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    # every command and group inherits these from the root context
    context_settings={"help_option_names": ["-h", "--help"]},
)
worlds_app = typer.Typer(
    help="List, build and preview the benchmark worlds; import your own scene.",
    no_args_is_help=True,
    rich_markup_mode=None,
)
app.add_typer(worlds_app, name="worlds")


def _print_version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"nbv-gym {version('nbv-gym')}")
        raise typer.Exit()


@app.callback()
def _options(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    pass


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@worlds_app.command("list")
def worlds_list() -> None:
    """List the benchmark worlds with a one-line description.

    Examples:

    \b
      nbv-gym worlds list
    """
    from nbv_gym.worlds import benchmark_names, load_spec

    for name in benchmark_names():
        typer.echo(f"{name:<16} {load_spec(name).description}")


@worlds_app.command("build")
def worlds_build(
    names: Annotated[list[str] | None, typer.Argument(help="World names or spec files.")] = None,
    all_worlds: Annotated[bool, typer.Option("--all", help="Build all benchmark worlds.")] = False,
    force: Annotated[bool, typer.Option(help="Rebuild even if cached.")] = False,
) -> None:
    """Build worlds (mesh and ground truth) into the cache ($NBV_GYM_CACHE moves it).

    Examples:

    \b
      nbv-gym worlds build pp1-trees
      nbv-gym worlds build --all
      nbv-gym worlds build my_world.toml --force
    """
    from nbv_gym.worlds import benchmark_names, load_spec
    from nbv_gym.worlds.world import cache_path, load_world

    if bool(names) == all_worlds:
        raise typer.BadParameter("name the worlds to build, or pass --all (not both)")
    specs = [load_spec(n) for n in (benchmark_names() if all_worlds else names or [])]
    with progress_bar(len(specs), unit="world") as bar:
        for spec in specs:
            bar.set_description(spec.name)
            world = load_world(spec, rebuild=force)
            bar.write(
                f"{spec.name}: {len(world.faces):,} triangles, "
                f"{len(world.ground_truth.voxels):,} ground-truth voxels → {cache_path(spec)}"
            )
            bar.update()


@worlds_app.command("import")
def worlds_import(
    file: Annotated[Path, typer.Argument(help="Mesh (OBJ PLY STL OFF GLB GLTF) or point cloud.")],
    out: Annotated[Path, typer.Option(help="World spec file to write (.toml).")],
    name: Annotated[str | None, typer.Option(help="World name [default: the file's stem].")] = None,
    scale: Annotated[
        float | None,
        typer.Option(help="File units to metres [default: detected].", parser=POSITIVE),
    ] = None,
    up: Annotated[
        str | None, typer.Option(help="The file's up axis, z or y [default: y for GLB/GLTF].")
    ] = None,
    ground: Annotated[
        str, typer.Option(help="add: a ground plane at the lowest point; mesh: the file's own.")
    ] = "add",
    force: Annotated[bool, typer.Option(help="Overwrite an existing spec file.")] = False,
) -> None:
    """Write the world spec of your own scene (detected units, bounds and counts in it) and build
    the world into the cache; then run it like any world. Nothing is written when the file
    cannot make a world.

    Examples:

    \b
      nbv-gym worlds import park.glb --out park.toml
      nbv-gym worlds import scan.ply --out scan.toml --scale 0.001 --up z
      nbv-gym worlds preview park.toml --out park.png
      nbv-gym run --world park.toml --out runs/park
    """
    from nbv_gym.core.outputs import OutputError, writable_file
    from nbv_gym.worlds.scenes.importer import import_scene

    if out.exists() and not force:
        raise OutputError(
            f"--out {out} exists; pass --force to overwrite it, or give another path."
        )
    if out.suffix != ".toml":
        raise typer.BadParameter(f"expected a .toml file, got {out}", param_hint="--out")
    from nbv_gym.simulator import scored_voxels

    writable_file(out)
    for line in import_scene(file, out, name, scale, up, ground, scored_voxels, force):
        typer.echo(line)


@worlds_app.command("preview")
def worlds_preview(
    name: Annotated[str, typer.Argument(help="World name or spec file.")],
    out: Annotated[Path, typer.Option(help="PNG file to write.")] = Path("world.png"),
) -> None:
    """Draw a world (top-down and oblique views, ground truth coloured by height) to a PNG.

    Examples:

    \b
      nbv-gym worlds preview pp1-trees --out pp1-trees.png
    """
    from nbv_gym.core.outputs import writable_file
    from nbv_gym.worlds import load_world
    from nbv_gym.worlds.preview import save_preview

    writable_file(out)
    typer.echo(save_preview(load_world(name), out))


@app.command()
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
    lidar: LidarOption = None,
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
      nbv-gym run --policy nbv-nobs --task budget --budget-scans 20
      nbv-gym run --policy ig-unknown --task time --time-budget-s 300
      nbv-gym run --policy my_module:MyPolicy --world my_world.toml \\
          --no-animation --json
      nbv-gym run --world pp1-trees --out runs/cf --force
      nbv-gym run --world pp1-trees --lidar vlp-16 --out runs/vlp16
    """
    from nbv_gym.core.outputs import claim_folder, staged_folder
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env, run_episode, write_run_folder
    from nbv_gym.policies import load_policy
    from nbv_gym.sensor.presets import DEFAULT_LIDAR, lidar_config
    from nbv_gym.simulator import SimulatorConfig
    from nbv_gym.worlds import load_spec

    lidar = lidar or DEFAULT_LIDAR
    sensor = lidar_config(lidar)  # an unknown preset fails first
    task, budget_scans = task_of(policy, task, budget_scans, max_steps, time_budget_s)
    episode = task_episode_config(
        task, budget_scans, max_steps, time_budget_s, speed_mps, scan_time_s
    )
    run_files = _check_run_folder(out, force)  # a bad --out fails before the world is built
    agent = load_policy(policy)
    simulator = SimulatorConfig(world=world, noise=noise, lidar=sensor, episode=episode)
    load_spec(world)  # a bad world name or spec fails before the world is built
    env = make_env(EnvConfig(simulator), agent, render=animation)
    claim_folder(out, "run")
    frames = []

    def report(row: dict, env) -> None:
        _stderr(
            f"step {row['step']:>3}  discovered {row['discovered']:6.1%}  Q {row['q']:.4f}  "
            f"Q_paper {row['q_paper']:.4f}  path {row['path_length_m']:6.1f} m  "
            f"time {row['elapsed_s']:6.1f} s"
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


def _check_run_folder(out: Path, force: bool) -> tuple[str, ...]:
    """The names of the files a run writes, after checking that ``out`` can take them: not
    another command's folder, and no earlier run's files unless ``force``."""
    from nbv_gym.core.outputs import OutputError, check_owner
    from nbv_gym.core.trajectory import TRAJECTORY_NAME
    from nbv_gym.episode import RUN_FILES

    check_owner(out, "run")
    names = (*RUN_FILES, TRAJECTORY_NAME)
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


@app.command()
def bench(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    suite: Annotated[list[str] | None, typer.Option(help="Only these suites.")] = None,
) -> None:
    """Measure throughput (world build, scans, …); progress goes to stderr.

    Examples:

    \b
      nbv-gym bench
      nbv-gym bench --json > bench.json
      nbv-gym bench --suite foundation
    """
    from nbv_gym.perf import run_suites

    results = run_suites(suite, _stderr)
    if as_json:
        typer.echo(dumps_json(results))
        return
    for key, value in results.items():
        typer.echo(f"{key:<28} {value:>14,.4g}")


#: Commands that live in modules of their own, in the order ``--help`` lists them: (module of
#: nbv_gym.cli, the function or Typer group, the command's name; None: the function's name).
_ELSEWHERE = (
    ("evaluate", "evaluate", None),
    ("sweep", "sweep", None),
    ("sweep", "report", None),
    ("score", "score", None),
    ("score", "leaderboard", None),
    ("train", "train", None),
    ("package", "package_model", "package-model"),
    ("study", "study_app", "study"),
    ("configs", "configs_app", "configs"),
    ("exports", "export", None),
    ("exports", "view", None),
    ("exports", "record", None),
)


def _register(commands: tuple[tuple[str, str, str | None], ...]) -> None:
    """Add ``commands`` (:data:`_ELSEWHERE`) to the app: functions as commands, Typer apps as
    groups."""
    for module, attribute, name in commands:
        target = getattr(importlib.import_module(f"nbv_gym.cli.{module}"), attribute)
        if isinstance(target, typer.Typer):
            app.add_typer(target, name=name)
        else:
            app.command(name)(target)


_register(_ELSEWHERE)


def main() -> None:
    """Entry point of the ``nbv-gym`` console script."""
    speak_on_stderr()
    app()
