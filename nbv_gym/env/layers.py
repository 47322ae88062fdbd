"""Optional observation layers, computed only when a policy or user asks for them: the predicted
NBV gains of the four viewpoint statistics, the volumetric gains (unknown voxels and entropy seen,
:mod:`nbv_gym.nbv.volumetric`) and the candidate mask."""

from __future__ import annotations

import math

import numpy as np

from nbv_gym.nbv import (
    CANDIDATES_LAYER,
    GAIN_LAYERS,
    GainPredictor,
    NbvConfig,
    NbvSensor,
    realised_gains,
)
from nbv_gym.nbv.volumetric import VOLUMETRIC_LAYERS, VoxelTotals, volumetric_gains
from nbv_gym.simulator import Simulator, StepOutcome

#: Names of the optional layers and what they hold (flat (3600,) float32, goal order).
OPTIONAL_LAYERS: dict[str, str] = {
    "gain_nobs": "predicted E[I] of n_obs from each candidate goal, 0 elsewhere",
    "gain_rmin": "predicted E[I] of r_min from each candidate goal, 0 elsewhere",
    "gain_nomega": "predicted E[I] of n_Ω (swept sectors credited) from each candidate, 0 elsewhere",
    "gain_sigma": "predicted E[I] of σ_θ from each candidate goal, 0 elsewhere",
    "gain_unknown": "unknown voxels a scan from each candidate goal would see, 0 elsewhere",
    "gain_entropy": "occupancy entropy (bits) a scan from each candidate would see, 0 elsewhere",
    CANDIDATES_LAYER: "1 on the NBV candidates: valid goals within the search range",
}
assert set(GAIN_LAYERS) | set(VOLUMETRIC_LAYERS) < set(OPTIONAL_LAYERS)


class OptionalLayers:
    """Computes the requested optional layers after each scan (any gain layer brings the
    candidate mask along). The occlusion grid behind the
    gains is kept up to date after every scan (only the touched cells), so a request costs one
    prediction for all requested gain layers together.

    Calibration: after each step :meth:`calibration` gives, per requested gain layer, the gain
    predicted for the goal the robot moved to (``predicted_gain``) and the gain its scan realised
    (``realised_gain``, :func:`~nbv_gym.nbv.realised_gains` on the statistics before and after);
    both NaN after a reset.
    """

    def __init__(self, sim: Simulator, names: tuple[str, ...], config: NbvConfig):
        self.sim = sim
        wants_gains = any(name in (*GAIN_LAYERS, *VOLUMETRIC_LAYERS) for name in names)
        self.names = tuple(dict.fromkeys((*names, *([CANDIDATES_LAYER] if wants_gains else []))))
        resolution_m = sim.config.mapping.map.resolution_m
        self.config = config
        self.sensor = NbvSensor.of(sim.config.lidar, sim.config.mapping)
        self.predictor = (
            GainPredictor(sim.goal_grid, config, resolution_m, self.sensor) if self.names else None
        )
        self.gains = tuple(name for name in self.names if name in GAIN_LAYERS)
        self.volumetric = tuple(name for name in self.names if name in VOLUMETRIC_LAYERS)
        self.totals = VoxelTotals(sim.goal_grid, resolution_m) if self.volumetric else None
        self._layers: dict[str, np.ndarray] = {}
        self._before: tuple[np.ndarray, ...] | None = None
        self._calibration = self._unknown()

    def bounds(self) -> dict[str, float]:
        """Upper bound of each requested layer: a gain sums at most one cell gain (≤ ln(1 /
        floor) or the never-observed r_min) over every cell of G; the mean at most one."""
        per_cell = max(math.log(1.0 / self.config.gain_floor), self.config.unobserved_r_min_m)
        cells = self.sim.goal_grid.size if self.config.aggregate == "sum" else 1
        bounds = {name: float(per_cell * cells) for name in self.gains}
        voxels = float(self.sim.goal_grid.size * self.totals.voxels_per_cell) if self.totals else 0
        bounds.update({name: voxels for name in self.volumetric})  # ≤ 1 per voxel of G
        return {name: bounds.get(name, 1.0) for name in self.names}

    def reset(self) -> None:
        """Forget per-episode state (the occlusion grid of the previous map)."""
        if self.predictor is not None:
            self.predictor.reset()
        if self.totals is not None:
            self.totals.reset()
        self._layers, self._before, self._calibration = {}, None, self._unknown()

    def calibration(self) -> dict[str, dict[str, float]]:
        """``{"predicted_gain": {layer: value}, "realised_gain": {layer: value}}`` of the last
        step, per requested gain layer (``{}`` when no gain layer is requested)."""
        return self._calibration

    def _unknown(self) -> dict[str, dict[str, float]]:
        if not self.gains:
            return {}
        nan = {name: float("nan") for name in self.gains}
        return {"predicted_gain": nan, "realised_gain": dict(nan)}

    def _calibrate(self, statistics) -> None:
        """Compare the last prediction at the goal reached with what the scan realised."""
        now = (statistics.n_obs, statistics.r_min, statistics.sector_mask, statistics.sum_u)
        if self._before is not None and self._layers:
            goal = self.sim.navigation.robot_goal
            realised = realised_gains(self._before, now, self.config, self.sensor)
            self._calibration = {
                "predicted_gain": {n: float(self._layers[n][goal]) for n in self.gains},
                "realised_gain": {n: realised[n] for n in self.gains},
            }
        self._before = tuple(np.array(a, copy=True) for a in now)

    def compute(self, outcome: StepOutcome) -> dict[str, np.ndarray]:
        """The requested layers for the simulator's state after ``outcome``'s scan."""
        if self.predictor is None:
            return {}
        sim = self.sim
        robot_xy = np.array([sim.pose.x, sim.pose.y])
        goal_mask = sim.navigation.goal_mask()
        layers = {CANDIDATES_LAYER: self.predictor.candidates(goal_mask, robot_xy)}
        if self.gains:
            self._calibrate(sim.statistics)
            self.predictor.observe(sim.occupancy, outcome.touched)
            layers.update(self.predictor.predict(sim.statistics, robot_xy, goal_mask, self.gains))
        if self.totals is not None:
            self.totals.update(sim.occupancy, outcome.touched)
            layers.update(
                volumetric_gains(
                    sim.goal_grid,
                    self.totals.table,
                    self.totals.blocking.mask,
                    layers[CANDIDATES_LAYER],
                    self.predictor.sensor,
                )
            )
        self._layers = {name: np.asarray(layers[name], np.float32).ravel() for name in self.names}
        return self._layers
