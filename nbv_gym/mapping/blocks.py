"""Reading the occupancy map by coarse cell (a cell of G, a goal cell) and by voxel column: the
log-odds and threshold levels of each cell's voxels, whether a cell reaches a log-odds, and the
known/occupied projection of voxel columns — :class:`CellReaders`, which
:class:`~nbv_gym.mapping.occupancy.OccupancyMap` mixes in, over numba kernels that read the
bricked store (voxel (a, b, k) at ``x_offset[a] + y_offset[b] + z_offset[k]``,
:func:`~nbv_gym.mapping.traversal.axis_offsets`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.columns import ColumnCounts
from nbv_gym.mapping.probability import probabilities_in_place
from nbv_gym.mapping.store import KNOWN_ZERO, is_known


@njit(inline="always")
def _cell_voxels(offset, cells, c, f, dims):
    """The map voxels coarse cell ``cells[c]`` (``f`` voxels a side, the grid's first voxel at
    map voxel ``offset``) covers: its first voxel (x0, y0, z0) and, per axis, the range [lo, hi)
    of its voxels inside the map (``dims[2:5]`` voxels). Inlined: no call, no reference count."""
    x0 = offset[0] + cells[c, 0] * f
    y0 = offset[1] + cells[c, 1] * f
    z0 = offset[2] + cells[c, 2] * f
    return (x0, y0, z0, max(0, -x0), min(f, dims[2] - x0), max(0, -y0), min(f, dims[3] - y0),
            max(0, -z0), min(f, dims[4] - z0))  # fmt: skip


@njit(cache=True)
def gather_logodds(store, x_offset, y_offset, z_offset, dims, offset, cells, out):
    """Fill ``out`` (k, f, f, f) with the log-odds (NaN = unknown, also outside the map) of
    ``cells`` (coarse indices) from the bricked ``store`` (voxel (a, b, k) at ``x_offset[a] +
    y_offset[b] + z_offset[k]``)."""
    f = out.shape[1]
    out[:] = np.nan
    for c in range(cells.shape[0]):
        x0, y0, z0, a0, a1, b0, b1, d0, d1 = _cell_voxels(offset, cells, c, f, dims)
        for a in range(a0, a1):
            for b in range(b0, b1):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(d0, d1):
                    value = store[column + z_offset[z0 + d]]
                    if is_known(value):
                        out[c, a, b, d] = value if value != KNOWN_ZERO else np.float32(0.0)


@njit(cache=True)
def mark_reaching(store, x_offset, y_offset, z_offset, dims, offset, cells, f, logodds, out):
    """Set ``out[c]`` iff coarse cell ``cells[c]`` (``f`` voxels a side) holds a known voxel
    of log-odds ≥ ``logodds`` (float32; :data:`KNOWN_ZERO` read as 0)."""
    zero = np.float32(0.0)
    for c in range(cells.shape[0]):
        x0, y0, z0, a0, a1, b0, b1, d0, d1 = _cell_voxels(offset, cells, c, f, dims)
        for a in range(a0, a1):
            for b in range(b0, b1):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(d0, d1):
                    value = store[column + z_offset[z0 + d]]
                    if is_known(value) and (zero if value == KNOWN_ZERO else value) >= logodds:
                        out[c] = True
                        break
                if out[c]:
                    break
            if out[c]:
                break


@njit(cache=True)
def gather_levels(store, x_offset, y_offset, z_offset, dims, offset, cells, bounds, out):
    """Fill ``out`` (k, f, f, f) uint32 with the bitmask of the ``bounds`` each voxel's
    log-odds reaches (unknown and outside the map: log-odds 0) for the coarse ``cells``."""
    f = out.shape[1]
    unknown = np.uint32(0)  # the stored value of an unknown voxel is 0 too
    for s in range(bounds.shape[0]):
        unknown |= np.uint32(bounds[s] <= 0.0) << np.uint32(s)
    out[:] = unknown
    for c in range(cells.shape[0]):
        x0, y0, z0, a0, a1, b0, b1, d0, d1 = _cell_voxels(offset, cells, c, f, dims)
        for a in range(a0, a1):
            for b in range(b0, b1):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(d0, d1):
                    value = store[column + z_offset[z0 + d]]  # KNOWN_ZERO compares like 0
                    level = np.uint32(0)
                    for s in range(bounds.shape[0]):
                        level |= np.uint32(value >= bounds[s]) << np.uint32(s)
                    out[c, a, b, d] = level


@njit(cache=True)
def project_columns(store, x_offset, y_offset, z_offset, x0, y0, f, known_layers, occupied_layers,  # noqa: C901 — a numba kernel: helpers taking arrays cost reference counting per call
                     bound, cells, known, occupied):  # fmt: skip
    """Set ``known[i, j]`` and ``occupied[i, j]`` of each (i, j) of ``cells``: whether some voxel
    of the cell's f × f columns (first column (x0 + f·i, y0 + f·j)) in the [k0, k1) layers is
    known, respectively known and ≥ ``bound`` (a positive bound needs no test of known-ness:
    unknown is 0). Voxel (a, b, k) is ``store[x_offset[a] + y_offset[b] + z_offset[k]]``
    (:func:`~nbv_gym.mapping.traversal.axis_offsets`); the loops are written out (a helper
    taking the arrays would cost numba reference counting per call)."""
    for c in range(cells.shape[0]):
        i, j = cells[c, 0], cells[c, 1]
        xa, ya = x0 + f * i, y0 + f * j
        for target in range(2):  # 0: known, 1: occupied
            layers = occupied_layers if target else known_layers
            found = False
            for k in range(layers[0], layers[1]):
                for a in range(xa, xa + f):
                    base = z_offset[k] + x_offset[a]
                    for b in range(ya, ya + f):
                        value = store[base + y_offset[b]]
                        if target:
                            found = value >= bound and (bound > 0.0 or is_known(value))
                        else:
                            found = is_known(value)
                        if found:
                            break
                    if found:
                        break
                if found:
                    break
            if target:
                occupied[i, j] = found
            else:
                known[i, j] = found


class CellReaders:
    """The map's readers by coarse cell and by voxel column, mixed into
    :class:`~nbv_gym.mapping.occupancy.OccupancyMap` (whose bricked store they read: voxel (a, b, k)
    at ``x_offset[a] + y_offset[b] + z_offset[k]``)."""

    grid: GridSpec
    _store: np.ndarray
    _offsets: tuple[np.ndarray, np.ndarray, np.ndarray]
    _dims: np.ndarray
    _lo_occupied: np.float32
    _sigmoid_cache: tuple[np.ndarray, np.ndarray]

    def _voxel_offset(self, grid: GridSpec) -> np.ndarray:
        """(3,) int64 index in the map of ``grid``'s first voxel (the map defines it)."""
        raise NotImplementedError

    def logodds_blocks(self, grid: GridSpec, cells: np.ndarray) -> np.ndarray:
        """(k, f, f, f) float32 log-odds (NaN = unknown, also outside the map) of the voxels of
        the (k, 3) ``cells`` of a coarse ``grid`` aligned to the map whose cells are ``f`` voxels
        on a side (G: f = 10). Reads only those voxels: the fast path for per-scan updates."""
        return self._blocks(grid, cells, as_probability=False)

    def probability_blocks(self, grid: GridSpec, cells: np.ndarray) -> np.ndarray:
        """(k, f, f, f) float32 probabilities (0.5 where unknown) of the voxels of the (k, 3)
        ``cells`` of a coarse aligned ``grid``, bit for bit as :meth:`probability` gives them."""
        return self._blocks(grid, cells, as_probability=True)

    def level_blocks(self, grid: GridSpec, cells: np.ndarray, bounds: np.ndarray) -> np.ndarray:
        """(k, f, f, f) uint32 of the voxels of the (k, 3) ``cells`` of a coarse aligned
        ``grid``: bit s set iff the voxel's probability (0.5 where unknown or outside the map)
        exceeds the threshold whose :func:`~nbv_gym.mapping.probability.logodds_bound` is
        ``bounds[s]`` ((s,) float32, s ≤ 32). The same bits as comparing
        :meth:`probability_blocks` with the thresholds, without computing a probability."""
        offset, cells, f = self._cell_voxels(grid, cells)
        out = np.empty((len(cells), f, f, f), np.uint32)
        gather_levels(
            self._store, *self._offsets, self._dims, offset, cells,
            np.asarray(bounds, np.float32), out,
        )  # fmt: skip
        return out

    def cells_reaching(self, grid: GridSpec, cells: np.ndarray, logodds: float) -> np.ndarray:
        """(k,) bool: whether each of the (k, 3) ``cells`` of a coarse aligned ``grid`` holds a
        known voxel whose log-odds is ≥ ``logodds`` (compared in float32) — ``(logodds_blocks(grid,
        cells) >= logodds).any()`` per cell, stopping at a cell's first such voxel."""
        offset, cells, f = self._cell_voxels(grid, cells)
        out = np.zeros(len(cells), bool)
        mark_reaching(
            self._store, *self._offsets, self._dims, offset, cells, f, np.float32(logodds), out
        )
        return out

    def _blocks(self, grid: GridSpec, cells: np.ndarray, as_probability: bool) -> np.ndarray:
        offset, cells, f = self._cell_voxels(grid, cells)
        out = np.empty((len(cells), f, f, f), np.float32)
        gather_logodds(self._store, *self._offsets, self._dims, offset, cells, out)
        if as_probability:
            probabilities_in_place(out.reshape(-1), out.size, self._sigmoid_cache)
        return out

    def _cell_voxels(self, grid: GridSpec, cells: np.ndarray) -> tuple:
        """The first voxel of ``grid``, its (k, 3) int64 ``cells`` and ``f``, the voxels on a
        side of a cell; ConfigError unless ``grid`` is aligned to the map."""
        factor = grid.res / self.grid.res
        if not is_whole(factor):
            raise ConfigError(f"grid cells of {grid.res} m are not a whole number of voxels")
        offset = self._voxel_offset(GridSpec(grid.origin, self.grid.res, grid.shape))
        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 3)
        return offset, cells, int(round(factor))

    def project(
        self,
        grid: GridSpec,
        known_band_m: tuple[float, float],
        occupied_band_m: tuple[float, float],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Project voxel columns onto the x, y cells of ``grid`` (aligned to the map, cells a whole
        number of voxels, inside the map; its z is ignored).

        Returns:
            (nx, ny) bool ``known``: some voxel of the cell's columns whose centre lies in
            ``known_band_m`` is known; (nx, ny) bool ``occupied``: some voxel whose centre lies in
            ``occupied_band_m`` is occupied.
        """
        known = np.zeros(grid.shape[:2], bool)
        occupied = np.zeros(grid.shape[:2], bool)
        (x0, y0), factor = self._column_block(grid)
        project_columns(
            self._store, *self._offsets, x0, y0, factor,
            np.array(self._band_layers(known_band_m), np.int64),
            np.array(self._band_layers(occupied_band_m), np.int64),
            _positive_bound(self._lo_occupied), np.argwhere(~known), known, occupied,
        )  # fmt: skip
        return known, occupied

    def column_counts(
        self,
        grid: GridSpec,
        known_band_m: tuple[float, float],
        occupied_band_m: tuple[float, float],
    ) -> ColumnCounts:
        """Counts of the known voxels in ``known_band_m`` and the occupied ones in
        ``occupied_band_m`` of each x, y cell's columns of ``grid`` (aligned to the map, inside it)
        — :meth:`project` as counts, to be kept up to date by :meth:`insert`. All zero: build
        them for an empty map."""
        (x0, y0), f = self._column_block(grid)
        cell = [np.full(n, -1, np.int64) for n in self.grid.shape[:2]]
        for axis, first in enumerate((x0, y0)):
            n = grid.shape[axis]
            cell[axis][first : first + f * n] = np.arange(f * n) // f
        shape = grid.shape[:2]
        return ColumnCounts(
            x_cell=cell[0],
            y_cell=cell[1],
            layers=np.array(
                [*self._band_layers(known_band_m), *self._band_layers(occupied_band_m)]
            ),
            bound=_positive_bound(self._lo_occupied),
            known=np.zeros(shape, np.int32),
            occupied=np.zeros(shape, np.int32),
            changed=np.zeros(shape, bool),
        )

    def _column_block(self, grid: GridSpec) -> tuple[tuple[int, int], int]:
        """First voxel column (x, y) of ``grid`` and voxels per cell side; ConfigError unless
        ``grid`` is aligned to the map's voxels and inside the map in x, y."""
        factor = grid.res / self.grid.res
        offset = (grid.low[:2] - self.grid.low[:2]) / self.grid.res
        end = offset + round(factor) * np.asarray(grid.shape[:2])
        ok = is_whole(factor) and np.all(is_whole(offset)) and np.all(offset > -1e-6)
        if not (ok and np.all(end <= np.asarray(self.grid.shape[:2]) + 1e-6)):
            raise ConfigError(
                f"grid {grid.low[:2].tolist()}–{grid.high[:2].tolist()} m with {grid.res} m cells "
                f"must lie inside the map and be aligned to its {self.grid.res} m voxels"
            )
        return (int(round(offset[0])), int(round(offset[1]))), int(round(factor))

    def _band_layers(self, band_m: tuple[float, float]) -> tuple[int, int]:
        """[k0, k1): the z layers whose voxel centres lie in the closed band, within the map."""
        low = (band_m[0] - self.grid.origin[2]) / self.grid.res - 0.5
        high = (band_m[1] - self.grid.origin[2]) / self.grid.res - 0.5
        k0 = max(math.ceil(low - 1e-6), 0)
        k1 = min(math.floor(high + 1e-6) + 1, self.grid.shape[2])
        return k0, max(k0, k1)


def _positive_bound(threshold: np.float32) -> np.float32:
    """A stored-value threshold equivalent to "known and ≥ ``threshold``": for a threshold of 0
    (p_occupied = 0.5) the least positive value, :data:`KNOWN_ZERO` (a stored known 0), so that
    the kernel tests one comparison."""
    return max(threshold, KNOWN_ZERO) if threshold >= 0 else threshold


def is_whole(x, tol: float = 1e-6):
    """Whether ``x`` (scalar or array) is within ``tol`` of an integer."""
    return np.abs(np.asarray(x) - np.rint(x)) < tol
