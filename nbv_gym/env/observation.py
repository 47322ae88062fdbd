"""The observation of ``Explore-v0``: fixed-size 2D layers over the 60 × 60 goal grid and the
robot state, all float32 (SPEC §6).

Each layer is a flat (3600,) vector in goal order — ``layer[g]`` belongs to goal ``g = i · 60 + j``
(``i`` along x), and ``layer.reshape(60, 60)[i, j]`` is the picture — scaled to [0, 1]. Flat
vectors keep Stable-Baselines3's checks and extractors happy; a CNN reshapes them.

========== ===============================================================================
known      fraction of the cell's navigation cells that are known
free       fraction that are known free (before erosion)
occupied   fraction that are occupied
frontier   1 on frontier goals (valid goals at the frontier)
valid      1 on valid goals (the action mask)
cost       min(path length / search range, 1); 1 on invalid goals
distance   straight-line distance from the robot / the window's diagonal
robot      1 in the robot's cell
n_obs      log1p(Σ_z n_obs) / log1p(100 · nz), clipped to 1
r_min      min_z r_min / sensor range, clipped to 1; 1 where never observed
n_omega    max_z n_Ω / number of sectors
sigma_theta max_z σ_θ
========== ===============================================================================

``state`` is ``[x / half-width, y / half-width, cos yaw, sin yaw, discovered fraction,
steps / max_steps]``. Optional layers (the NBV gains) are added only when asked for.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from nbv_gym.simulator import Simulator

BASE_LAYERS = ("known", "free", "occupied", "frontier", "valid", "cost", "distance", "robot",
               "n_obs", "r_min", "n_omega", "sigma_theta")  # fmt: skip
STATE_SIZE = 6


def observation_space(n_goals: int, optional: dict[str, float]) -> spaces.Dict:
    """The Dict space of the base layers, the ``optional`` layers (name → upper bound) and the
    robot state."""
    entries = {name: spaces.Box(0.0, 1.0, (n_goals,), np.float32) for name in BASE_LAYERS}
    for name, high in optional.items():
        entries[name] = spaces.Box(0.0, high, (n_goals,), np.float32)
    entries["state"] = spaces.Box(-2.0, 2.0, (STATE_SIZE,), np.float32)
    return spaces.Dict(entries)


def base_layers(sim: Simulator) -> dict[str, np.ndarray]:
    """The base layers of the simulator's current state."""
    nx, ny = sim.goal_grid.shape[:2]
    nav = sim.state.navigation
    mask = nav.goal_mask()
    layers = {
        "known": _coarse_mean(nav.known, nx, ny),
        "free": _coarse_mean(nav.free, nx, ny),
        "occupied": _coarse_mean(nav.occupied, nx, ny),
        "frontier": nav.frontier_goal_mask(),
        "valid": mask,
        "cost": nav.goal_cost(),
        "distance": _distance(sim),
        "robot": _one_hot(nav.robot_goal, nx * ny),
        **statistics_layers(sim),
    }
    return {name: np.asarray(value, np.float32).ravel() for name, value in layers.items()}


def statistics_layers(sim: Simulator) -> dict[str, np.ndarray]:
    """The four viewpoint statistics of G projected to 2D (see the module docstring)."""
    stats = sim.state.statistics
    nz = stats.n_obs.shape[2]
    with np.errstate(invalid="ignore"):
        r_min = np.nanmin(np.where(np.isnan(stats.r_min), np.inf, stats.r_min), axis=2)
    return {
        "n_obs": np.minimum(np.log1p(stats.n_obs.sum(axis=2)) / np.log1p(100 * nz), 1.0),
        "r_min": np.minimum(r_min / sim.config.mapping.sensor_range_m, 1.0),
        "n_omega": stats.n_omega.max(axis=2) / sim.config.mapping.statistics.n_sectors,
        "sigma_theta": stats.sigma_theta.max(axis=2),
    }


def robot_state(sim: Simulator) -> np.ndarray:
    """(6,) float32 robot state (see the module docstring)."""
    half = sim.goal_grid.high[:2]
    pose = sim.pose
    return np.array(
        [pose.x / half[0], pose.y / half[1], np.cos(pose.yaw), np.sin(pose.yaw),
         sim.state.navigation.discovered_fraction,
         sim.steps / sim.config.episode.max_steps],
        dtype=np.float32,
    )  # fmt: skip


def _coarse_mean(fine: np.ndarray, nx: int, ny: int) -> np.ndarray:
    fx, fy = fine.shape[0] // nx, fine.shape[1] // ny
    return fine.reshape(nx, fx, ny, fy).mean(axis=(1, 3))


def _distance(sim: Simulator) -> np.ndarray:
    offset = sim.goal_centres - [sim.pose.x, sim.pose.y]
    diagonal = np.linalg.norm(sim.goal_grid.high[:2] - sim.goal_grid.low[:2])
    return np.hypot(offset[:, 0], offset[:, 1]) / diagonal


def _one_hot(index: int, size: int) -> np.ndarray:
    out = np.zeros(size)
    if 0 <= index < size:
        out[index] = 1.0
    return out
