"""``nbv-gym worlds``: list, build and preview the benchmark worlds; import your own scene."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from nbv_gym.cli.params import POSITIVE
from nbv_gym.core.progress import progress_bar

worlds_app = typer.Typer(
    help="List, build and preview the benchmark worlds; import your own scene.",
    no_args_is_help=True,
    rich_markup_mode=None,
)


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
    from nbv_gym.worlds.importer import import_scene

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
