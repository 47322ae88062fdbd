"""Compiled voxel traversals: the ray walk of the occupancy map and of the viewpoint statistics,
and the map store's layout.

Everything here works in *grid units*: a point ``p`` in metres becomes ``(p - low) / res``, so cell
``(i, j, k)`` covers ``[i, i + 1) × [j, j + 1) × [k, k + 1)``. The functions are numba-compiled
(``cache=True``) and take plain arrays; the classes of :mod:`nbv_gym.mapping` convert units and check
inputs before calling them.

The ray walk mirrors OctoMap's ``computeRayKeys`` (Amanatides–Woo 3D DDA): the ray's first cell is
the sensor's, the endpoint's cell is excluded, ties between axes go to the later axis, and the walk
stops early if it overshoots the ray's length (a numerical safeguard OctoMap has too). The map's
insertion kernel (:mod:`nbv_gym.mapping.insertion`) walks with the same steps.

Map storage is *bricked* (see :func:`axis_offsets`): a flat float32 array of bricks of 16 × 16 × 4
(x, y, z) voxels, each one 4 KiB page (:data:`BLOCK <nbv_gym.mapping.store.BLOCK>` values), made of
4 × 4 (x, y) tiles of 16 voxels — one 64-byte cache line. A scan makes resident only the pages of
the volume it reaches (:mod:`nbv_gym.mapping.store`), and its updates are applied in this order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
