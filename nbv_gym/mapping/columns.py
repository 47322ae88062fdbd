"""Per-column counts of the voxels the navigation layer projects, kept up to date by the map's
insertion, so that a scan's projection needs no re-scan of the columns it changed.

For each cell of a 2D grid aligned to the map (the navigation grid), the number of known voxels
whose centre lies in the known band and the number of occupied voxels in the occupied band of
its columns; the cell is known / occupied iff its count is positive (as
:meth:`OccupancyMap.project <nbv_gym.mapping.OccupancyMap.project>` decides by scanning).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.mapping.traversal import OUTSIDE


@dataclass
class ColumnCounts:
    """Counts over an (nx, ny) grid; built by
    :meth:`OccupancyMap.column_counts <nbv_gym.mapping.OccupancyMap.column_counts>`.

    Attributes:
        x_cell, y_cell: the grid cell of each map voxel index along x and y (−1 outside).
        layers: (4,) int64 [k0, k1) z layers of the known band, then of the occupied band.
        bound: a stored value at or above it is occupied (with the map's occupied threshold).
        known, occupied: (nx, ny) int32 counts.
        changed: (nx, ny) bool cells whose counts changed since :meth:`take_changed`.
    """

    x_cell: np.ndarray
    y_cell: np.ndarray
    layers: np.ndarray
    bound: np.float32
    known: np.ndarray
    occupied: np.ndarray
    changed: np.ndarray

    def __post_init__(self) -> None:
        ny = self.known.shape[1]
        #: per voxel index along x and y its part of the flat cell index (the sum < 0 outside)
        self.x_part = np.where(self.x_cell >= 0, self.x_cell * ny, OUTSIDE)
        self.y_part = np.where(self.y_cell >= 0, self.y_cell, OUTSIDE)

    def kernel_args(self) -> tuple:
        """What the insertion kernel reads and updates, in its order: :attr:`x_part` and
        :attr:`y_part`, the layers, the bound and flat views of the counts and flags."""
        return (
            self.x_part, self.y_part, self.layers, self.bound, self.known.reshape(-1),
            self.occupied.reshape(-1), self.changed.reshape(-1),
        )  # fmt: skip

    def take_changed(self) -> np.ndarray:
        """(m, 2) int64 the cells whose counts changed since the last call, and forget them."""
        flat = np.flatnonzero(self.changed)  # the flags are few: read and reset only them
        self.changed.reshape(-1)[flat] = False
        return np.stack(np.divmod(flat, self.changed.shape[1]), axis=1)

    def clear(self) -> None:
        """Every count 0 (an empty map)."""
        self.known[:] = 0
        self.occupied[:] = 0
        self.changed[:] = False


#: The counts of a map insertion that keeps none.
NO_COLUMNS = ColumnCounts(
    x_cell=np.full(0, -1, np.int64),
    y_cell=np.full(0, -1, np.int64),
    layers=np.zeros(4, np.int64),
    bound=np.float32(0),
    known=np.zeros((0, 0), np.int32),
    occupied=np.zeros((0, 0), np.int32),
    changed=np.zeros((0, 0), bool),
)
