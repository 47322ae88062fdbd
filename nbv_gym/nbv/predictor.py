"""One object that keeps the occlusion mask up to date and predicts the gain layers of a decision."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from nbv_gym.core.arrays import BoolArray, FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap
from nbv_gym.mapping.statistics import ViewpointStatistics
from nbv_gym.nbv.config import NbvConfig, NbvSensor
from nbv_gym.nbv.gains import GAIN_LAYERS, candidate_mask, goal_centres_xy, predict_gains
from nbv_gym.nbv.occlusion import OcclusionGrid

#: The layer that marks the candidates (1) among the goals (0 elsewhere).
CANDIDATES_LAYER = "nbv_candidates"


class GainPredictor:
    """The statistic-based NBV's view of an episode: occlusion kept up to date scan by scan, and
    the gain layers of the candidates on demand.

    Args:
        grid: the statistics grid G (its x, y cells are the goals).
        config: the NBV config.
        resolution_m: the map's voxel size, metres.
        sensor: the sensor predicted for (default: :meth:`NbvSensor.default`).

    Use: :meth:`reset` at the start of an episode, :meth:`observe` after each scan with the map and
    the scan's ``ScanUpdate.touched``, then :meth:`predict` for the layers.
    """

    def __init__(
        self,
        grid: GridSpec,
        config: NbvConfig,
        resolution_m: float = MapConfig.resolution_m,
        sensor: NbvSensor | None = None,
    ):
        self.grid = grid
        self.config = config
        self.sensor = sensor or NbvSensor.default()
        config.sight_model(self.sensor)  # checks config and sensor together
        self.occlusion = OcclusionGrid(grid, resolution_m, config.blocking_probability)
        self._centres = goal_centres_xy(grid)

    def reset(self) -> None:
        """Forget the occlusion mask (a new, empty map)."""
        self.occlusion.reset()

    def observe(self, occupancy_map: OccupancyMap, touched: BoolArray | None) -> None:
        """Bring the occlusion mask up to date with the cells of G a scan touched ((nx, ny, nz)
        bool; None recomputes every cell)."""
        self.occlusion.update(occupancy_map, touched)

    def candidates(self, goal_mask: BoolArray, robot_xy: FloatArray) -> np.ndarray:
        """(n_goals,) bool: valid goals within the search range of ``robot_xy`` (2,) metres."""
        goal_mask = np.asarray(goal_mask, bool).ravel()
        if goal_mask.shape != (len(self._centres),):
            raise NbvGymError(
                f"goal_mask must have {len(self._centres)} entries (one per goal), "
                f"got {goal_mask.shape}"
            )
        return candidate_mask(goal_mask, robot_xy, self._centres, self.config.search_range_m)

    def predict(
        self,
        statistics: ViewpointStatistics,
        robot_xy: FloatArray,
        goal_mask: BoolArray,
        layers: Sequence[str] = GAIN_LAYERS,
    ) -> dict[str, np.ndarray]:
        """The requested gain layers and :data:`CANDIDATES_LAYER`, each (nx, ny) float32.

        Args:
            statistics: the viewpoint statistics now.
            robot_xy: (2,) float the robot's position, metres.
            goal_mask: (n_goals,) bool valid goals (``NavigationLayer.goal_mask()``).
            layers: names among :data:`GAIN_LAYERS` (and optionally :data:`CANDIDATES_LAYER`).
        """
        gains = [name for name in layers if name != CANDIDATES_LAYER]
        candidates = self.candidates(goal_mask, robot_xy)
        out = predict_gains(
            statistics, self.occlusion.mask, robot_xy, candidates, self.config, gains, self.sensor
        )
        out[CANDIDATES_LAYER] = candidates.reshape(self.grid.shape[:2]).astype(np.float32)
        return out
