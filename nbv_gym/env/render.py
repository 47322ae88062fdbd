"""A top-down picture of an exploration: map, viewpoint statistics, frontiers, path and goal."""

from __future__ import annotations

import numpy as np

from nbv_gym.simulator import Simulator

UNKNOWN, FREE, OCCUPIED = (0.55, 0.55, 0.58), (0.97, 0.97, 0.95), (0.1, 0.1, 0.12)
FRONTIER = (1.0, 0.55, 0.0)


def render_rgb(sim: Simulator, size_px: int = 640) -> np.ndarray:
    """(size_px, size_px, 3) uint8 picture: left the navigation map (unknown grey, free white,
    occupied black, frontiers orange) with the path and last goal, right the observation count
    n_obs per 1 m column."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (left, right) = plt.subplots(1, 2, figsize=(size_px / 50, size_px / 100), dpi=100)
    extent = _extent(sim)
    left.imshow(_map_image(sim).transpose(1, 0, 2), origin="lower", extent=extent)
    _draw_path(left, sim)
    n_obs = sim.state.statistics.n_obs.sum(axis=2)
    heat = right.imshow(np.log1p(n_obs).T, origin="lower", extent=extent, cmap="magma")
    _draw_path(right, sim)
    figure.colorbar(heat, ax=right, fraction=0.046, label="log(1 + n_obs)")
    summary = sim.summary
    left.set_title(
        f"step {sim.steps} · discovered {sim.state.navigation.discovered_fraction:.0%}", fontsize=9
    )
    right.set_title(
        f"Q {summary.q:.3f} · Q_paper {summary.q_paper:.3f} · path {sim.path_length_m:.0f} m",
        fontsize=9,
    )
    for axes in (left, right):
        axes.set(xlabel="x (m)", ylabel="y (m)")
        axes.tick_params(labelsize=7)
    figure.tight_layout()
    figure.canvas.draw()
    image = np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()
    plt.close(figure)
    return image


def _extent(sim: Simulator) -> tuple[float, float, float, float]:
    low, high = sim.goal_grid.low, sim.goal_grid.high
    return low[0], high[0], low[1], high[1]


def _map_image(sim: Simulator) -> np.ndarray:
    nav = sim.state.navigation
    image = np.empty((*nav.known.shape, 3))
    image[:] = UNKNOWN
    image[nav.free] = FREE
    image[nav.occupied] = OCCUPIED
    image[nav.frontier_mask] = FRONTIER
    return image


def _draw_path(axes, sim: Simulator) -> None:
    xy = np.array([[p.x, p.y] for p in sim.trajectory])
    axes.plot(xy[:, 0], xy[:, 1], "-o", color="tab:blue", markersize=2.5, linewidth=1)
    axes.plot(*xy[0], "s", color="tab:green", markersize=6, label="start")
    axes.plot(*xy[-1], "*", color="red", markersize=11, label="robot / last goal")
