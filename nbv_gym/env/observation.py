"""The observation of ``Explore-v0``: fixed-size 2D layers over the 60 × 60 goal grid and the
robot state, all float32 (docs/environment.md#observation).

Each layer is a flat (3600,) vector in goal order — ``layer[g]`` belongs to goal ``g = i · 60 + j``
(``i`` along x), and ``layer.reshape(60, 60)[i, j]`` is the picture — scaled to [0, 1]. Flat
vectors keep Stable-Baselines3's checks and extractors happy; a CNN reshapes them.

========== ===============================================================================
known      fraction of the cell's navigation cells that are known
free       fraction that are known free (before erosion)
occupied   fraction that are occupied
frontier   1 on frontier goals (valid goals at the frontier)
valid      1 on valid goals (the action mask)
cost       min(path length / search range, 1); 1 on invalid goals. In the time task not
           clipped: path length / search range on every valid goal however far (up to
           time budget · speed / search range), so a policy sees what a far goal costs
distance   straight-line distance from the robot / the window's diagonal
robot      1 in the robot's cell
n_obs      log1p(Σ_z n_obs) / log1p(100 · nz), clipped to 1
r_min      min_z r_min / sensor range, clipped to 1; 1 where never observed
n_omega    max_z n_Ω / number of sectors
sigma_theta max_z σ_θ
========== ===============================================================================

``state`` is ``[x / half-width, y / half-width, cos yaw, sin yaw, discovered fraction,
progress]``, progress being steps / max_steps (elapsed time / time budget in the time task).
Optional layers (the NBV gains) are added only when asked for.

An :class:`Observer` is built once from plain values (the goal grid, the sensor range, the number
of sectors, the step limit) and reads the navigation layer and the statistics it is given; the
statistics' 2D projections are kept up to date scan by scan, so a step costs a few (3600,) vector
operations.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from nbv_gym.core import libm
from nbv_gym.core.grid import GridSpec
from nbv_gym.core.pose import Pose
from nbv_gym.core.protocol import TimeBudget
from nbv_gym.mapping import NavigationLayer, ViewpointStatistics

BASE_LAYERS = ("known", "free", "occupied", "frontier", "valid", "cost", "distance", "robot",
               "n_obs", "r_min", "n_omega", "sigma_theta")  # fmt: skip
STATE_SIZE = 6


def observation_space(
    n_goals: int, optional: dict[str, float], cost_high: float = 1.0
) -> spaces.Dict:
    """The Dict space of the base layers, the ``optional`` layers (name → upper bound) and the
    robot state; ``cost_high``: the ``cost`` layer's upper bound (1 but in the time task,
    :meth:`Observer.cost_high`)."""
    entries: dict[str, spaces.Space] = {
        name: spaces.Box(0.0, 1.0, (n_goals,), np.float32) for name in BASE_LAYERS
    }
    entries["cost"] = spaces.Box(0.0, max(cost_high, 1.0), (n_goals,), np.float32)
    for name, high in optional.items():
        entries[name] = spaces.Box(0.0, high, (n_goals,), np.float32)
    entries["state"] = spaces.Box(-2.0, 2.0, (STATE_SIZE,), np.float32)
    return spaces.Dict(entries)


class Observer:
    """Builds observations over the goal grid.

    Args:
        goal_grid: the grid G (its x, y cells are the goals).
        sensor_range_m: the sensor range that scales ``r_min``, metres.
        n_sectors: the azimuth sectors that scale ``n_omega``.
        max_steps: the step limit that scales the state's progress.
        budget: the episode's time budget (none but in the time task; with one the ``cost``
            layer is not clipped at 1 and the progress is elapsed time / the budget).
    """

    def __init__(
        self,
        goal_grid: GridSpec,
        sensor_range_m: float,
        n_sectors: int,
        max_steps: int,
        budget: TimeBudget | None = None,
    ):
        self.shape = goal_grid.shape[:2]
        self.n_goals = self.shape[0] * self.shape[1]
        self.sensor_range_m = float(sensor_range_m)
        self.n_sectors = int(n_sectors)
        self.max_steps = int(max_steps)
        self.budget = budget or TimeBudget()
        self._centres = goal_grid.xy_centres().T.copy()  # (2, n_goals): x row, y row
        self._diagonal = float(np.hypot(*(goal_grid.high[:2] - goal_grid.low[:2])))  # no BLAS
        self._half = goal_grid.high[:2]
        self._n_obs_scale = math.log1p(100 * goal_grid.shape[2])

    def cost_high(self, cost_range_m: float) -> float:
        """The ``cost`` layer's upper bound with the navigation's ``cost_range_m``."""
        if not self.budget.limited:
            return 1.0
        return max(1.0, self.budget.bound_m() / cost_range_m)  # no valid goal's path is longer

    def observe(
        self,
        navigation: NavigationLayer,
        statistics: ViewpointStatistics,
        pose: Pose,
        steps: int,
        optional: dict[str, np.ndarray] | None = None,
        elapsed_s: float = 0.0,
    ) -> dict[str, np.ndarray]:
        """The observation: the base layers, the ``optional`` (n_goals,) layers and the state,
        each a fresh float32 array (rows of one block); ``elapsed_s``: the robot's clock (read
        in the time task)."""
        block = np.empty((len(BASE_LAYERS), self.n_goals), np.float32)
        layers = dict(zip(BASE_LAYERS, block, strict=True))
        self._navigation_layers(navigation, pose, layers)
        self._statistics_layers(statistics, layers)
        for name, layer in (optional or {}).items():  # a copy: the layers' own arrays stay theirs
            layers[name] = np.array(layer, np.float32).ravel()
        layers["state"] = self.state(pose, navigation.discovered_fraction, steps, elapsed_s)
        return layers

    def state(
        self, pose: Pose, discovered: float, steps: int, elapsed_s: float = 0.0
    ) -> np.ndarray:
        """(6,) float32 robot state (see the module docstring)."""
        budget = self.budget
        progress = budget.share(elapsed_s) if budget.limited else steps / self.max_steps
        return np.array(
            [pose.x / self._half[0], pose.y / self._half[1], math.cos(pose.yaw), math.sin(pose.yaw),
             discovered, progress],
            dtype=np.float32,
        )  # fmt: skip

    def _navigation_layers(self, nav: NavigationLayer, pose: Pose, out: dict) -> None:
        for name, fractions in zip(("known", "free", "occupied"), nav.goal_fractions, strict=True):
            out[name][:] = fractions.ravel()
        out["frontier"][:] = nav.frontier_goal_mask()
        out["valid"][:] = nav.goal_mask()
        out["cost"][:] = nav.goal_cost(clipped=not self.budget.limited)  # the time task's: not
        x, y = self._centres
        out["distance"][:] = np.hypot(x - pose.x, y - pose.y) / self._diagonal
        out["robot"][:] = 0.0
        if 0 <= nav.robot_goal < self.n_goals:
            out["robot"][nav.robot_goal] = 1.0

    def _statistics_layers(self, stats: ViewpointStatistics, out: dict) -> None:
        """The four viewpoint statistics of G projected to 2D (see the module docstring)."""
        n_obs = libm.log1p(stats.column("n_obs")) / self._n_obs_scale
        out["n_obs"][:] = np.minimum(n_obs, 1.0).ravel()
        out["r_min"][:] = np.minimum(stats.column("r_min") / self.sensor_range_m, 1.0).ravel()
        out["n_omega"][:] = (stats.column("n_omega") / self.n_sectors).ravel()
        out["sigma_theta"][:] = stats.column("sigma_theta").ravel()
