"""Scans tried on the exploration state's map without writing it: what inserting a scan would
change in the totals and threshold levels of G's cells (a look-ahead scoring many candidate scans).

A trial reads the map and its cell totals and writes only arrays of its own, so trials on one state
run side by side in threads (the kernels release the GIL), and nothing has to be undone. It marks
the voxels the scan would update in two bitsets over the scan's marking window — those getting a
hit, and all those getting an update; the window is laid out in the store's pages, 1024 bits a
page, so the sweep reads the map page by page — walking the rays exactly as
:meth:`OccupancyMap.insert <nbv_gym.mapping.OccupancyMap.insert>` does (OctoMap's semantics: every
return within range a hit, then one miss for every other voxel of the rays' free passes), then
sweeps the marked voxels once: a voxel's value after the scan follows from its value now and its
mark. The changes go into the cells' totals through the same kernels as
:class:`~nbv_gym.mapping.tally.CellTally`'s, whose sums are exact in any order: the totals a trial
gives are those the tally would hold after inserting the scan, bit for bit, and the levels those
:meth:`OccupancyMap.level_blocks <nbv_gym.mapping.OccupancyMap.level_blocks>` would give (tests
compare both with a real insertion).

One trial costs the walk and one pass over the marked voxels (no map writes, no undo): about half
the CPU of inserting the scan into a scratch copy of the map and undoing it, and no copy of the map
per state (``nbv-gym bench --suite references``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.mapping.blocks import _cell_voxels
from nbv_gym.mapping.occupancy import OccupancyMap
from nbv_gym.mapping.probability import (
    logodds_bound,
    new_cache,
    probabilities_in_place,
    sigmoid_one,
)
from nbv_gym.mapping.state import ExplorationState
from nbv_gym.mapping.store import BLOCK, stored
from nbv_gym.mapping.tally import _apply, _apply_first_misses
from nbv_gym.mapping.traversal import BRICK, OUTSIDE, TILE, _advance, _axis_setup, _distance

#: Changes a trial logs before it folds them into the totals (12 bytes each).
LOG_CAPACITY = 1 << 16


@dataclass(frozen=True)
class TrialTotals:
    """What a tried scan would do to the cells of G.

    Attributes:
        cells: (k,) int64 flat (C-order) indices of the cells holding a voxel whose value the
            scan would change (the insertion's ``touched_cells``, in another order).
        sums: (k,) float64 each cell's Σ p after the scan (unknown = 0.5).
        outside: (k,) int32 each cell's number of voxels outside the unobserved band after it.
        crossed: (k,) bool whether a voxel of the cell would cross one of the trial's
            thresholds.
    """

    cells: np.ndarray
    sums: np.ndarray
    outside: np.ndarray
    crossed: np.ndarray


class ScanOverlay:
    """Trials of scans on ``state``'s map and cell totals, read as they are at each trial
    (``state`` must keep cell totals). One overlay runs one trial at a time; use one per thread.

    Args:
        state: the exploration state whose map the scans are tried on.
        thresholds: (s,) probabilities whose crossings :meth:`try_scan` flags and whose levels
            :meth:`levels` gives (e.g. the coverage threshold of Q).
    """

    def __init__(self, state: ExplorationState, thresholds: tuple[float, ...]):
        if state.tally is None:
            raise NbvGymError("a scan overlay needs a state that keeps cell totals")
        self.state, self.tally = state, state.tally
        occupancy = state.occupancy
        self.region = state.statistics.grid
        self.thresholds = np.unique(np.array(thresholds, np.float32))
        #: (s,) float32 log-odds bounds of :attr:`thresholds` (``p > t`` iff ``l >= b``)
        self.bounds = np.array([logodds_bound(t) for t in self.thresholds], np.float32)
        _, bricks = OccupancyMap.brick_counts(occupancy.grid, occupancy.params["max_range_m"])
        #: (3,) int64 the window's bricks (store pages) along x, y, z, and the map's brick where
        #: the last trial's window starts
        self._bricks = np.array(bricks, np.int64)
        self._first = np.zeros(3, np.int64)
        self._in_brick = tuple(offset & (BLOCK - 1) for offset in occupancy._offsets)
        self._tables = tuple(np.empty(n + 2, np.int64) for n in occupancy.grid.shape)
        self._visit = np.zeros(int(np.prod(bricks)) * BLOCK // 8, np.uint8)
        self._hit = np.zeros_like(self._visit)
        n_cells = int(np.prod(self.region.shape))
        self._slot = np.full(n_cells, -1, np.int64)
        self._cells = np.empty(n_cells, np.int64)
        self._out = (np.empty(n_cells), np.empty(n_cells, np.int32), np.empty(n_cells, bool))
        self._log = (np.empty(LOG_CAPACITY, np.int64), np.empty(LOG_CAPACITY, np.float32),
                     np.empty(LOG_CAPACITY, np.float32))  # fmt: skip
        self._first_misses = np.zeros(n_cells, np.int32)
        self._cache = new_cache()

    def try_scan(self, origin: FloatArray, points: FloatArray) -> TrialTotals:
        """The totals of the cells a scan from ``origin`` (3,) with returns ``points`` (n, 3)
        (map frame, metres; rows with a NaN or infinite coordinate dropped) would change, as
        :meth:`OccupancyMap.insert <nbv_gym.mapping.OccupancyMap.insert>` would leave them;
        the map and totals are not written."""
        occupancy, tally = self.state.occupancy, self.tally
        origin_grid = occupancy._origin_in_grid(origin)
        points = np.asarray(points, np.float64)
        points_grid = (points[np.isfinite(points).all(axis=1)] - occupancy.grid.low) / (
            occupancy.grid.res
        )
        self._fill_tables(occupancy._window.box(origin_grid))
        _, cells = occupancy._touch_grid(self.region)
        max_range = occupancy.params["max_range_m"] / occupancy.grid.res
        k = _try_scan(
            origin_grid, points_grid, max_range, self._tables, self._visit, self._hit,
            self._first, self._bricks, occupancy._store, occupancy._dirty, occupancy._offsets,
            occupancy._deltas, occupancy._bounds, cells, tally.sums.reshape(-1),
            tally.outside.reshape(-1), tally.band, self.thresholds, self._slot, self._cells,
            self._out, self._log, self._first_misses, self._cache,
        )  # fmt: skip
        sums, outside, crossed = self._out
        return TrialTotals(self._cells[:k].copy(), sums[:k].copy(), outside[:k].copy(),
                           crossed[:k].copy())  # fmt: skip

    def _fill_tables(self, window: np.ndarray) -> None:
        """Set the bit tables for the map's marking window ``window`` ((3, 3) rows: low voxel,
        limit, shape; :meth:`MarkingWindow.box <nbv_gym.mapping.insertion.MarkingWindow.box>`): the window's voxels lie in whole bricks of
        the store from the bricks holding its low voxel, each brick 1024 bits in the store's
        order, bricks in (x, y, z) row-major order; voxel (i, j, k) has bit ``x[i + 1] + y[j +
        1] + z[k + 1]``, a negative sum outside the window (as the insertion's tables)."""
        low, limit, _ = window
        self._first[:] = low // np.array(BRICK)
        strides = (self._bricks[1] * self._bricks[2], self._bricks[2], 1)
        for axis, table in enumerate(self._tables):
            table.fill(OUTSIDE)
            index = np.arange(low[axis], low[axis] + limit[axis])
            brick = index // BRICK[axis] - self._first[axis]
            table[index + 1] = (brick * strides[axis] << 10) + self._in_brick[axis][index]

    def levels(self, cells: np.ndarray) -> np.ndarray:
        """(k, f, f, f) uint32 levels of the voxels of the (k,) flat cells of G after the scan
        last tried: bit s set iff the voxel's probability would exceed ``thresholds[s]`` — as
        :meth:`OccupancyMap.level_blocks <nbv_gym.mapping.OccupancyMap.level_blocks>` with
        :attr:`bounds` would give them after inserting it."""
        occupancy = self.state.occupancy
        offset, cells3, f = occupancy._cell_voxels(self.region, self.region.unravel(cells))
        out = np.empty((len(cells3), f, f, f), np.uint32)
        _overlay_levels(
            occupancy._store, occupancy._dirty, occupancy._offsets, occupancy._dims, offset,
            cells3, self._tables, self._visit, self._hit, occupancy._deltas, occupancy._bounds,
            self.bounds, out,
        )  # fmt: skip
        return out


@njit(cache=True, nogil=True)
def _try_scan(origin, points, max_range, window, visit, hit, first, bricks, store, dirty, offsets,
              deltas, clamp, cells, sums, outside, band, thresholds, slot, touched, out, log,
              first_misses, cache):  # fmt: skip
    """Mark the voxels a scan updates (:func:`_mark`), then sweep them (:func:`_sweep`): the
    number k of cells it would change, their flat indices left in ``touched[:k]`` and their
    sums, outside counts and crossing flags in ``out[0][:k]``, ``out[1][:k]``, ``out[2][:k]``."""
    visit[:] = 0
    hit[:] = 0
    _mark(origin, points, max_range, window, visit, hit)
    return _sweep(visit, hit, first, bricks, store, dirty, offsets, deltas, clamp, cells, sums,
                  outside, band, thresholds, slot, touched, out, log, first_misses, cache)  # fmt: skip


@njit(cache=True)
def _mark(origin, points, max_range, window, visit, hit):  # noqa: C901 — a numba kernel
    """Set in ``visit`` the window bit of every voxel :func:`~nbv_gym.mapping.traversal.insert_scan`
    updates for this scan, and in ``hit`` those it gives a hit: the voxels of the returns within
    ``max_range`` (inside the map and window), then every voxel of each ray's free pass (the
    sensor's voxel included, the endpoint's excluded, far returns carving up to the range),
    walked as it walks them."""
    x_mark, y_mark, z_mark = window
    n_x, n_y, n_z = x_mark.shape[0] - 2, y_mark.shape[0] - 2, z_mark.shape[0] - 2
    for r in range(len(points)):
        p = points[r]
        if not _distance(p, origin) <= max_range:
            continue
        cx, cy, cz = int(math.floor(p[0])), int(math.floor(p[1])), int(math.floor(p[2]))
        if not (0 <= cx < n_x and 0 <= cy < n_y and 0 <= cz < n_z):
            continue
        bit = x_mark[cx + 1] + y_mark[cy + 1] + z_mark[cz + 1]
        if bit >= 0:
            visit[bit >> 3] |= np.uint8(1 << (bit & 7))
            hit[bit >> 3] |= np.uint8(1 << (bit & 7))
    end = np.empty(3)
    ox, oy, oz = int(math.floor(origin[0])), int(math.floor(origin[1])), int(math.floor(origin[2]))
    for r in range(len(points)):
        p = points[r]
        near = _distance(p, origin) <= max_range
        scale = 1.0 if near else max_range / _distance(p, origin)
        for a in range(3):
            end[a] = origin[a] + (p[a] - origin[a]) * scale if scale < 1.0 else p[a]
        ex, ey, ez = int(math.floor(end[0])), int(math.floor(end[1])), int(math.floor(end[2]))
        if ox == ex and oy == ey and oz == ez:
            continue
        dx, dy, dz = end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        sx, tx, ddx = _axis_setup(origin[0], dx / length, ox)
        sy, ty, ddy = _axis_setup(origin[1], dy / length, oy)
        sz, tz, ddz = _axis_setup(origin[2], dz / length, oz)
        cx, cy, cz = ox, oy, oz
        while True:
            bit = x_mark[cx + 1] + y_mark[cy + 1] + z_mark[cz + 1]
            if bit < 0:  # outside the window or the map
                break
            visit[bit >> 3] |= np.uint8(1 << (bit & 7))
            cx, cy, cz, tx, ty, tz = _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz)
            if (cx == ex and cy == ey and cz == ez) or min(tx, min(ty, tz)) > length:
                break


@njit(cache=True)
def _sweep(visit, hit, first, bricks, store, dirty, offsets, deltas, clamp, cells, sums, outside,  # noqa: C901 — a numba kernel
           band, thresholds, slot, touched, out, log, first_misses, cache):  # fmt: skip
    """Visit every marked voxel once, brick by brick of the window (one page of the store
    each, read in its order), compute its value after the scan from its stored value and its
    mark as :func:`~nbv_gym.mapping.traversal.insert_scan` does, and fold the changes inside G
    into per-touched-cell copies of the cells' ``sums`` and ``outside`` (flat over G) with the
    tally's kernels: logged changes (``log``: slot, old, new log-odds; NaN = unknown) through
    the probability ``cache``, first misses (unknown to the miss log-odds) counted in
    ``first_misses``. ``slot`` (cells,) maps a cell to its index among the touched (-1: none;
    left all -1 on return)."""
    x_offset, y_offset, z_offset = offsets
    log_slot, log_old, log_new = log
    out_sums, out_outside, crossed = out
    lo_min, lo_max = clamp[0], clamp[1]
    first_miss = min(max(np.float32(0.0) + deltas[1], lo_min), lo_max)
    n_touched = n_log = 0
    words, hits = visit.view(np.uint64), hit.view(np.uint64)
    per_brick = BLOCK // 64
    for brick in range(bricks[0] * bricks[1] * bricks[2]):
        w0 = brick * per_brick
        marked = np.uint64(0)
        for q in range(per_brick):
            marked |= words[w0 + q]
        if marked == 0:
            continue
        i0 = (first[0] + brick // (bricks[1] * bricks[2])) * BRICK[0]
        j0 = (first[1] + (brick // bricks[2]) % bricks[1]) * BRICK[1]
        k0 = (first[2] + brick % bricks[2]) * BRICK[2]
        base = x_offset[i0] + y_offset[j0] + z_offset[k0]
        written = dirty[base >> 10]
        for q in range(per_brick):
            word, word_hits = words[w0 + q], hits[w0 + q]
            while word:
                o = q * 64 + _trailing_zeros(word)
                word &= word - np.uint64(1)
                old = store[base + o] if written else np.float32(0.0)
                is_hit = word_hits and (word_hits >> np.uint64(o & 63)) & np.uint64(1)
                new = min(max(old + deltas[0 if is_hit else 1], lo_min), lo_max)
                known = old != 0.0
                if known and new == old:
                    continue
                i = i0 + ((o >> 6) & 3) * TILE + ((o >> 2) & 3)
                j = j0 + ((o >> 4) & 3) * TILE + (o & 3)
                cell = cells[0, i] + cells[1, j] + cells[2, k0 + (o >> 8)]
                if cell < 0:  # outside G
                    continue
                s = slot[cell]
                if s < 0:
                    s = slot[cell] = n_touched
                    touched[s] = cell
                    out_sums[s], out_outside[s], crossed[s] = sums[cell], outside[cell], False
                    n_touched += 1
                if not (known or is_hit):
                    first_misses[s] += 1
                    continue
                if n_log == log_slot.shape[0]:
                    _fold(log, n_log, cache, band, thresholds, out_sums, out_outside, crossed)
                    n_log = 0
                log_slot[n_log], log_old[n_log] = s, old if known else np.float32(np.nan)
                log_new[n_log] = new
                n_log += 1
    _fold(log, n_log, cache, band, thresholds, out_sums, out_outside, crossed)
    _apply_first_misses(np.arange(n_touched), first_misses, sigmoid_one(first_miss), band,
                        thresholds, out_sums, out_outside, crossed)  # fmt: skip
    slot[touched[:n_touched]] = -1
    return n_touched


#: De Bruijn sequence and table of :func:`_trailing_zeros`.
_DE_BRUIJN = np.uint64(0x03F79D71B4CB0A89)
_TRAILING = np.zeros(64, np.int64)
_TRAILING[(((np.uint64(1) << np.arange(64, dtype=np.uint64)) * _DE_BRUIJN) >> np.uint64(58))] = (
    np.arange(64)
)


@njit(cache=True, inline="always")
def _trailing_zeros(word):
    """The index of the lowest set bit of a nonzero uint64 (a de Bruijn multiplication)."""
    lowest = word & (~word + np.uint64(1))
    return _TRAILING[(lowest * _DE_BRUIJN) >> np.uint64(58)]


@njit(cache=True)
def _fold(log, count, cache, band, thresholds, sums, outside, crossed):
    """Add the ``count`` logged changes (slot, old, new log-odds) to the per-slot totals, as
    :meth:`CellTally.apply <nbv_gym.mapping.tally.CellTally.apply>` adds its log."""
    log_slot, log_old, log_new = log
    probabilities_in_place(log_old, count, cache)
    probabilities_in_place(log_new, count, cache)
    _apply(log_slot, log_old, log_new, count, band, thresholds, sums, outside, crossed)


@njit(cache=True, nogil=True)
def _overlay_levels(store, dirty, offsets, dims, offset, cells, window, visit, hit, deltas,
                    clamp, bounds, out):  # fmt: skip
    """Fill ``out`` (k, f, f, f) uint32 with the levels (bitmask of the ``bounds`` each voxel's
    stored log-odds reaches; unknown and outside the map: 0) of the (k, 3) coarse ``cells``
    after the marked scan: a marked voxel holds its updated value (as
    :func:`~nbv_gym.mapping.blocks.gather_levels` reads the map after an insertion)."""
    x_offset, y_offset, z_offset = offsets
    x_mark, y_mark, z_mark = window
    f = out.shape[1]
    unknown = np.uint32(0)
    for s in range(bounds.shape[0]):
        unknown |= np.uint32(bounds[s] <= 0.0) << np.uint32(s)
    out[:] = unknown
    for c in range(cells.shape[0]):
        x0, y0, z0, a0, a1, b0, b1, d0, d1 = _cell_voxels(offset, cells, c, f, dims)
        for a in range(a0, a1):
            for b in range(b0, b1):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                marks = x_mark[x0 + a + 1] + y_mark[y0 + b + 1]
                for d in range(d0, d1):
                    i = column + z_offset[z0 + d]
                    value = store[i] if dirty[i >> 10] else np.float32(0.0)
                    bit = marks + z_mark[z0 + d + 1]
                    if bit >= 0 and visit[bit >> 3] & np.uint8(1 << (bit & 7)):
                        delta = deltas[0] if hit[bit >> 3] & np.uint8(1 << (bit & 7)) else deltas[1]
                        value = stored(min(max(value + delta, clamp[0]), clamp[1]))
                    level = np.uint32(0)
                    for s in range(bounds.shape[0]):
                        level |= np.uint32(value >= bounds[s]) << np.uint32(s)
                    out[c, a, b, d] = level
