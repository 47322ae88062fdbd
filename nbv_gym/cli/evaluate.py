"""``nbv-gym evaluate``: score a map against a world's ground truth, or a point cloud against another."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, cast

import numpy as np
import typer

from nbv_gym.cli.params import POSITIVE
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.core.outputs import claim_folder
from nbv_gym.core.progress import Stages
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.empir3d_config import Empir3DConfig
from nbv_gym.metrics.evaluation import (
    CSV_NAME,
    REGIONS_NAME,
    SUMMARY_NAME,
    TRUTH_CLOUD_SUFFIXES,
    alg1_inputs,
    check_map_world,
    check_probability_file,
    empir3d_config,
    load_ground_truth,
    load_probability,
    map_summary,
    world_inputs,
    write_cuboid_csv,
    write_rows,
)

_EMPIR3D = Empir3DConfig()
#: ``--epsilon`` and ``--region`` of the Empir3D commands (``evaluate``, ``study empir3d``); None
#: is the config's value.
EpsilonOption = Annotated[
    float | None,
    typer.Option(
        help=f"Empir3D cell size ε, metres [default: {_EMPIR3D.epsilon_m}].", parser=POSITIVE
    ),
]
RegionOption = Annotated[
    float | None,
    typer.Option(
        help=f"Empir3D region size r, metres [default: {_EMPIR3D.region_m}].", parser=POSITIVE
    ),
]

HEATMAP_NAME = "quality.png"


def evaluate(
    reference: Annotated[
        Path | None, typer.Argument(help="Ground-truth point cloud (.ply .pcd .npy .xyz).")
    ] = None,
    candidate: Annotated[Path | None, typer.Argument(help="Point cloud to score.")] = None,
    map_path: Annotated[
        Path | None,
        typer.Option("--map", help="Saved map (.npz) or a (600, 600, 60) probability grid (.npy)."),
    ] = None,
    world: Annotated[
        str | None, typer.Option(help="World whose ground truth scores --map.")
    ] = None,
    ground_truth: Annotated[
        Path | None,
        typer.Option(
            help="Instead of --world: a ground-truth point cloud (.ply .pcd .xyz .las .laz; "
            "Alg. 1) or a bool grid (.npy)."
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Folder for the CSV, summary and heat map.")
    ] = None,
    epsilon: EpsilonOption = None,
    region: RegionOption = None,
    json_output: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Quality metrics of a map against a world's ground truth, or of a point cloud against another.

    With --map: per-cuboid cov (4 settings), L1, WD_occ and quality into DIR/cuboids.csv, the
    summary (Q, Q_paper, cov x4, L1, WD_occ statistics) into DIR/summary.json and a heat map of the
    per-cuboid quality into DIR/quality.png. With --ground-truth CLOUD (a map that did not come
    from nbv-gym, scored against a real scan): Alg. 1 of the paper — both on 0.1 m voxels,
    compared over the 1 m cuboids meeting the intersection of the map's and the cloud's
    bounding boxes; --map is then a saved map (.npz), an OctoMap (.bt, .ot; needs
    nbv-gym[octomap]) or a PLY of known voxel centres with a probability property (nbv-gym
    export --min-p 0). With two point clouds (ground truth first): the Empir3D scores Q_r, Q_a,
    Q_c, Q_t and the Chamfer and Hausdorff distances (per-region table in DIR/regions.csv with
    --out).

    Examples:

        nbv-gym evaluate --map runs/pp1-trees/map.npz --world pp1-trees --out eval/

        nbv-gym evaluate --map prob.npy --ground-truth gt.npy --out eval/ --json

        nbv-gym evaluate --map robot-map.ply --ground-truth park-scan.las --json

        nbv-gym evaluate truth.ply scan.pcd --epsilon 0.05 --region 2 --json
    """
    if map_path is not None:
        if reference is not None or candidate is not None:
            raise MetricInputError("give either --map or two point clouds, not both")
        summary = evaluate_map(map_path, world, ground_truth, out)
    elif reference is not None and candidate is not None:
        summary = evaluate_clouds(reference, candidate, epsilon, region, out)
    else:
        raise MetricInputError(
            "nothing to evaluate: give --map MAP with --world NAME (or --ground-truth GT.npy), "
            "or two point clouds REFERENCE CANDIDATE"
        )
    typer.echo(dumps_json(summary, indent=None) if json_output else _table(summary))


def evaluate_map(
    map_path: Path, world: str | None, ground_truth: Path | None, out: Path | None
) -> dict:
    """Score a map on the benchmark grid; write the CSV, summary and heat map to ``out``; the summary."""
    from nbv_gym.metrics.cuboids import benchmark_grid
    from nbv_gym.metrics.tracker import evaluate_cuboids
    from nbv_gym.metrics.wasserstein import wd_occ

    check_map_world(map_path, world)
    if (world is None) == (ground_truth is None):
        raise MetricInputError(
            "give exactly one of --world NAME and --ground-truth (a cloud, or a GT.npy grid)"
        )
    cloud = ground_truth is not None and _is_cloud(ground_truth)
    if not cloud:
        check_probability_file(map_path)  # before any world is built
    if out is not None:
        claim_folder(out, "evaluate")
    with Stages(4) as stage:
        stage("reading the map")
        stage("reading the ground truth; the grid scored")
        if cloud:
            prob, truth, grid = alg1_inputs(map_path, cast(Path, ground_truth))
        elif world is not None:
            prob, truth, grid = world_inputs(map_path, world)
        else:
            grid = benchmark_grid()
            prob = load_probability(map_path, grid)
            truth = load_ground_truth(cast(Path, ground_truth), grid)
        stage("cov, L1, Q per cuboid (kernels compile on a first run, then are cached)")
        metrics = evaluate_cuboids(prob, truth)
        stage("WD_occ per cuboid")
        wd = wd_occ(prob, truth, metrics.config, metrics.observed)
    summary = map_summary(metrics, wd)
    if out is not None:
        write_cuboid_csv(out / CSV_NAME, metrics, wd, grid)
        (out / SUMMARY_NAME).write_text(dumps_json(summary) + "\n", encoding="utf-8")
        _write_heatmap(out / HEATMAP_NAME, metrics.quality, summary["q"])
    return summary


def _is_cloud(path: Path) -> bool:
    return path.suffix.lower() in TRUTH_CLOUD_SUFFIXES


def evaluate_clouds(
    reference: Path,
    candidate: Path,
    epsilon: float | None,
    region: float | None,
    out: Path | None,
) -> dict:
    """Empir3D of ``candidate`` against ``reference``; per-region CSV into ``out``; the scalar results."""
    from nbv_gym.core.pointclouds import read_points
    from nbv_gym.metrics.empir3d import empir3d

    if out is not None:
        claim_folder(out, "evaluate")
    config = empir3d_config(epsilon, region)
    result = empir3d(read_points(reference), read_points(candidate), config, distances=True)
    summary = {"reference": str(reference), "candidate": str(candidate), **result.as_dict()}
    if out is not None:
        write_rows(out / REGIONS_NAME, result.regions.rows())
    return summary


def _write_heatmap(path: Path, quality: np.ndarray, q: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    layers = quality.shape[2]
    fig, axes = plt.subplots(1, layers, figsize=(2.6 * layers + 1, 3.2), squeeze=False)
    for k, ax in enumerate(axes[0]):
        image = ax.imshow(quality[:, :, k].T, origin="lower", vmin=0, vmax=1, cmap="viridis")
        ax.set_title(f"layer z{k}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.colorbar(image, ax=axes[0].tolist(), shrink=0.8, label="cuboid quality")
    fig.suptitle(f"Per-cuboid quality (Q = {q:.3f})")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _table(summary: dict) -> str:
    width = max(len(k) for k in summary)
    return "\n".join(f"{k:<{width}}  {_format(v)}" for k, v in summary.items())


def _format(value) -> str:
    from nbv_gym.reporting.formatting import number_text

    return number_text(value, ".6g") if isinstance(value, float) else str(value)
