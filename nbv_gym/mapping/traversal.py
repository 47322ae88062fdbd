"""Compiled voxel traversals: the hot paths of the occupancy map and the viewpoint statistics.

Everything here works in *grid units*: a point ``p`` in metres becomes ``(p - low) / res``, so cell
``(i, j, k)`` covers ``[i, i + 1) × [j, j + 1) × [k, k + 1)``. The functions are numba-compiled
(``cache=True``) and take plain arrays; the classes of :mod:`nbv_gym.mapping` convert units and check
inputs before calling them.

The map traversal mirrors OctoMap's ``computeRayKeys`` (Amanatides–Woo 3D DDA): the ray's first cell
is the sensor's, the endpoint's cell is excluded, ties between axes go to the later axis, and the walk
stops early if it overshoots the ray's length (a numerical safeguard OctoMap has too).

Map storage is *bricked* for locality (see :func:`axis_offsets`): a flat float32 array of bricks of
16 × 16 × 4 (x, y, z) voxels, each one 4 KiB page (:data:`BLOCK <nbv_gym.mapping.store.BLOCK>`
values), made of 4 × 4 (x, y) tiles of 16 voxels — one 64-byte cache line. A ray touches a new
cache line every few cells and a new page every few dozen, and a scan makes resident only the pages
of the volume it reaches (:mod:`nbv_gym.mapping.store`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nbv_gym.mapping.store import is_known, stored

_BIG = 1e300
#: Voxels per tile side (a tile is TILE × TILE (x, y) voxels: one 64-byte cache line of float32).
TILE = 4
#: Voxels per brick side along x, y and z: TILE × TILE tiles of TILE layers (16 · 16 · 4 = BLOCK
#: values: one page). The bit fields of :func:`axis_offsets` are written for these sizes.
BRICK = (TILE * TILE, TILE * TILE, TILE)


def axis_offsets(bricks: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The map store's layout, for a store of ``bricks`` (x, y, z) bricks: three int64 arrays
    over the voxel indices such that voxel (i, j, k) is at ``x[i] + y[j] + z[k]`` (the parts are
    disjoint bit fields). Bricks lie in (z, x, y) row-major order; inside a brick, 4 z layers of
    4 × 4 (x, y) tiles; inside a tile, 4 × 4 (x, y) voxels row-major. A loop over voxels adds
    three table entries instead of recomputing the index."""
    bx, by, _bz = bricks
    i, j, k = (np.arange(n * b, dtype=np.int64) for n, b in zip(bricks, BRICK, strict=True))
    x = ((i >> 4) * by << 10) + (((i >> 2) & 3) << 6) + ((i & 3) << 2)
    y = ((j >> 4) << 10) + (((j >> 2) & 3) << 4) + (j & 3)
    z = ((k >> 2) * bx * by << 10) + ((k & 3) << 8)
    return x, y, z


@njit(cache=True, inline="always")
def _axis_setup(origin: float, direction: float, cell: int) -> tuple[int, float, float]:
    """Step sign, distance to the first cell border and distance between borders along one axis."""
    if direction > 0.0:
        return 1, (cell + 1.0 - origin) / direction, 1.0 / direction
    if direction < 0.0:
        return -1, (cell - origin) / direction, -1.0 / direction
    return 0, _BIG, _BIG


@njit(cache=True, inline="always")
def _argmin_octomap(tx: float, ty: float, tz: float) -> int:
    """The axis OctoMap advances along: the smallest ``t``, ties going to the later axis."""
    if tx < ty:
        return 0 if tx < tz else 2
    return 1 if ty < tz else 2


@njit(cache=True, inline="always")
def _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz):
    """One DDA step: move to the next cell along the axis OctoMap advances along."""
    axis = _argmin_octomap(tx, ty, tz)
    if axis == 0:
        return cx + sx, cy, cz, tx + ddx, ty, tz
    if axis == 1:
        return cx, cy + sy, cz, tx, ty + ddy, tz
    return cx, cy, cz + sz, tx, ty, tz + ddz


#: A table entry for an index outside the window (or grid): any sum of three entries with it is < 0.
OUTSIDE = -(1 << 40)


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


@njit(cache=True, inline="always")
def _distance(p, q) -> float:
    """Euclidean distance of two (3,) points."""
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)


@njit(cache=True, inline="always")
def _clip_segment(a, b, shape) -> tuple[float, float]:
    """Parameters ``t0 ≤ t1`` of the part of segment ``a + t (b - a)``, t ∈ [0, 1], inside the box
    ``[0, shape]``; ``t0 > t1`` if it misses the box."""
    t0, t1 = 0.0, 1.0
    for k in range(3):
        d = b[k] - a[k]
        if d == 0.0:
            if a[k] < 0.0 or a[k] > shape[k]:
                return 1.0, 0.0
            continue
        u, v = (0.0 - a[k]) / d, (shape[k] - a[k]) / d
        if u > v:
            u, v = v, u
        t0, t1 = max(t0, u), min(t1, v)
    return t0, t1


@njit(cache=True, inline="always")
def _cell_of(x: float, n: int) -> int:
    """Cell index of a coordinate on the closed segment [0, n], the high border in the last cell."""
    return min(max(int(math.floor(x)), 0), n - 1)


@njit(cache=True)
def _observe_cell(stats, i, j, k, origin, cell_m, low, window, n_sectors) -> None:
    """Add one observation from ``origin`` (metres) to cell ``(i, j, k)`` if its centre's range is in
    ``window = (min, max)`` metres: ``[min, max)``."""
    n_obs, r_min, sectors, sum_u = stats
    cxm = low[0] + (i + 0.5) * cell_m
    cym = low[1] + (j + 0.5) * cell_m
    czm = low[2] + (k + 0.5) * cell_m
    ux, uy, uz = origin[0] - cxm, origin[1] - cym, origin[2] - czm
    r = math.sqrt(ux * ux + uy * uy + uz * uz)
    if r < window[0] or r >= window[1]:
        return
    n_obs[i, j, k] += 1
    if r < r_min[i, j, k]:
        r_min[i, j, k] = r
    theta = math.atan2(uy, ux)
    if theta < 0.0:
        theta += 2.0 * math.pi
    sector = min(int(math.floor(theta * n_sectors / (2.0 * math.pi))), n_sectors - 1)
    sectors[i, j, k] |= np.uint32(1) << np.uint32(sector)
    sum_u[i, j, k, 0] += ux / r
    sum_u[i, j, k, 1] += uy / r
    sum_u[i, j, k, 2] += uz / r


@njit(cache=True)
def _observe_segment(stats, stamp, scan_id, a, b, origin, cell_m, low, window, n_sectors) -> None:
    """Observe every cell the segment ``a → b`` (grid units, clipped to the grid) crosses, both end
    cells included, each at most once per scan (``stamp`` holds the last scan that touched it)."""
    n = stamp.shape
    t0, t1 = _clip_segment(a, b, n)
    if t0 > t1:
        return
    d = b - a
    p = a + t0 * d
    q = a + t1 * d
    cx, cy, cz = _cell_of(p[0], n[0]), _cell_of(p[1], n[1]), _cell_of(p[2], n[2])
    ex, ey, ez = _cell_of(q[0], n[0]), _cell_of(q[1], n[1]), _cell_of(q[2], n[2])
    seg = q - p
    length = math.sqrt(seg[0] ** 2 + seg[1] ** 2 + seg[2] ** 2)
    if length > 0.0:
        seg /= length
    sx, tx, ddx = _axis_setup(p[0], seg[0], cx)
    sy, ty, ddy = _axis_setup(p[1], seg[1], cy)
    sz, tz, ddz = _axis_setup(p[2], seg[2], cz)
    for _ in range(n[0] + n[1] + n[2] + 3):
        if stamp[cx, cy, cz] != scan_id:
            stamp[cx, cy, cz] = scan_id
            _observe_cell(stats, cx, cy, cz, origin, cell_m, low, window, n_sectors)
        if (cx == ex and cy == ey and cz == ez) or min(tx, min(ty, tz)) > length + 1e-9:
            return
        cx, cy, cz, tx, ty, tz = _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz)
        if not (0 <= cx < n[0] and 0 <= cy < n[1] and 0 <= cz < n[2]):
            return


@njit(cache=True)
def observe_scan(
    n_obs,
    r_min,
    sectors,
    sum_u,
    stamp,
    scan_id,
    origin,
    points,
    low,
    cell_m,
    window,
    n_sectors,
) -> None:
    """Update the viewpoint statistics with one scan (docs/protocol.md#viewpoint-statistics).

    Every cell crossed by a segment from a return to the sensor, the return's cell included, receives
    at most one observation per scan, seen from the sensor, if the range of its centre lies in
    ``[window[0], window[1])``.

    Args:
        n_obs: (nx, ny, nz) int32; r_min: float64 (+inf = never observed); sectors: uint32 bitmask;
            sum_u: (nx, ny, nz, 3) float64 sum of unit vectors cell → sensor. Updated in place.
        stamp: (nx, ny, nz) int64 id of the last scan that touched each cell.
        scan_id: id of this scan, different from every id already in ``stamp``.
        origin: (3,) float64 sensor position, metres.
        points: (n, 3) float64 returns in metres (already filtered by height and finiteness).
        low: (3,) float64 low corner of the grid, metres; cell_m: cell size, metres.
        window: (2,) float64 range window of a cell centre, metres.
        n_sectors: number of azimuth sectors (≤ 32).
    """
    stats = (n_obs, r_min, sectors, sum_u)
    o_grid = (origin - low) / cell_m
    reach = window[1] + 0.5 * math.sqrt(3.0) * cell_m
    a = np.empty(3)
    for r in range(len(points)):
        p = points[r]
        d = math.sqrt((p[0] - origin[0]) ** 2 + (p[1] - origin[1]) ** 2 + (p[2] - origin[2]) ** 2)
        s = 1.0 if d <= reach else reach / d
        for k in range(3):
            a[k] = (origin[k] + (p[k] - origin[k]) * s - low[k]) / cell_m
        _observe_segment(stats, stamp, scan_id, a, o_grid, origin, cell_m, low, window, n_sectors)
