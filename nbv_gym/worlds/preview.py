"""A picture of a world: top-down and oblique views of its ground truth, coloured by height."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.worlds.scenes import SceneSpec
from nbv_gym.worlds.world import World

MAX_POINTS_3D = 60_000


def save_preview(world: World, path: str | Path) -> Path:
    """Write a PNG with a top-down and an oblique view of ``world``'s ground truth to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    points = world.ground_truth.points()
    figure = plt.figure(figsize=(14, 6.5), dpi=110)
    top = figure.add_subplot(1, 2, 1)
    _top_down(top, world, points)
    oblique = figure.add_subplot(1, 2, 2, projection="3d")
    scatter = _oblique(oblique, points)
    figure.colorbar(scatter, ax=[top, oblique], shrink=0.7, label="height z (m)")
    figure.suptitle(
        f"{world.name}: {world.spec.description}\n"
        f"{_contents(world)}, {len(world.faces):,} triangles, "
        f"{len(points):,} ground-truth voxels at {world.ground_truth.res} m"
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path)
    plt.close(figure)
    return path


def _top_down(axes, world: World, points: np.ndarray) -> None:
    order = np.argsort(points[:, 2])
    axes.scatter(
        points[order, 0],
        points[order, 1],
        c=points[order, 2],
        s=0.3,
        cmap="viridis",
        vmin=0,
        vmax=points[:, 2].max(),
        rasterized=True,
    )
    x0, y0, x1, y1 = world.window_m
    axes.add_patch(_rectangle(x0, y0, x1 - x0, y1 - y0, "window"))
    axes.add_patch(_circle(world.clear_radius_m))
    axes.plot(0, 0, "r^", markersize=9, label="start")
    (gx0, gy0), (gx1, gy1) = world.ground_bounds_xy
    axes.set(
        xlim=(gx0, gx1),
        ylim=(gy0, gy1),
        xlabel="x (m)",
        ylabel="y (m)",
        title="top-down",
        aspect="equal",
    )
    axes.legend(loc="upper right", fontsize=8)


def _contents(world: World) -> str:
    if isinstance(world.spec, SceneSpec):
        return f"scene {world.spec.path.name} ({world.spec.scene.kind})"
    return f"{len(world.layout.xy)} assets"


def _oblique(axes, points: np.ndarray):
    step = max(1, len(points) // MAX_POINTS_3D)
    shown = points[::step]
    scatter = axes.scatter(
        shown[:, 0],
        shown[:, 1],
        shown[:, 2],
        c=shown[:, 2],
        s=0.4,
        cmap="viridis",
        vmin=0,
        vmax=points[:, 2].max(),
        rasterized=True,
    )
    axes.view_init(elev=30, azim=-60)
    axes.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="oblique")
    axes.set_box_aspect((1, 1, max(0.15, np.ptp(points[:, 2]) / max(np.ptp(points[:, 0]), 1))))
    return scatter


def _rectangle(x, y, width, height, label):
    from matplotlib.patches import Rectangle

    return Rectangle((x, y), width, height, fill=False, ls="--", ec="grey", label=label)


def _circle(radius):
    from matplotlib.patches import Circle

    return Circle((0, 0), radius, fill=False, ec="red", label="start disc")
