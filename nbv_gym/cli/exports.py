"""Commands that carry results out of the package: ``export`` (a map as PLY, PCD or OctoMap),
``view`` (a 3D page to turn around) and ``record`` (episodes as a Minari dataset). Heavy imports
happen inside each command, so ``nbv-gym --help`` stays instant."""

from __future__ import annotations

import sys
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
from nbv_gym.cli.params import COUNT, FINITE, NOISE_HELP, NOISE_LEVEL, POSITIVE_COUNT, PROBABILITY
from nbv_gym.mapping.mapfile import load_map


def export(
    map_path: Annotated[Path, typer.Argument(help="Saved map (.npz), e.g. RUN_DIR/map.npz.")],
    format: Annotated[str, typer.Option("--format", help="ply, pcd or bt (OctoMap).")] = "ply",
    min_p: Annotated[
        float | None,
        typer.Option(
            "--min-p",
            help="Only voxels with probability ≥ this (ply, pcd) [default: 0.5].",
            parser=PROBABILITY,
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="File to write (default: the map's name, new suffix).")
    ] = None,
) -> None:
    """Export a saved map: occupied voxel centres with their probability (PLY, PCD) or the
    whole map as an OctoMap .bt (needs pyoctomap: pip install "nbv-gym[octomap]").

    PLY and PCD hold float32 x, y, z (metres) and the scalar field "probability"; they open
    in CloudCompare, MeshLab, Open3D and PCL.

    Examples:

    \b
      nbv-gym export runs/cf/map.npz --format pcd --out map.pcd
      nbv-gym export runs/cf/map.npz --min-p 0.7
      nbv-gym export runs/cf/map.npz --format bt
    """
    from nbv_gym.core.errors import missing_file
    from nbv_gym.core.outputs import writable_file
    from nbv_gym.mapping.export import FORMATS, ExportError, export_map

    if format not in FORMATS:
        raise ExportError(f"unknown format {format!r}; use one of {', '.join(FORMATS)}")
    if not map_path.is_file():
        raise ExportError(f"{map_path}: the map file {missing_file(map_path)}")
    if format == "bt" and min_p is not None:
        raise ExportError(
            "--min-p applies to ply and pcd; an OctoMap .bt holds the whole map (every voxel "
            "with its log-odds). Leave --min-p out, or export ply or pcd."
        )
    out = out or map_path.with_suffix(f".{format}")
    if out.suffix.lower() != f".{format}":
        raise ExportError(f"--out {out} does not end in .{format}; name it *.{format}")
    count = export_map(load_map(map_path), writable_file(out), 0.5 if min_p is None else min_p)
    typer.echo(f"{count:,} voxels → {out}")


def view(
    source: Annotated[Path, typer.Argument(help="Run folder (nbv-gym run) or a map .npz.")],
    colour_by: Annotated[
        str,
        typer.Option("--colour-by", help="probability, n_obs, r_min, n_omega or sigma_theta."),
    ] = "probability",
    world: Annotated[
        str | None, typer.Option(help="World whose ground truth to draw (default: the run's).")
    ] = None,
    min_p: Annotated[
        float, typer.Option("--min-p", help="Voxels drawn: p ≥ this.", parser=PROBABILITY)
    ] = 0.5,
    min_z: Annotated[
        float,
        typer.Option(
            "--min-z", help="Voxels drawn: centre z ≥ this, metres (0.2: no ground).", parser=FINITE
        ),
    ] = 0.2,
    max_points: Annotated[
        int, typer.Option(help="Thin larger clouds to this many.", parser=POSITIVE_COUNT)
    ] = 150_000,
    out: Annotated[
        Path | None, typer.Option(help="HTML file (default: RUN_DIR/view.html).")
    ] = None,
    offline: Annotated[
        bool,
        typer.Option(help="Inline plotly.js (3.5 MB) so the page opens without a network."),
    ] = False,
) -> None:
    """Write a 3D view of a run (one HTML file; drag to turn, scroll to zoom): the map's
    occupied voxels coloured by probability or a viewpoint statistic, the ground truth
    translucent, and the robot's path and scan poses. The page loads plotly.js from its CDN;
    --offline inlines it (3.5 MB more) for a page that opens without a network.

    Examples:

    \b
      nbv-gym view runs/cf
      nbv-gym view runs/cf --colour-by n_obs --out cf-nobs.html
      nbv-gym view runs/cf/map.npz --world pp1-trees
      nbv-gym view runs/cf --offline    # to mail or archive
    """
    from nbv_gym.core.outputs import writable_file
    from nbv_gym.reporting.view import VIEW_NAME, load_scene, write_view

    if out is None:
        out = (source if source.is_dir() else source.parent) / VIEW_NAME
    writable_file(out)
    scene = load_scene(source, colour_by, world, min_p, max_points, min_z_m=min_z)
    typer.echo(write_view(scene, out, offline))


def record(
    policy: Annotated[str, typer.Option(help="Policy name or module:Class.")],
    world: Annotated[str, typer.Option(help="World name or spec file.")],
    out: Annotated[Path, typer.Option(help="Folder of the Minari dataset.")],
    episodes: Annotated[int, typer.Option(help="Episodes to record.", parser=POSITIVE_COUNT)] = 1,
    noise: Annotated[int, typer.Option(help=NOISE_HELP, parser=NOISE_LEVEL)] = 1,
    seed: Annotated[
        int, typer.Option(help="Seed of the first episode (then +1 each).", parser=COUNT)
    ] = 0,
    task: TaskOption = None,
    budget_scans: BudgetScansOption = None,
    max_steps: MaxStepsOption = None,
    time_budget_s: TimeBudgetOption = None,
    speed_mps: SpeedOption = None,
    scan_time_s: ScanTimeOption = None,
    lidar: AgentLidarOption = None,
    dataset_id: Annotated[
        str | None, typer.Option(help="Minari dataset id (default: nbv-gym/WORLD/POLICY-v0).")
    ] = None,
) -> None:
    """Record episodes of a policy as a Minari dataset (observations, actions, rewards,
    terminations, truncations; action masks in the infos) for offline RL or imitation
    (needs minari: pip install "nbv-gym[data]").

    --out is the datasets root: load with MINARI_DATASETS_PATH=OUT and
    minari.load_dataset(ID), or nbv_gym.rl.dataset.load_recording(OUT, ID); each episode's reset
    seed is in its metadata, so its actions replay to the same rewards.

    Examples:

    \b
      nbv-gym record --policy nbv-nobs --world pp1-trees --episodes 3 \\
          --out data/nbv-nobs
      nbv-gym record --policy closest-frontier --world pp2-crosses \\
          --max-steps 30 --out data/cf
      nbv-gym record --policy ppo-budget --world pp3-trees --episodes 5 \\
          --out data/ppo  # its own task: budget, 12 scans
      nbv-gym record --policy ig-unknown --world pp1-trees --task time \\
          --time-budget-s 300 --out data/ig
    """
    from nbv_gym.rl.dataset import record_dataset
    from nbv_gym.sensor.presets import lidar_preset

    if lidar is not None:
        lidar_preset(lidar)  # an unknown preset fails first
    settings = task_config(policy, noise, task, budget_scans, max_steps, time_budget_s,
                           speed_mps, scan_time_s, lidar)  # fmt: skip

    def progress(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    dataset = record_dataset(
        policy, world, out, settings, episodes=episodes, seed=seed, dataset_id=dataset_id,
        progress=progress,
    )  # fmt: skip
    typer.echo(f"{dataset.total_episodes} episodes, {dataset.total_steps} steps → {out}")
