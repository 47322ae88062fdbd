"""Today's insertion kernel before the store-order one, kept as the tests' reference: it applies
each voxel's update inside the ray walk, in ray order, marking visits in a bitset of 8 × 8 × 8
bricks over the window (one 64-byte line each). :class:`ReferenceMap` is an
:class:`~nbv_gym.mapping.OccupancyMap` that inserts with it; every output must equal the map's
own, bit for bit (tests/mapping/test_insertion.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nbv_gym.mapping.occupancy import OccupancyMap
from nbv_gym.mapping.store import is_known, stored
from nbv_gym.mapping.traversal import OUTSIDE, _advance, _axis_setup, _distance


class ReferenceMap(OccupancyMap):
    """An occupancy map that inserts with the reference kernel (the same window of voxels)."""

    def __init__(self, grid, **params):
        super().__init__(grid, **params)
        shape = self._window.shape
        self._marks = np.zeros(int(np.prod(shape)) // 8, dtype=np.uint8)
        self._mark_patterns = window_patterns(shape)
        self._mark_tables = tuple(np.empty(n + 2, np.int64) for n in grid.shape)

    def _update(self, origin_grid, points_grid, touched, cells, log, columns):
        shape = np.asarray(self.grid.shape)
        low = np.floor(origin_grid).astype(np.int64) - self._window.shape // 2
        low = np.minimum(np.maximum(low, 0), np.maximum(shape - self._window.shape, 0))
        window = np.stack([low, np.minimum(self._window.shape, shape - low), self._window.shape])
        fill_window_tables(self._mark_tables, self._mark_patterns, window)
        self._marks[:] = 0
        n_hits, n_changes = insert_scan(
            self._store, self._offsets, origin_grid, points_grid,
            self.params["max_range_m"] / self.grid.res, self._deltas, self._bounds, self._marks,
            self._mark_tables, touched.reshape(-1), cells, log, self._dirty, self._journal,
            columns.kernel_args(),
        )  # fmt: skip
        return n_hits, n_changes, int(np.unpackbits(self._marks).sum())  # each mark: one update


def window_patterns(shape: np.ndarray) -> tuple[np.ndarray, ...]:
    """For a per-scan marking window of ``shape`` (3,) voxels (multiples of 8), stored as a
    bitset in bricks of 8 × 8 × 8 bits (one 64-byte cache line each): three int64 arrays, the
    part of a voxel's bit index contributed by its offset in the window along x, y and z."""
    bricks = np.asarray(shape) >> 3
    strides = (bricks[1] * bricks[2], bricks[2], 1)
    return tuple(
        ((a >> 3) * strides[axis] << 9) | ((a & 7) << (6 - 3 * axis))
        for axis, a in enumerate(np.arange(n, dtype=np.int64) for n in shape)
    )


def fill_window_tables(tables: tuple, patterns: tuple, window: np.ndarray) -> None:
    """Set the three int64 ``tables`` over the voxel indices −1 … n of a map along x, y and z
    (entry ``i + 1`` for index ``i``) for the marking window ``window`` = (3, 3) rows: low
    voxel, limit (``min(window shape, map shape − low)``) and shape, whose
    :func:`window_patterns` are ``patterns``: voxel (i, j, k) then has bit ``x[i + 1] + y[j + 1]
    + z[k + 1]`` of the window's bitset, a negative sum outside the window or the map."""
    low, limit, _ = window
    for table, pattern, first, count in zip(tables, patterns, low, limit, strict=True):
        table.fill(OUTSIDE)
        table[first + 1 : first + 1 + count] = pattern[:count]


@njit(cache=True)
def insert_scan(  # noqa: C901 — a numba kernel: helpers taking arrays cost reference counting per call
    store,
    offsets,
    origin,
    points,
    max_range,
    deltas,
    bounds,
    marks,
    window,
    touched,
    cells,
    log,
    dirty,
    written,
    columns,
):
    """Insert one scan into tiled log-odds storage with OctoMap's ``insertPointCloud`` semantics.

    First every return within ``max_range`` gets a hit (once per voxel), then every voxel of every
    ray's free pass (OctoMap's ``computeRayKeys``: the sensor's voxel included, the endpoint's
    excluded) not yet updated in this scan gets a miss; far returns carve up to ``max_range``. A
    pass stops where it leaves the map (or the marking window, which holds the range).

    Both passes share one loop (a hit is a pass of one voxel), written out in this function: numba
    adds reference counting to every inlined helper that takes an array, which made this loop
    three times slower when the voxel update was such a helper (measured).

    Args:
        store: flat float32 bricked log-odds (:func:`axis_offsets`) in the store's encoding
            (:mod:`nbv_gym.mapping.store`: zero bits = unknown); updated in place.
        offsets: the (x, y, z) int64 tables of :func:`axis_offsets`: voxel (i, j, k) is
            ``store[x[i] + y[j] + z[k]]``.
        origin: (3,) float64 sensor position in grid units, inside the map.
        points: (n, 3) float64 finite returns in grid units.
        max_range: sensor range in grid units.
        deltas: (2,) float32 log-odds of a hit and of a miss; bounds: (2,) float32 clamping bounds.
        marks: uint8 bitset over the window, all zero on entry (left set on return).
        window: the marking window's tables (:func:`fill_window_tables`); the window must hold
            every voxel within range.
        touched: flat bool over the coarse grid's cells; a cell is set when a voxel inside it
            changes value.
        cells: (3, max(nx, ny, nz)) int64 per voxel index along x, y, z (row 0, 1, 2) the
            contribution of its coarse cell index to the flat index (index × stride),
            :data:`OUTSIDE` outside the coarse grid.
        log: (cell, old, new, first_misses): the changes of voxels inside the coarse grid,
            one entry each while the (capacity,) arrays last: int32 flat coarse ``cell``,
            float32 ``old`` (NaN when unknown) and ``new`` log-odds — except a voxel's first
            miss (unknown to the miss log-odds, most changes of a scan), counted per coarse
            cell in the (cells,) int32 ``first_misses`` instead (empty: log it too).
        dirty: (bricks,) bool: set for each brick (block of the store) written; the voxels of a
            brick not set are all unknown (0).
        written: (bricks,) bool: also set for each brick written (``dirty`` itself, or a journal
            of the bricks this scan and others since its reset wrote).
        columns: :meth:`ColumnCounts.kernel_args <nbv_gym.mapping.columns.ColumnCounts>`: the
            per-column counts of known and occupied voxels in the navigation bands to keep up
            to date (``NO_COLUMNS``: empty bands, nothing counted).

    Returns:
        Number of voxels that received a hit, number of logged changes inside the coarse grid
        (more than the log's capacity when they did not all fit).
    """
    x_offset, y_offset, z_offset = offsets
    x_mark, y_mark, z_mark = window
    n_x, n_y, n_z = x_mark.shape[0] - 2, y_mark.shape[0] - 2, z_mark.shape[0] - 2
    col_x, col_y, layers, occupied_bound, known_count, occupied_count, col_changed = columns
    known_first, known_end, occupied_first, occupied_end = (
        layers[0],
        layers[1],
        layers[2],
        layers[3],
    )
    lo_min, lo_max = bounds[0], bounds[1]
    log_cell, log_old, log_new, first_misses = log
    counting_first = first_misses.shape[0] > 0
    n_points = len(points)
    near = np.empty(n_points, dtype=np.bool_)
    for r in range(n_points):
        near[r] = _distance(points[r], origin) <= max_range
    n_hits = n_changes = 0
    end = np.empty(3)
    for task in range(2 * n_points):
        hit, r = task < n_points, task % n_points
        p = points[r]
        if hit:
            if not near[r]:
                continue
            cx, cy, cz = int(math.floor(p[0])), int(math.floor(p[1])), int(math.floor(p[2]))
            if not (0 <= cx < n_x and 0 <= cy < n_y and 0 <= cz < n_z):
                continue  # outside the map (the tables cover one voxel beyond it)
            delta = deltas[0]
        else:
            scale = 1.0 if near[r] else max_range / _distance(p, origin)
            for a in range(3):
                end[a] = origin[a] + (p[a] - origin[a]) * scale if scale < 1.0 else p[a]
            cx, cy, cz = (
                int(math.floor(origin[0])),
                int(math.floor(origin[1])),
                int(math.floor(origin[2])),
            )
            ex, ey, ez = int(math.floor(end[0])), int(math.floor(end[1])), int(math.floor(end[2]))
            if cx == ex and cy == ey and cz == ez:
                continue
            dx, dy, dz = end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            sx, tx, ddx = _axis_setup(origin[0], dx / length, cx)
            sy, ty, ddy = _axis_setup(origin[1], dy / length, cy)
            sz, tz, ddz = _axis_setup(origin[2], dz / length, cz)
            delta = deltas[1]
        while True:
            bit = x_mark[cx + 1] + y_mark[cy + 1] + z_mark[cz + 1]
            if bit < 0:  # outside the window or the map
                break
            byte, mask = bit >> 3, np.uint8(1 << (bit & 7))
            if not marks[byte] & mask:  # the voxel's first update in this scan
                marks[byte] |= mask
                i = x_offset[cx] + y_offset[cy] + z_offset[cz]
                # unknown: 0, the log-odds a first update starts from; a brick not written since
                # the map was cleared is all unknown, and not reading it spares a page fault
                old = store[i] if dirty[i >> 10] else np.float32(0.0)
                known = is_known(old)
                new = min(max(old + delta, lo_min), lo_max)
                n_hits += hit
                if not (known and new == old):
                    store[i] = stored(new)
                    dirty[i >> 10] = True
                    written[i >> 10] = True
                    in_known = not known and known_first <= cz < known_end
                    in_occupied = occupied_first <= cz < occupied_end
                    column = col_x[cx] + col_y[cy] if in_known or in_occupied else -1
                    if column >= 0:  # the voxel counts in a navigation band of a grid column
                        if in_known:
                            known_count[column] += 1
                            col_changed[column] = True
                        if in_occupied:
                            was = known and old >= occupied_bound
                            now = stored(new) >= occupied_bound
                            if was != now:
                                occupied_count[column] += 1 if now else -1
                                col_changed[column] = True
                    cell = cells[0, cx] + cells[1, cy] + cells[2, cz]
                    if cell >= 0:  # inside the coarse grid
                        touched[cell] = True
                        if counting_first and not (known or hit):
                            first_misses[cell] += 1
                        else:
                            if n_changes < log_cell.shape[0]:
                                log_cell[n_changes] = cell
                                log_old[n_changes] = old if known else np.float32(np.nan)
                                log_new[n_changes] = new
                            n_changes += 1
            if hit:
                break
            cx, cy, cz, tx, ty, tz = _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz)
            if (cx == ex and cy == ey and cz == ez) or min(tx, min(ty, tz)) > length:
                break
    return n_hits, n_changes


@njit(cache=True)
def veering_rays(origin, points, max_range):
    """The number of the rays of a scan (grid units, as :func:`insert_scan` takes them) whose
    float walk does not visit exactly the voxels a walk of as many steps as the Manhattan
    distance to the endpoint's voxel visits: it stops early (overshooting the ray's length)
    or does not stand on that voxel after those steps."""
    veering = 0
    end = np.empty(3)
    for r in range(len(points)):
        p = points[r]
        distance = _distance(p, origin)
        scale = 1.0 if distance <= max_range else max_range / distance
        for a in range(3):
            end[a] = origin[a] + (p[a] - origin[a]) * scale if scale < 1.0 else p[a]
        cx, cy, cz = (int(math.floor(origin[0])), int(math.floor(origin[1])),
                      int(math.floor(origin[2])))  # fmt: skip
        ex, ey, ez = int(math.floor(end[0])), int(math.floor(end[1])), int(math.floor(end[2]))
        if cx == ex and cy == ey and cz == ez:
            continue
        dx, dy, dz = end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        sx, tx, ddx = _axis_setup(origin[0], dx / length, cx)
        sy, ty, ddy = _axis_setup(origin[1], dy / length, cy)
        sz, tz, ddz = _axis_setup(origin[2], dz / length, cz)
        steps = abs(ex - cx) + abs(ey - cy) + abs(ez - cz)
        for taken in range(1, steps + 1):
            cx, cy, cz, tx, ty, tz = _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz)
            if taken < steps and min(tx, min(ty, tz)) > length:
                veering += 1
                break
        else:
            veering += not (cx == ex and cy == ey and cz == ez)
    return veering
