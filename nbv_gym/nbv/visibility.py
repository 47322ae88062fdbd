"""Sight lines from a candidate's sensor to the cells of G in range, and which ones are occluded.

A cell C of G is *visible* from a candidate T iff its centre's range from T's sensor is in
``[min_range_m, sensor_range_m)`` and the segment from the sensor to C's centre passes through the
interior of no occluding cell other than C itself and the sensor's own cell (SPEC §4: unknown space
does not occlude; an occupied cell is visible — it is the surface we want to see — but hides what is
behind it). A segment that only touches a cell's edge or corner does not pass through it.

Every candidate's sensor stands at the centre (x, y) of a G column at the same height, so the cells a
sight line crosses depend only on the offset (dx, dy) of the target column and the target layer k:
the crossings are computed once per grid geometry (:func:`sight_lines`, cached) with an exact 3D
DDA, and stored inverted — for each relative cell, the sight lines that cross it. A candidate's
occluded sight lines are then the union of those of the occluding cells near it, which costs a few
operations per occluding cell instead of a ray walk per target cell.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from nbv_gym.errors import NbvGymError
from nbv_gym.grid import GridSpec

#: Crossings closer than this (in units of the segment's parameter t ∈ [0, 1]) are simultaneous.
_TIE = 1e-12


@dataclass(frozen=True)
class SightLines:
    """All sight lines from a sensor at a column centre to the cells within range.

    Ray ``r`` goes from the sensor (column offset (0, 0)) to the centre of the cell at column offset
    ``(dx[r], dy[r])`` and absolute layer ``k[r]``. Rays are sorted by ``dx``; those with offset
    ``dx`` are ``dx_start[dx + reach] : dx_start[dx + reach + 1]``.

    Attributes:
        reach: largest |dx|, |dy| of a ray, cells.
        dx, dy, k: (n,) int64 target cell offsets and layer.
        range_m: (n,) float64 distance sensor – target centre, metres.
        unit: (n, 3) float64 unit vector target centre → sensor, ``(T − C) / |T − C|``.
        azimuth: (n,) float64 ``atan2(T_y − C_y, T_x − C_x)`` in [0, 2π).
        dx_start: (2 · reach + 2,) int64 first ray of each dx.
        crossing_start: (n_offsets + 1,) int64 CSR row starts over the relative cells
            ``((cdx + reach) · (2 · reach + 1) + cdy + reach) · nz + ck``.
        crossing_rays: int64 ids of the rays crossing each relative cell (strictly between the
            sensor's cell and the target cell).
    """

    reach: int
    nz: int
    dx: np.ndarray
    dy: np.ndarray
    k: np.ndarray
    range_m: np.ndarray
    unit: np.ndarray
    azimuth: np.ndarray
    dx_start: np.ndarray
    crossing_start: np.ndarray
    crossing_rays: np.ndarray

    @property
    def n_rays(self) -> int:
        """Number of sight lines."""
        return len(self.dx)


def sight_lines(
    grid: GridSpec, sensor_height_m: float, min_range_m: float, max_range_m: float
) -> SightLines:
    """The sight lines of a sensor at ``sensor_height_m`` (metres, map frame) above a column centre
    of ``grid`` to every cell whose centre's range is in ``[min_range_m, max_range_m)``. Cached per
    geometry."""
    return _sight_lines(
        float(grid.res), float(grid.origin[2]), int(grid.shape[2]),
        float(sensor_height_m), float(min_range_m), float(max_range_m),
    )  # fmt: skip


@functools.lru_cache(maxsize=8)
def _sight_lines(
    res: float, z0: float, nz: int, sensor_height_m: float, min_range_m: float, max_range_m: float
) -> SightLines:
    reach = max(int(math.ceil(max_range_m / res)), 0)
    zs = (sensor_height_m - z0) / res
    dx, dy, k = (a.ravel() for a in np.meshgrid(
        np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), np.arange(nz), indexing="ij"
    ))  # fmt: skip
    to_sensor = np.column_stack([-dx, -dy, zs - (k + 0.5)]).astype(np.float64) * res
    range_m = np.linalg.norm(to_sensor, axis=1)
    keep = (range_m >= min_range_m) & (range_m < max_range_m)
    dx, dy, k, range_m, to_sensor = dx[keep], dy[keep], k[keep], range_m[keep], to_sensor[keep]
    if len(dx) == 0:
        raise NbvGymError(
            f"no cell of G lies within [{min_range_m}, {max_range_m}) m of a sensor at "
            f"{sensor_height_m} m; check NbvConfig.min_range_m and sensor_range_m"
        )
    unit = to_sensor / range_m[:, None]
    azimuth = np.mod(np.arctan2(to_sensor[:, 1], to_sensor[:, 0]), 2.0 * np.pi)
    azimuth[azimuth >= 2.0 * np.pi] = 0.0
    width = 2 * reach + 1
    offsets, rays = _all_crossings(dx, dy, k, zs, nz, reach)
    order = np.argsort(offsets, kind="stable")
    counts = np.bincount(offsets, minlength=width * width * nz)
    crossing_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    dx_start = np.searchsorted(dx, np.arange(-reach, reach + 2)).astype(np.int64)
    return SightLines(
        reach, nz, dx.astype(np.int64), dy.astype(np.int64), k.astype(np.int64), range_m, unit,
        azimuth, dx_start, crossing_start, rays[order].astype(np.int64),
    )  # fmt: skip


def crossed_cells(dx: int, dy: int, k: int, zs: float) -> np.ndarray:
    """(m, 3) int64 cells (column offset dx, dy and absolute layer) whose interior the segment from
    the sensor at ``(0.5, 0.5, zs)`` (grid units, column (0, 0)) to the centre of cell
    ``(dx, dy, k)`` crosses, in order, the sensor's and the target's cells excluded."""
    out = np.empty((abs(dx) + abs(dy) + abs(k - int(math.floor(zs))) + 3, 3), np.int64)
    n = _crossings(dx, dy, k, zs, out)
    return out[:n].copy()


@njit(cache=True)
def _crossings(dx, dy, k, zs, out) -> int:
    """Write the crossed cells of one sight line to ``out`` (see :func:`crossed_cells`); return how
    many. Crossing parameters are computed from the boundary, not accumulated, so that exact ties
    (a segment through an edge or corner) are found exactly in x, y (both ends are column centres)."""
    p0 = np.array([0.5, 0.5, zs])
    d = np.array([dx + 0.5, dy + 0.5, k + 0.5]) - p0
    cell = np.array([0, 0, int(math.floor(zs))])
    end = np.array([dx, dy, k])
    step = np.zeros(3, np.int64)
    boundary = np.zeros(3)
    t = np.full(3, np.inf)
    for a in range(3):
        if d[a] > 0.0:
            step[a] = 1
            boundary[a] = cell[a] + 1.0
        elif d[a] < 0.0:
            step[a] = -1
            boundary[a] = cell[a]
        if step[a] != 0:
            t[a] = (boundary[a] - p0[a]) / d[a]
    n = 0
    while True:
        t_min = min(t[0], min(t[1], t[2]))
        if t_min >= 1.0:
            return n
        for a in range(3):
            if t[a] <= t_min + _TIE:
                cell[a] += step[a]
                boundary[a] += step[a]
                t[a] = (boundary[a] - p0[a]) / d[a]
        at_end = cell[0] == end[0] and cell[1] == end[1] and cell[2] == end[2]
        if t_min > _TIE and not at_end:
            out[n, 0], out[n, 1], out[n, 2] = cell[0], cell[1], cell[2]
            n += 1


@njit(cache=True)
def _all_crossings(dx, dy, k, zs, nz, reach):
    """(offset, ray) pairs of every in-grid (0 ≤ layer < nz) cell crossed by every sight line."""
    width = 2 * reach + 1
    longest = 2 * (2 * reach + 1) + nz + int(abs(zs)) + 4
    buffer = np.empty((longest, 3), np.int64)
    total = 0
    for r in range(len(dx)):
        total += _crossings(dx[r], dy[r], k[r], zs, buffer)
    offsets = np.empty(total, np.int64)
    rays = np.empty(total, np.int64)
    n = 0
    for r in range(len(dx)):
        m = _crossings(dx[r], dy[r], k[r], zs, buffer)
        for c in range(m):
            ck = buffer[c, 2]
            if 0 <= ck < nz:
                offsets[n] = ((buffer[c, 0] + reach) * width + buffer[c, 1] + reach) * nz + ck
                rays[n] = r
                n += 1
    return offsets[:n], rays[:n]


@njit(cache=True)
def mark_occluded(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, stamps, stamp):
    """Set ``stamps[r] = stamp`` for every sight line ``r`` of the candidate column ``(ci, cj)``
    that crosses one of the (q, 3) int64 ``occluders`` cells."""
    width = 2 * reach + 1
    for q in range(occluders.shape[0]):
        a = occluders[q, 0] - ci
        b = occluders[q, 1] - cj
        if a < -reach or a > reach or b < -reach or b > reach:
            continue
        o = ((a + reach) * width + b + reach) * nz + occluders[q, 2]
        for p in range(crossing_start[o], crossing_start[o + 1]):
            stamps[crossing_rays[p]] = stamp


@njit(cache=True)
def _visible_mask(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, dx, dy, k, out):
    """Set ``out[cell] = True`` for each in-grid target of an unoccluded sight line of the
    candidate column ``(ci, cj)`` (the same rule as the gains kernel)."""
    stamps = np.full(len(dx), -1, np.int64)
    mark_occluded(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, stamps, 0)
    nx, ny = out.shape[0], out.shape[1]
    for r in range(len(dx)):
        i, j = ci + dx[r], cj + dy[r]
        if 0 <= i < nx and 0 <= j < ny and stamps[r] != 0:
            out[i, j, k[r]] = True


def visible_cells(
    occluding: np.ndarray,
    column: tuple[int, int],
    grid: GridSpec,
    sensor_height_m: float,
    min_range_m: float,
    max_range_m: float,
) -> np.ndarray:
    """(nx, ny, nz) bool: the cells of ``grid`` visible from a sensor at ``sensor_height_m`` above
    the centre of column ``(i, j)``, given the (nx, ny, nz) bool ``occluding`` cells."""
    lines = sight_lines(grid, sensor_height_m, min_range_m, max_range_m)
    out = np.zeros(grid.shape, bool)
    _visible_mask(
        int(column[0]), int(column[1]), occluder_cells(occluding), lines.reach, lines.nz,
        lines.crossing_start, lines.crossing_rays, lines.dx, lines.dy, lines.k, out,
    )  # fmt: skip
    return out


def occluder_cells(occluding: np.ndarray) -> np.ndarray:
    """(q, 3) int64 indices of the True cells of the (nx, ny, nz) bool ``occluding``."""
    return np.argwhere(np.asarray(occluding, bool)).astype(np.int64)
