"""The viewpoint-statistics grid G (docs/protocol.md#viewpoint-statistics, paper §III-B).

Per 1 m cell: ``n_obs`` observations; ``r_min`` the smallest range of a viewpoint (range of a cell =
distance from the sensor to the cell's centre; +inf, the minimum of no range, while never observed);
the 32-sector azimuth bitmask and its popcount
``n_omega``; the sum of the unit viewing directions ``u = (O − C) / |O − C|`` (sensor O, cell centre
C) giving the spherical variance ``sigma_theta = 1 − |Σu| / n_obs``.

For each return whose map-frame z is ≥ ``min_return_z_m``, the cell of the return and every cell the
segment return → sensor crosses receive one observation from the sensor if their range is in
``[min_range_cells · cell_m, max_range_m)``; each cell at most once per scan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from nbv_gym.core.arrayfiles import array_of, read_saved
from nbv_gym.core.arrays import FloatArray, finite_rows
from nbv_gym.core.config import check
from nbv_gym.core.errors import DataFileError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.traversal import observe_scan

#: The four viewpoint statistics of a cuboid of G, in the papers' order.
STATISTICS = ("n_obs", "r_min", "n_omega", "sigma_theta")

_FORMAT = "nbv_gym.ViewpointStatistics/1"
#: The grid-shaped arrays of a saved file: name, numpy dtype kinds, trailing shape.
_SAVED_ARRAYS = (("n_obs", "iu", ()), ("r_min_raw", "f", ()), ("sector_mask", "u", ()),
                 ("sum_u", "f", (3,)))  # fmt: skip


@dataclass(frozen=True)
class StatisticsConfig:
    """Geometry and observation rules of the statistics grid G.

    ``min_range_cells`` is the lower end of the range window in cells (√3: a cell's diagonal), and
    ``min_return_z_m`` keeps returns from the ground out.
    """

    cell_m: float = 1.0
    low_m: tuple[float, float, float] = (-30.0, -30.0, 0.2)
    high_m: tuple[float, float, float] = (30.0, 30.0, 6.2)
    n_sectors: int = 32
    min_range_cells: float = math.sqrt(3.0)
    min_return_z_m: float = 0.2

    def __post_init__(self) -> None:
        check(self.cell_m > 0, "cell_m", f"must be > 0, got {self.cell_m}")
        check(1 <= self.n_sectors <= 32, "n_sectors", f"must be in 1..32, got {self.n_sectors}")
        check(
            self.min_range_cells >= 0, "min_range_cells", f"must be ≥ 0, got {self.min_range_cells}"
        )
        self.grid()

    def grid(self) -> GridSpec:
        """The grid G."""
        return GridSpec.from_bounds(self.low_m, self.high_m, self.cell_m)


class ViewpointStatistics:
    """The statistics grid G, updated scan by scan.

    Args:
        grid: the grid G.
        n_sectors: azimuth sectors (≤ 32, one bit each of ``sector_mask``).
        min_range_m, max_range_m: range window ``[min, max)`` of an observation, metres.
        min_return_z_m: returns below this map-frame height are ignored.
    """

    def __init__(
        self,
        grid: GridSpec,
        *,
        n_sectors: int,
        min_range_m: float,
        max_range_m: float,
        min_return_z_m: float,
    ):
        check(0 <= min_range_m < max_range_m, "max_range_m", "need 0 ≤ min_range_m < max_range_m")
        self.grid = grid
        self.n_sectors = int(n_sectors)
        self.range_window_m = (float(min_range_m), float(max_range_m))
        self.min_return_z_m = float(min_return_z_m)
        self._n_obs = np.zeros(grid.shape, np.int32)
        self._r_min = np.full(grid.shape, np.inf)
        self._sectors = np.zeros(grid.shape, np.uint32)
        self._sum_u = np.zeros((*grid.shape, 3))
        self._stamp = np.full(grid.shape, -1, np.int64)
        self._scan_id = 0
        nx, ny = grid.shape[:2]
        self._columns = {
            "n_obs": np.zeros((nx, ny), np.int64),
            "r_min": np.full((nx, ny), np.inf),
            "n_omega": np.zeros((nx, ny), np.int32),
            "sigma_theta": np.zeros((nx, ny)),
        }

    def clear(self) -> None:
        """Forget every observation (empty statistics), reusing the arrays."""
        for array, value in ((self._n_obs, 0), (self._r_min, np.inf), (self._sectors, 0),
                             (self._sum_u, 0.0), (self._stamp, -1)):  # fmt: skip
            array.fill(value)
        self._scan_id = 0
        for name, value in (("n_obs", 0), ("r_min", np.inf), ("n_omega", 0), ("sigma_theta", 0)):
            self._columns[name].fill(value)

    @classmethod
    def from_config(cls, config: StatisticsConfig, max_range_m: float) -> ViewpointStatistics:
        """Empty statistics as ``config`` describes, for a sensor of range ``max_range_m`` metres."""
        return cls(
            config.grid(),
            n_sectors=config.n_sectors,
            min_range_m=config.min_range_cells * config.cell_m,
            max_range_m=max_range_m,
            min_return_z_m=config.min_return_z_m,
        )

    def update(self, origin: FloatArray, points: FloatArray) -> int:
        """Add one scan's observations.

        Args:
            origin: (3,) float sensor position in the map frame, metres.
            points: (n, 3) float returns in the map frame, metres; rows with a NaN or infinite
                coordinate and returns below ``min_return_z_m`` are skipped.

        Returns:
            The number of returns used.
        """
        origin = np.asarray(origin, dtype=np.float64).reshape(3)
        if not np.isfinite(origin).all():
            raise NbvGymError(f"sensor position must be finite, got {origin.tolist()}")
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        keep = finite_rows(points)
        keep[keep] = points[keep, 2] >= self.min_return_z_m
        observe_scan(
            self._n_obs,
            self._r_min,
            self._sectors,
            self._sum_u,
            self._stamp,
            self._scan_id,
            origin,
            points[keep],
            self.grid.low,
            float(self.grid.res),
            np.asarray(self.range_window_m),
            self.n_sectors,
        )
        self._project(every=False, box=self._reach_box(origin))
        self._scan_id += 1
        return int(keep.sum())

    def _reach_box(self, origin: np.ndarray) -> np.ndarray:
        """(4,) int64 x, y cell ranges [i0, i1) × [j0, j1) of the cells a scan from ``origin``
        can observe: those whose centre lies within the range window's upper end (and the cells
        a segment to the sensor crosses, within it too)."""
        reach = self.range_window_m[1] + self.grid.res
        low = np.floor((origin[:2] - reach - self.grid.low[:2]) / self.grid.res)
        high = np.ceil((origin[:2] + reach - self.grid.low[:2]) / self.grid.res) + 1
        shape = np.asarray(self.grid.shape[:2])
        low, high = (np.clip(edge, 0, shape).astype(np.int64) for edge in (low, high))
        return np.array([low[0], high[0], low[1], high[1]], np.int64)

    def _project(self, every: bool, box: np.ndarray | None = None) -> None:
        """Recompute the 2D projections (:meth:`column`) of every x, y column, or of those
        holding a cell the current scan observed (all inside the cell ranges ``box``,
        :meth:`_reach_box`)."""
        columns = self._columns
        if box is None:
            box = np.array([0, self.grid.shape[0], 0, self.grid.shape[1]], np.int64)
        _project_columns(
            self._stamp, self._scan_id, every, box, self._n_obs, self._r_min, self._sectors,
            self._sum_u, columns["n_obs"], columns["r_min"], columns["n_omega"],
            columns["sigma_theta"],
        )  # fmt: skip

    # ------------------------------------------------------------------ read-out (G's shape)

    @property
    def n_obs(self) -> np.ndarray:
        """(nx, ny, nz) int32 number of observations (read-only view)."""
        return _read_only(self._n_obs)

    @property
    def r_min(self) -> np.ndarray:
        """(nx, ny, nz) float64 smallest observation range, metres; +inf where never observed
        (read-only view)."""
        return _read_only(self._r_min)

    @property
    def sector_mask(self) -> np.ndarray:
        """(nx, ny, nz) uint32 azimuth sectors observed from: bit s set iff sector s was
        (read-only view)."""
        return _read_only(self._sectors)

    @property
    def n_omega(self) -> np.ndarray:
        """(nx, ny, nz) int32 number of azimuth sectors observed from."""
        return popcount(self._sectors)

    @property
    def sum_u(self) -> np.ndarray:
        """(nx, ny, nz, 3) float64 sum of the unit vectors cell centre → sensor (read-only
        view)."""
        return _read_only(self._sum_u)

    @property
    def sigma_theta(self) -> np.ndarray:
        """(nx, ny, nz) float64 spherical variance 1 − |Σu| / n_obs in [0, 1]; 0 where never
        observed (and after one observation)."""
        return spherical_variance(self._sum_u, self._n_obs)

    def column(self, name: str) -> np.ndarray:
        """(nx, ny) projection over z of a statistic, kept up to date scan by scan for the
        columns the scan touched (read-only view): ``"n_obs"`` int64 sum, ``"r_min"`` float64
        minimum (+inf: never observed), ``"n_omega"`` int32 maximum, ``"sigma_theta"`` float64
        maximum."""
        return _read_only(self._columns[name])

    # ------------------------------------------------------------------ files

    def save(self, path: str | Path) -> None:
        """Write the statistics to a ``.npz`` file."""
        grid: dict[str, Any] = self.grid.to_arrays()
        np.savez_compressed(
            Path(path),
            format=np.array(_FORMAT),
            **grid,
            n_sectors=np.int64(self.n_sectors),
            range_window_m=np.asarray(self.range_window_m),
            min_return_z_m=np.float64(self.min_return_z_m),
            n_obs=self._n_obs,
            r_min_raw=self._r_min,
            sector_mask=self._sectors,
            sum_u=self._sum_u,
        )

    @classmethod
    def load(cls, path: str | Path) -> ViewpointStatistics:
        """Read statistics written by :meth:`save`; :class:`DataFileError` for any other file
        (array shapes are checked against the grid before it is allocated)."""
        data = read_saved(path, _FORMAT, "statistics file")
        grid = GridSpec.from_arrays(data, str(path))
        arrays = [
            array_of(data, name, kinds, (*grid.shape, *extra), path)
            for name, kinds, extra in _SAVED_ARRAYS
        ]
        low, high = array_of(data, "range_window_m", "f", (2,), path).tolist()
        n_sectors = int(array_of(data, "n_sectors", "iu", (), path))
        if not 1 <= n_sectors <= 32:
            raise DataFileError(f"{path}: n_sectors must be in 1..32, got {n_sectors}")
        stats = cls(
            grid,
            n_sectors=n_sectors,
            min_range_m=low,
            max_range_m=high,
            min_return_z_m=float(array_of(data, "min_return_z_m", "f", (), path)),
        )
        targets: tuple[np.ndarray, ...] = (stats._n_obs, stats._r_min, stats._sectors, stats._sum_u)
        for target, array in zip(targets, arrays, strict=True):
            target[...] = array
        stats._project(every=True)
        return stats


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def popcount(mask: np.ndarray) -> np.ndarray:
    """int32 number of set bits of each uint32 in ``mask``."""
    bits = np.unpackbits(np.ascontiguousarray(mask, dtype="<u4").view(np.uint8), axis=-1)
    return bits.reshape(*mask.shape, 32).sum(axis=-1, dtype=np.int32)


@njit(cache=True)
def _project_columns(stamp, scan_id, every, box, n_obs, r_min, sectors, sum_u, n_obs_2d,
                     r_min_2d, n_omega_2d, sigma_theta_2d):  # fmt: skip
    """Recompute the 2D projections over z (:meth:`ViewpointStatistics.column`) of the x, y
    columns in ``box`` (i0, i1, j0, j1) holding a cell that scan ``scan_id`` stamped (of
    ``every`` column there): the same values as :func:`popcount` and :func:`spherical_variance`
    give (|Σu| summed x² + y² + z² in that order, as numpy)."""
    for i in range(box[0], box[1]):
        for j in range(box[2], box[3]):
            scanned = every
            for k in range(stamp.shape[2]):
                scanned |= stamp[i, j, k] == scan_id
            if not scanned:
                continue
            total, lowest, sectors_max, variance_max = 0, np.inf, 0, 0.0
            for k in range(stamp.shape[2]):
                n = n_obs[i, j, k]
                total += n
                lowest = min(lowest, r_min[i, j, k])
                bits, count = sectors[i, j, k], 0
                while bits:
                    bits &= bits - np.uint32(1)
                    count += 1
                sectors_max = max(sectors_max, count)
                if n > 0:
                    x, y, z = sum_u[i, j, k, 0], sum_u[i, j, k, 1], sum_u[i, j, k, 2]
                    variance = 1.0 - math.sqrt(x * x + y * y + z * z) / n
                    variance_max = max(variance_max, min(max(variance, 0.0), 1.0))
            n_obs_2d[i, j], r_min_2d[i, j] = total, lowest
            n_omega_2d[i, j], sigma_theta_2d[i, j] = sectors_max, variance_max


def spherical_variance(sum_u: np.ndarray, n_obs: np.ndarray) -> np.ndarray:
    """float64 ``1 − |Σu| / n`` of (..., 3) sums of unit vectors over (...) counts; 0 where n = 0."""
    length = np.linalg.norm(sum_u, axis=-1)
    n = np.maximum(n_obs, 1)
    return np.clip(np.where(n_obs > 0, 1.0 - length / n, 0.0), 0.0, 1.0)
