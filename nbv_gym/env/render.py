"""A top-down picture of an exploration: map, viewpoint statistics, frontiers, path and goal; and
the animation of an episode (``exploration.gif``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from nbv_gym.simulator import Exploration, Simulator

UNKNOWN, FREE, OCCUPIED = (0.55, 0.55, 0.58), (0.97, 0.97, 0.95), (0.1, 0.1, 0.12)
FRONTIER = (1.0, 0.55, 0.0)


def render_rgb(sim: Simulator, size_px: int = 520) -> np.ndarray:
    """(size_px, 2 size_px, 3) uint8 picture: left the navigation map (unknown grey, free white,
    occupied black, frontiers orange) with the path, start and robot, and a legend; right the
    observation count n_obs per 1 m column."""
    summary = sim.summary
    titles = (
        f"step {sim.steps} · discovered {sim.navigation.discovered_fraction:.0%}",
        f"Q {summary.q:.3f} · Q_paper {summary.q_paper:.3f} · path {sim.path_length_m:.0f} m",
    )
    return render_exploration(sim, titles, lambda axes: _draw_path(axes, sim), size_px)


def render_exploration(
    exploration: Exploration,
    titles: tuple[str, str],
    draw: Callable[[Any], None],
    size_px: int = 520,
) -> np.ndarray:
    """(size_px, 2 size_px, 3) uint8 picture of ``exploration``'s map (left, with a legend) and
    its n_obs per 1 m column (right), ``draw(axes)`` drawing the robots on both panels,
    ``titles`` over them (left, right)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(size_px / 50, size_px / 100), dpi=100)
    canvas = FigureCanvasAgg(figure)
    left, right = figure.subplots(1, 2)
    extent = _extent(exploration)
    left.imshow(_map_image(exploration).transpose(1, 0, 2), origin="lower", extent=extent)
    draw(left)
    n_obs = exploration.statistics.column("n_obs")
    heat = right.imshow(np.log1p(n_obs).T, origin="lower", extent=extent, cmap="magma")
    draw(right)
    figure.colorbar(heat, ax=right, fraction=0.046, label="log(1 + n_obs) per 1 m column")
    left.set_title(titles[0], fontsize=11)
    right.set_title(titles[1], fontsize=11)
    for axes in (left, right):
        axes.set_xlabel("x (m)", fontsize=10)
        axes.set_ylabel("y (m)", fontsize=10)
        axes.tick_params(labelsize=9)
    _legend(left)
    figure.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def save_animation(frames: list[np.ndarray], path, fps: float) -> None:
    """Write (h, w, 3) uint8 ``frames`` at full resolution as a looping GIF of ``fps`` frames
    per second (the env's ``metadata["render_fps"]``); one shared adaptive palette keeps the
    colours steady from frame to frame."""
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    palette = images[-1].quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    quantised = [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    quantised[0].save(path, save_all=True, append_images=quantised[1:],
                      duration=round(1000 / fps), loop=0, optimize=False)  # fmt: skip


def _legend(axes) -> None:
    """Legend of the map panel: the four cell classes and the path markers."""
    from matplotlib.patches import Patch

    handles, _ = axes.get_legend_handles_labels()
    cells = [Patch(facecolor=c, edgecolor="0.4", label=n) for c, n in
             ((UNKNOWN, "unknown"), (FREE, "free"), (OCCUPIED, "occupied"),
              (FRONTIER, "frontier"))]  # fmt: skip
    axes.legend(handles=cells + handles, loc="upper left", fontsize=8, framealpha=0.85,
                ncol=2, handlelength=1.2)  # fmt: skip


def _extent(sim: Exploration) -> tuple[float, float, float, float]:
    low, high = sim.goal_grid.low, sim.goal_grid.high
    return low[0], high[0], low[1], high[1]


def _map_image(sim: Exploration) -> np.ndarray:
    nav = sim.navigation
    image = np.empty((*nav.known.shape, 3))
    image[:] = UNKNOWN
    image[nav.free] = FREE
    image[nav.occupied] = OCCUPIED
    image[nav.frontier_mask] = FRONTIER
    return image


def _draw_path(axes, sim: Simulator) -> None:
    xy = np.array([[p.x, p.y] for p in sim.trajectory])
    axes.plot(xy[:, 0], xy[:, 1], "-o", color="tab:blue", markersize=3, linewidth=1.2,
              label="path, scans")  # fmt: skip
    axes.plot(*xy[0], "s", color="tab:green", markersize=7, label="start")
    axes.plot(*xy[-1], "*", color="red", markersize=12, label="robot (last goal)")
