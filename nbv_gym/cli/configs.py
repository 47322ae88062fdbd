"""``nbv-gym configs``: list, show and copy the configs shipped with the package."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Annotated

import typer

configs_app = typer.Typer(
    help="List, show and copy the shipped configs (sweeps, training, rl-zoo3); list the lidar "
    "presets.",
    no_args_is_help=True,
    rich_markup_mode=None,
)


@configs_app.command("list")
def configs_list() -> None:
    """List the shipped configs: name, kind and what it runs.

    A sweep config's name runs it (nbv-gym sweep NAME), a training config's name trains it
    (nbv-gym train --config NAME); copy one to edit it.

    Examples:

    \b
      nbv-gym configs list
    """
    from nbv_gym.configs import shipped_configs

    for config in shipped_configs().values():
        typer.echo(f"{config.name:<16}{config.kind:<9}{config.summary}")


@configs_app.command("lidars")
def configs_lidars() -> None:
    """List the lidar presets (--lidar NAME, lidar="NAME" on the environment): beams, vertical
    field of view, azimuth samples, rays per scan, datasheet range and source.

    Examples:

    \b
      nbv-gym configs lidars
      nbv-gym run --lidar vlp-16 --world pp1-trees --out runs/vlp16
    """
    from nbv_gym.sensor.presets import LIDAR_PRESETS

    typer.echo(f"{'name':<9}{'beams':>6}{'vertical FoV':>18}{'azimuth':>9}{'rays':>8}{'range':>8}")
    for preset in LIDAR_PRESETS.values():
        low, high = preset.vertical_fov_deg
        fov = f"{low:+.2f}° … {high:+.2f}°"
        config = preset.config
        typer.echo(
            f"{preset.name:<9}{config.n_channels:>6}{fov:>18}{config.n_azimuth:>9}"
            f"{preset.rays:>8,}{preset.range_m:>6.0f} m  {preset.description}"
        )
    typer.echo("\nsources:")
    for preset in LIDAR_PRESETS.values():
        typer.echo(f"  {preset.name}: {preset.source}")


@configs_app.command("show")
def configs_show(
    name: Annotated[
        str, typer.Argument(help="A shipped config's name (see nbv-gym configs list).")
    ],
) -> None:
    """Print a shipped config's file.

    Examples:

    \b
      nbv-gym configs show quick
      nbv-gym configs show ppo
    """
    from nbv_gym.configs import shipped_config

    typer.echo(shipped_config(name).path.read_text(encoding="utf-8"), nl=False)


@configs_app.command("copy")
def configs_copy(
    name: Annotated[
        str, typer.Argument(help="A shipped config's name (see nbv-gym configs list).")
    ],
    path: Annotated[Path, typer.Argument(help="File to write (a folder: NAME.toml inside it).")],
    force: Annotated[bool, typer.Option(help="Overwrite an existing file.")] = False,
) -> None:
    """Copy a shipped config to a file you can edit, then run that file.

    Examples:

    \b
      nbv-gym configs copy quick my-sweep.toml
      nbv-gym sweep my-sweep.toml --out results/my-sweep
      nbv-gym configs copy ppo my-ppo.toml && nbv-gym train --config my-ppo.toml
      nbv-gym configs copy rl-zoo3-ppo .
    """
    from nbv_gym.configs import shipped_config
    from nbv_gym.core.outputs import OutputError, writable_file

    source = shipped_config(name).path
    target = path / source.name if path.is_dir() else path
    if target.exists() and not force:
        raise OutputError(f"{target} exists; pass --force to overwrite it, or give another path.")
    shutil.copyfile(source, writable_file(target, "PATH"))
    typer.echo(f"{name} → {target}")
