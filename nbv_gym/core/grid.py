"""Regular axis-aligned 3D grids: the voxel map, the ground truth and the statistics grid G.

All grids in nbv-gym share one convention: cell ``(i, j, k)`` covers
``[origin + (i, j, k) * res, origin + (i + 1, j + 1, k + 1) * res)`` in the map frame (metres),
arrays are indexed ``[i, j, k]`` = ``[x, y, z]``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.errors import ConfigError, DataFileError

#: The arrays :meth:`GridSpec.to_arrays` writes.
GRID_ARRAYS = ("origin", "res", "shape")
#: The longest side of a world's window, metres: the largest window the map's goal grid grows to
#: (the mapping's ``max_window_m`` default); a larger world could not be mapped whole.
MAX_WINDOW_M = 500.0


def float_triple(values: Iterable[float]) -> tuple[float, float, float]:
    """Three values as a tuple of floats (x, y, z); ValueError unless there are exactly three."""
    x, y, z = (float(v) for v in values)
    return x, y, z


def int_triple(values: Iterable[int]) -> tuple[int, int, int]:
    """Three values as a tuple of ints (x, y, z); ValueError unless there are exactly three."""
    i, j, k = (int(v) for v in values)
    return i, j, k


@dataclass(frozen=True)
class GridSpec:
    """A regular grid: ``origin`` (3,) float metres of the low corner, cell size ``res`` metres and
    ``shape`` (3,) cells along x, y, z."""

    origin: tuple[float, float, float]
    res: float
    shape: tuple[int, int, int]

    @classmethod
    def from_bounds(
        cls, low: tuple[float, float, float], high: tuple[float, float, float], res: float
    ) -> GridSpec:
        """The grid of cells of size ``res`` that exactly tiles the box ``[low, high]`` (metres)."""
        extent = (np.asarray(high, float) - np.asarray(low, float)) / res
        shape = np.rint(extent).astype(int)
        if np.any(shape <= 0) or not np.allclose(extent, shape, atol=1e-6):
            raise ConfigError(f"box {low}–{high} is not a positive whole number of {res} m cells")
        return cls(float_triple(low), float(res), int_triple(shape))

    @property
    def low(self) -> FloatArray:
        """(3,) float: the low corner in metres."""
        return np.asarray(self.origin, dtype=float)

    @property
    def high(self) -> FloatArray:
        """(3,) float: the high corner in metres."""
        return self.low + self.res * np.asarray(self.shape, dtype=float)

    @property
    def size(self) -> int:
        """Number of cells."""
        return int(np.prod(self.shape))

    def index(self, points: FloatArray) -> IntArray:
        """(n, 3) int64 cell indices of (n, 3) points in metres (not bounds-checked)."""
        return np.floor((np.asarray(points, float) - self.low) / self.res).astype(np.int64)

    def contains(self, index: IntArray) -> np.ndarray:
        """(n,) bool: which (n, 3) cell indices lie inside the grid."""
        index = np.asarray(index)
        return np.all((index >= 0) & (index < np.asarray(self.shape)), axis=-1)

    def centres(self, index: IntArray) -> FloatArray:
        """(n, 3) float centres in metres of (n, 3) cell indices."""
        return self.low + (np.asarray(index, float) + 0.5) * self.res

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The grid as arrays ``origin``, ``res``, ``shape`` (for ``.npz`` files)."""
        return {
            "origin": np.asarray(self.origin, float),
            "res": np.asarray(self.res, np.float64),
            "shape": np.asarray(self.shape, np.int64),
        }

    @classmethod
    def from_arrays(cls, data, source: str = "grid") -> GridSpec:
        """The grid stored by :meth:`to_arrays` in ``data`` (a mapping such as an open ``.npz``);
        :class:`DataFileError` naming ``source`` unless ``origin`` is 3 finite numbers, ``res``
        a positive finite number and ``shape`` 3 positive integers."""
        origin, res, shape = (np.asarray(data.get(k, np.array(None))) for k in GRID_ARRAYS)
        if not (
            origin.shape == (3,) and origin.dtype.kind in "iuf" and np.isfinite(origin).all()
            and res.shape == () and res.dtype.kind in "iuf" and np.isfinite(res) and res > 0
            and shape.shape == (3,) and shape.dtype.kind in "iu" and (shape > 0).all()
        ):  # fmt: skip
            found = ", ".join(
                f"{k} {a.dtype} {a.shape}" if k in data else f"no {k}"
                for k, a in zip(GRID_ARRAYS, (origin, res, shape), strict=True)
            )
            raise DataFileError(
                f"{source}: expected a grid's origin (3 finite metres), res (metres > 0) and "
                f"shape (3 positive cell counts), found {found}"
            )
        return cls(float_triple(origin), float(res), int_triple(shape))

    def xy_centres(self) -> FloatArray:
        """(nx · ny, 2) float centres in metres of the x, y cells, row-major (cell (i, j) at
        row i · ny + j): the goals, when this is the statistics grid G."""
        nx, ny = self.shape[:2]
        i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
        return self.low[:2] + (np.column_stack([i.ravel(), j.ravel()]) + 0.5) * self.res

    def ravel(self, index: IntArray) -> IntArray:
        """(n,) int64 flat (C-order) indices of (n, 3) in-grid cell indices."""
        return np.ravel_multi_index(tuple(np.asarray(index).T), self.shape)

    def unravel(self, flat: IntArray) -> IntArray:
        """(n, 3) int64 cell indices of (n,) flat indices."""
        return np.stack(np.unravel_index(np.asarray(flat), self.shape), axis=-1).astype(np.int64)
