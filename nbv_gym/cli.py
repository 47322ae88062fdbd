"""The ``nbv-gym`` command line: one app with subcommands (heavy imports inside each command)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.errors import NbvGymError


class _App(typer.Typer):
    """A Typer app that turns nbv-gym's errors into a one-line message and exit code 2."""

    def __call__(self, *args, **kwargs):
        try:
            return super().__call__(*args, **kwargs)
        except NbvGymError as error:
            typer.secho(f"Error: {error}", fg="red", err=True)
            raise SystemExit(2) from None


app = _App(
    name="nbv-gym",
    help="A benchmark for autonomous lidar exploration and Next-Best-View research.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
)
worlds_app = typer.Typer(
    help="List, build and preview the benchmark worlds.",
    no_args_is_help=True,
    rich_markup_mode=None,
)
app.add_typer(worlds_app, name="worlds")


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@worlds_app.command("list")
def worlds_list() -> None:
    """List the benchmark worlds with a one-line description.

    Examples:
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
      nbv-gym worlds build pp1-trees
      nbv-gym worlds build --all
      nbv-gym worlds build my_world.toml --force
    """
    from tqdm import tqdm

    from nbv_gym.worlds import benchmark_names, load_spec
    from nbv_gym.worlds.world import cache_path, load_world

    if not names and not all_worlds:
        raise typer.BadParameter("name at least one world, or pass --all")
    specs = [load_spec(n) for n in (benchmark_names() if all_worlds else names)]
    for spec in (bar := tqdm(specs, unit="world", file=sys.stderr)):
        bar.set_description(spec.name)
        if force:
            cache_path(spec).unlink(missing_ok=True)
        world = load_world(spec)
        bar.write(
            f"{spec.name}: {len(world.faces):,} triangles, "
            f"{len(world.ground_truth.voxels):,} ground-truth voxels → {cache_path(spec)}"
        )


@worlds_app.command("preview")
def worlds_preview(
    name: Annotated[str, typer.Argument(help="World name or spec file.")],
    out: Annotated[Path, typer.Option(help="PNG file to write.")] = Path("world.png"),
) -> None:
    """Draw a world (top-down and oblique views, ground truth coloured by height) to a PNG.

    Examples:
      nbv-gym worlds preview pp1-trees --out pp1-trees.png
    """
    from nbv_gym.worlds import load_world
    from nbv_gym.worlds.preview import save_preview

    typer.echo(save_preview(load_world(name), out))


@app.command()
def bench(
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    suite: Annotated[list[str] | None, typer.Option(help="Only these suites.")] = None,
) -> None:
    """Measure throughput (world build, scans, …); progress goes to stderr.

    Examples:
      nbv-gym bench
      nbv-gym bench --json > bench.json
      nbv-gym bench --suite foundation
    """
    from nbv_gym.bench import run_suites

    results = run_suites(suite, _stderr)
    if as_json:
        typer.echo(json.dumps(results, indent=2))
        return
    for key, value in results.items():
        typer.echo(f"{key:<28} {value:>14,.4g}")


def main() -> None:
    """Entry point of the ``nbv-gym`` console script."""
    app()
