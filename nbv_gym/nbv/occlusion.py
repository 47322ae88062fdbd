"""Which cells of G occlude a candidate's view: those holding a map voxel with p ≥ 0.8 (docs/protocol.md#visibility).

The mask is kept up to date incrementally: after a scan only the cells of G holding a voxel the scan
changed (``ScanUpdate.touched``) are recomputed from the map.
"""

from __future__ import annotations

import numpy as np

from nbv_gym.core.arrays import BoolArray
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap, logit


class OcclusionGrid:
    """(nx, ny, nz) bool mask over G: a cell occludes iff it holds a voxel with p ≥ the threshold.

    Args:
        grid: the statistics grid G (cells a whole number of voxels, aligned to the map).
        resolution_m: the map's voxel size, metres.
        occluding_probability: threshold p of an occluding voxel.
    """

    def __init__(
        self,
        grid: GridSpec,
        resolution_m: float = MapConfig.resolution_m,
        occluding_probability: float = 0.8,
    ):
        if not 0 < occluding_probability < 1:
            raise ConfigError(
                f"occluding_probability: must be in (0, 1), got {occluding_probability}"
            )
        factor = grid.res / resolution_m
        if round(factor) < 1 or abs(factor - round(factor)) > 1e-6:
            raise ConfigError(
                f"G's {grid.res} m cells must be a whole number of {resolution_m} m voxels"
            )
        self.grid = grid
        self.threshold_logodds = logit(occluding_probability)
        self._mask = np.zeros(grid.shape, bool)

    @property
    def mask(self) -> np.ndarray:
        """(nx, ny, nz) bool occluding cells (a read-only view; copy to keep it)."""
        view = self._mask.view()
        view.flags.writeable = False
        return view

    def reset(self) -> None:
        """Forget everything (an empty map occludes nothing)."""
        self._mask[:] = False

    def update(self, occupancy_map: OccupancyMap, touched: BoolArray | None = None) -> int:
        """Recompute the ``touched`` (nx, ny, nz) bool cells from ``occupancy_map`` (all cells when
        None); returns the number of cells recomputed.

        Reads only the touched cells' voxels, each up to its first occluding one
        (``OccupancyMap.cells_reaching``; unknown voxels never occlude).
        """
        touched = np.ones(self.grid.shape, bool) if touched is None else np.asarray(touched, bool)
        if touched.shape != self.grid.shape:
            raise NbvGymError(f"touched must have G's shape {self.grid.shape}, got {touched.shape}")
        cells = np.argwhere(touched)
        reaching = occupancy_map.cells_reaching(self.grid, cells, self.threshold_logodds)
        self._mask[tuple(cells.T)] = reaching
        return len(cells)
