"""Scans tried on the exploration state's map without writing it: what inserting a scan would
change in the totals and threshold levels of G's cells (a look-ahead scoring many candidate scans).

A trial reads the map and its cell totals and writes only arrays of its own, so trials on one state
run side by side in threads (the kernels release the GIL), and nothing has to be undone. It marks
the voxels the scan would update in two bitsets over the scan's marking window — those getting a
hit, and all those getting an update — walking the rays exactly as
:meth:`OccupancyMap.insert <nbv_gym.mapping.OccupancyMap.insert>` does (OctoMap's semantics: every
return within range a hit, then one miss for every other voxel of the rays' free passes), then
sweeps the marked voxels once: a voxel's value after the scan follows from its value now and its
mark. The changes go into the cells' totals through the same kernels as
:class:`~nbv_gym.mapping.tally.CellTally`'s, whose sums are exact in any order: the totals a trial
gives are those the tally would hold after inserting the scan, bit for bit, and the levels those
:meth:`OccupancyMap.level_blocks <nbv_gym.mapping.OccupancyMap.level_blocks>` would give (tests
compare both with a real insertion).

One trial costs the walk and one pass over the marked voxels (no map writes, no undo), about a
fifth of an insertion and its undo on a scratch copy (``nbv-gym bench --suite references``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.extending import intrinsic

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.mapping.blocks import _cell_voxels
from nbv_gym.mapping.probability import (
    logodds_bound,
    new_cache,
    probabilities_in_place,
    sigmoid_one,
)
from nbv_gym.mapping.state import ExplorationState
from nbv_gym.mapping.store import stored
from nbv_gym.mapping.tally import _apply, _apply_first_misses
from nbv_gym.mapping.traversal import (
    _advance,
    _axis_setup,
    _distance,
    fill_window_tables,
    window_patterns,
)

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
        self.state = state
        occupancy = state.occupancy
        self.region = state.statistics.grid
        self.thresholds = np.unique(np.array(thresholds, np.float32))
        #: (s,) float32 log-odds bounds of :attr:`thresholds` (``p > t`` iff ``l >= b``)
        self.bounds = np.array([logodds_bound(t) for t in self.thresholds], np.float32)
        shape = occupancy._window_shape
        self._patterns = window_patterns(shape)
        self._tables = tuple(np.empty(n + 2, np.int64) for n in occupancy.grid.shape)
        self._bricks = (shape >> 3).astype(np.int64)
        self._low = np.zeros(3, np.int64)
        self._visit = np.zeros(int(np.prod(shape)) // 8, np.uint8)
        self._hit = np.zeros_like(self._visit)
        n_cells = int(np.prod(self.region.shape))
        self._slot = np.full(n_cells, -1, np.int64)
        self._cells = np.empty(n_cells, np.int64)
        self._out = (np.empty(n_cells), np.empty(n_cells, np.int32), np.empty(n_cells, bool))
        self._log = (np.empty(LOG_CAPACITY, np.int64), np.empty(LOG_CAPACITY, np.float32),
                     np.empty(LOG_CAPACITY, np.float32))  # fmt: skip
        self._first = np.zeros(n_cells, np.int32)
        self._cache = new_cache()

    def try_scan(self, origin: FloatArray, points: FloatArray) -> TrialTotals:
        """The totals of the cells a scan from ``origin`` (3,) with returns ``points`` (n, 3)
        (map frame, metres; rows with a NaN or infinite coordinate dropped) would change, as
        :meth:`OccupancyMap.insert <nbv_gym.mapping.OccupancyMap.insert>` would leave them;
        the map and totals are not written."""
        occupancy, tally = self.state.occupancy, self.state.tally
        origin_grid = occupancy._origin_in_grid(origin)
        points = np.asarray(points, np.float64)
        points_grid = (points[np.isfinite(points).all(axis=1)] - occupancy.grid.low) / (
            occupancy.grid.res
        )
        window = occupancy._window(origin_grid)
        fill_window_tables(self._tables, self._patterns, window)
        self._low[:] = window[0]
        _, cells = occupancy._touch_grid(self.region)
        max_range = occupancy.params["max_range_m"] / occupancy.grid.res
        k = _try_scan(
            origin_grid, points_grid, max_range, self._tables, self._visit, self._hit,
            self._low, self._bricks, occupancy._store, occupancy._dirty, occupancy._offsets,
            occupancy._deltas, occupancy._bounds, cells, tally.sums.reshape(-1),
            tally.outside.reshape(-1), tally.band, self.thresholds, self._slot, self._cells,
            self._out, self._log, self._first, self._cache,
        )  # fmt: skip
        sums, outside, crossed = self._out
        return TrialTotals(self._cells[:k].copy(), sums[:k].copy(), outside[:k].copy(),
                           crossed[:k].copy())  # fmt: skip

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
def _try_scan(origin, points, max_range, window, visit, hit, low, bricks, store, dirty, offsets,
              deltas, clamp, cells, sums, outside, band, thresholds, slot, touched, out, log,
              first, cache):  # fmt: skip
    """Mark the voxels a scan updates (:func:`_mark`), then sweep them (:func:`_sweep`): the
    number k of cells it would change, their flat indices left in ``touched[:k]`` and their
    sums, outside counts and crossing flags in ``out[0][:k]``, ``out[1][:k]``, ``out[2][:k]``."""
    visit[:] = 0
    hit[:] = 0
    _mark(origin, points, max_range, window, visit, hit)
    return _sweep(visit, hit, low, bricks, store, dirty, offsets, deltas, clamp, cells, sums,
                  outside, band, thresholds, slot, touched, out, log, first, cache)  # fmt: skip


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
def _sweep(visit, hit, low, bricks, store, dirty, offsets, deltas, clamp, cells, sums, outside,
           band, thresholds, slot, touched, out, log, first, cache):  # fmt: skip
    """Visit every marked voxel once (the bitsets word by word: window brick, x; then y, z
    within the word), compute its value after the scan from its stored value and its mark as
    :func:`~nbv_gym.mapping.traversal.insert_scan` does, and fold the changes inside G into
    per-touched-cell copies of the cells' ``sums`` and ``outside`` (flat over G) with the
    tally's kernels: logged changes (``log``: slot, old, new log-odds; NaN = unknown) through
    the probability ``cache``, first misses (unknown to the miss log-odds) counted in
    ``first``. ``slot`` (cells,) maps a cell to its index among the touched (-1: none; left
    all -1 on return)."""
    x_offset, y_offset, z_offset = offsets
    log_slot, log_old, log_new = log
    by_bz, bz = bricks[1] * bricks[2], bricks[2]
    lo_min, lo_max = clamp[0], clamp[1]
    first_miss = min(max(np.float32(0.0) + deltas[1], lo_min), lo_max)
    n_touched = n_log = 0
    out_sums, out_outside, crossed = out
    words, hits = visit.view(np.uint64), hit.view(np.uint64)
    for w in range(words.shape[0]):
        word = words[w]
        if word == 0:
            continue
        brick, x_in = w >> 3, w & 7
        a = low[0] + (brick // by_bz) * 8 + x_in
        b0 = low[1] + ((brick // bz) % bricks[1]) * 8
        c0 = low[2] + (brick % bz) * 8
        column_x, word_hits = x_offset[a], hits[w]
        while word:
            k = _trailing_zeros(word)
            word &= word - np.uint64(1)
            b, c = b0 + (k >> 3), c0 + (k & 7)
            i = column_x + y_offset[b] + z_offset[c]
            old = store[i] if dirty[i >> 10] else np.float32(0.0)
            is_hit = word_hits and (word_hits >> np.uint64(k)) & np.uint64(1)
            new = min(max(old + deltas[0 if is_hit else 1], lo_min), lo_max)
            known = old != 0.0
            if known and new == old:
                continue
            cell = cells[0, a] + cells[1, b] + cells[2, c]
            if cell < 0:  # outside G
                continue
            s = slot[cell]
            if s < 0:
                s = slot[cell] = n_touched
                touched[s] = cell
                out_sums[s], out_outside[s], crossed[s] = sums[cell], outside[cell], False
                n_touched += 1
            if not (known or is_hit):
                first[s] += 1
                continue
            if n_log == log_slot.shape[0]:
                _fold(log, n_log, cache, band, thresholds, out_sums, out_outside, crossed)
                n_log = 0
            log_slot[n_log], log_old[n_log] = s, old if known else np.float32(np.nan)
            log_new[n_log] = new
            n_log += 1
    _fold(log, n_log, cache, band, thresholds, out_sums, out_outside, crossed)
    _apply_first_misses(np.arange(n_touched), first, sigmoid_one(first_miss), band, thresholds,
                        out_sums, out_outside, crossed)  # fmt: skip
    slot[touched[:n_touched]] = -1
    return n_touched


@intrinsic
def _trailing_zeros(typingctx, word):
    """The number of trailing zero bits of a nonzero uint64 (one instruction)."""

    def codegen(context, builder, signature, args):
        count = builder.cttz(args[0], ir.Constant(ir.IntType(1), 1))
        return builder.trunc(count, ir.IntType(32))

    return types.int32(types.uint64), codegen


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
