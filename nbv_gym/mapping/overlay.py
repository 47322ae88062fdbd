"""Scans tried on the exploration state's map without writing it: what inserting a scan would
change in the totals and threshold levels of G's cells (a look-ahead scoring many candidate scans).

A trial reads the map and its cell totals and writes only arrays of its own, so trials on one state
run side by side in threads (the kernels release the GIL), and nothing has to be undone. It marks
the voxels the scan would update as the insertion marks them (:mod:`nbv_gym.mapping.insertion`:
the same walk, OctoMap's semantics — every return within range a hit, then one miss for every
other voxel of the rays' free passes — into a bitset laid out like the store's bricks, the hits in
a second one), then sweeps the marked bricks once in store order: a voxel's value after the scan
follows from its value now and its mark. Only the cells of G count, so a trial whose sensor lies in
G walks the rays only until they leave G's box, and sweeps only the bricks meeting it. The changes
go into the cells' totals through the same kernels as
:class:`~nbv_gym.mapping.tally.CellTally`'s, whose sums are exact in any order: the totals a trial
gives are those the tally would hold after inserting the scan, bit for bit, and the levels those
:meth:`OccupancyMap.level_blocks <nbv_gym.mapping.OccupancyMap.level_blocks>` would give (tests
compare both with a real insertion).

One trial costs the walk and one pass over the marked voxels (no map writes, no undo): less than
half the CPU of inserting the scan into a scratch copy of the map and undoing it, and no copy
of the map per state (``nbv-gym bench --suite references``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.mapping.blocks import _cell_voxels
from nbv_gym.mapping.insertion import (
    _WORD,
    _WORDS,
    MarkingWindow,
    _mark_hits,
    _mark_passes,
    _marked_bricks,
    _prefetch,
    grid_points,
    trailing_zeros,
)
from nbv_gym.mapping.probability import (
    logodds_bound,
    new_cache,
    probabilities_in_place,
    sigmoid_one,
)
from nbv_gym.mapping.state import ExplorationState
from nbv_gym.mapping.store import stored
from nbv_gym.mapping.tally import _apply, _apply_first_misses
from nbv_gym.mapping.traversal import OUTSIDE, TILE

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
        #: the trial's marking window: a bitset laid out like the store's bricks, holding the
        #: marks of the last trial until the next (:meth:`levels` reads them), and the hits'
        self._window = MarkingWindow(
            occupancy.grid.shape, occupancy.params["max_range_m"] / occupancy.grid.res
        )
        self._hit = np.zeros_like(self._window.words)
        self._marks = (np.empty(0, np.int64), np.zeros(8, np.int64), np.zeros(6, np.int64))
        _, cells = occupancy._touch_grid(self.region)
        #: (6,) int64 the least and greatest voxel index along x, y, z inside G
        self._inside = np.array([np.flatnonzero(c >= 0)[e] for e in (0, -1) for c in cells])
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
        points_grid = grid_points(
            np.asarray(points, np.float64), occupancy.grid.low, occupancy.grid.res
        )
        window = self._window
        if window._clean:  # the last trial's marks only
            _clear(window.words, self._hit, *self._marks)
        else:  # a trial did not finish
            window.words[:] = self._hit[:] = 0
        layout = window.place(origin_grid)
        self._cut_to_region(origin_grid)
        _, cells = occupancy._touch_grid(self.region)
        max_range = occupancy.params["max_range_m"] / occupancy.grid.res
        window._clean = False
        k, *self._marks = _try_scan(
            origin_grid, points_grid, max_range, window.words, self._hit, window.tables, layout,
            self._inside,            occupancy._store, occupancy._dirty, occupancy._offsets, occupancy._deltas,
            occupancy._bounds, cells, tally.sums.reshape(-1), tally.outside.reshape(-1),
            tally.band, self.thresholds, self._slot, self._cells, self._out, self._log,
            self._first_misses, self._cache,
        )  # fmt: skip
        window._clean = True
        sums, outside, crossed = self._out
        return TrialTotals(self._cells[:k].copy(), sums[:k].copy(), outside[:k].copy(),
                           crossed[:k].copy())  # fmt: skip

    def _cut_to_region(self, origin_grid: np.ndarray) -> None:
        """Leave only G's voxels in the window's tables when the sensor's voxel lies in G: a
        walk then stops where it leaves G. The trial loses nothing: only the updates inside G
        count, and a walk's indices move one way along each axis, so a walk that has left G's
        box never comes back into it."""
        low, high = self._inside[:3], self._inside[3:]
        voxel = np.floor(origin_grid).astype(np.int64)
        if np.all((low <= voxel) & (voxel <= high)):
            for table, first, last in zip(self._window.tables, low, high, strict=True):
                table[: first + 1] = OUTSIDE
                table[last + 2 :] = OUTSIDE

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
            cells3, self._window.tables, self._window.words, self._hit, occupancy._deltas, occupancy._bounds,
            self.bounds, out,
        )  # fmt: skip
        return out


@njit(cache=True, nogil=True)
def _try_scan(origin, points, max_range, words, hit, tables, layout, region, store, dirty, offsets,
              deltas, clamp, cells, sums, outside, band, thresholds, slot, touched, out, log,
              first_misses, cache):  # fmt: skip
    """Mark the voxels a scan updates in ``words`` as the insertion marks them, those of its
    hits in ``hit`` too, then sweep the marked bricks in store order (:func:`_sweep`). Returns the number k of cells it
    would change (their flat indices left in ``touched[:k]``, their sums, outside counts and
    crossing flags in ``out[0][:k]``, ``out[1][:k]``, ``out[2][:k]``), the (h,) int64 bits of
    its hits, the window's ``layout`` and the walks' box: the marks :func:`_clear` clears. Only
    the marked bricks meeting the ``region`` (6,) int64 (least and greatest voxel index along x,
    y, z of G) are swept."""
    hits, n_hits = _mark_hits(origin, points, max_range, words, tables)
    box = _mark_passes(origin, points, max_range, words, tables)
    one = np.uint64(1)
    for h in range(n_hits):  # an endpoint beats a free pass: its voxel gets a hit, no miss
        bit = hits[h, 3]
        hit[bit >> 6] |= one << np.uint64(bit & 63)
        for a in range(3):  # a walk cut short may not reach its endpoint's voxel
            box[a], box[a + 3] = min(box[a], hits[h, a]), max(box[a + 3], hits[h, a])
    inside = np.empty(6, np.int64)  # the walks' box cut to G's voxels: no update outside counts
    inside[:3], inside[3:] = np.maximum(box[:3], region[:3]), np.minimum(box[3:], region[3:])
    bricks = _marked_bricks(words, layout, inside)
    k = _sweep(words, hit, bricks, store, dirty, deltas, clamp, cells, sums,
               outside, band, thresholds, slot, touched, out, log, first_misses, cache)  # fmt: skip
    return k, hits[:n_hits, 3].copy(), layout.copy(), box


@njit(cache=True, nogil=True)
def _clear(words, hit, hit_bits, layout, box):
    """Zero the marks of a trial: the ``hit_bits`` of ``hit`` and the bricks of ``words`` marked
    in ``box`` (the walks' box of the window placed as ``layout`` says)."""
    for bit in hit_bits:
        hit[bit >> 6] = 0
    bricks = _marked_bricks(words, layout, box)
    for b in range(bricks.shape[0]):
        words[bricks[b, 0] * _WORDS : (bricks[b, 0] + 1) * _WORDS] = 0


@njit(cache=True)
def _sweep(words, hit, bricks, store, dirty, deltas, clamp, cells, sums, outside,  # noqa: C901 — a numba kernel
           band, thresholds, slot, touched, out, log, first_misses, cache):  # fmt: skip
    """Visit every bit of ``words`` in the ``bricks``, brick by brick in store order (a hit
    where ``hit`` holds it, else a miss); compute each voxel's value after the scan from its
    stored value as :func:`~nbv_gym.mapping.insertion.insert_scan` does, and fold the changes
    inside G into per-touched-cell copies of the cells' ``sums`` and ``outside`` (flat over G)
    with the tally's kernels: logged changes (``log``: slot, old, new log-odds; NaN = unknown)
    through the probability ``cache``, first misses (unknown to the miss log-odds) counted in
    ``first_misses``. ``slot`` (cells,) maps a cell to its index among the touched (-1: none;
    left all -1 on return). The voxel's update is written once, in this loop, as in the
    insertion's kernel (an inlined helper taking arrays costs reference counting)."""
    log_slot, log_old, log_new = log
    out_sums, out_outside, crossed = out
    lo_min, lo_max = clamp[0], clamp[1]
    first_miss = min(max(np.float32(0.0) + deltas[1], lo_min), lo_max)
    n_touched = n_log = 0
    n_bricks = bricks.shape[0]
    k, word, current, hits = -1, _WORDS - 1, np.uint64(0), np.uint64(0)
    at = base = vx = vy = vz = 0
    readable = False
    while True:
        while current == 0:  # the next mark, brick by brick in store order
            word += 1
            if word == _WORDS:
                k, word = k + 1, 0
                if k == n_bricks:
                    break
                at, base = bricks[k, 0] * _WORDS, bricks[k, 1]
                vx, vy, vz = bricks[k, 2], bricks[k, 3], bricks[k, 4]
                readable = dirty[base >> 10]
                if k + 1 < n_bricks and readable:  # the next brick's first lines
                    _prefetch(store, bricks[k + 1, 1])
            current, hits = words[at + word], hit[at + word]
        if k == n_bricks:
            break
        b = trailing_zeros(current)
        current &= current - np.uint64(1)
        is_hit = (hits >> np.uint64(b)) & np.uint64(1) != 0
        o = word * _WORD + b
        i = base + o  # the brick's voxel o (axis_offsets' bit fields)
        cx = vx + ((o >> 6) & 3) * TILE + ((o >> 2) & 3)
        cy = vy + ((o >> 4) & 3) * TILE + (o & 3)
        cz = vz + (o >> 8)
        cell = cells[0, cx] + cells[1, cy] + cells[2, cz]
        if cell < 0:  # outside G
            continue
        old = store[i] if readable else np.float32(0.0)
        new = min(max(old + deltas[0 if is_hit else 1], lo_min), lo_max)
        known = old != 0.0
        if known and new == old:
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


@njit(cache=True)
def _fold(log, count, cache, band, thresholds, sums, outside, crossed):
    """Add the ``count`` logged changes (slot, old, new log-odds) to the per-slot totals, as
    :meth:`CellTally.apply <nbv_gym.mapping.tally.CellTally.apply>` adds its log."""
    log_slot, log_old, log_new = log
    probabilities_in_place(log_old, count, cache)
    probabilities_in_place(log_new, count, cache)
    _apply(log_slot, log_old, log_new, count, band, thresholds, sums, outside, crossed)


@njit(cache=True, nogil=True)
def _overlay_levels(store, dirty, offsets, dims, offset, cells, window, passes, hit, deltas,
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
                    if bit >= 0:
                        mask = np.uint64(1) << np.uint64(bit & 63)
                        if (passes[bit >> 6] | hit[bit >> 6]) & mask:
                            delta = deltas[0] if hit[bit >> 6] & mask else deltas[1]
                            value = stored(min(max(value + delta, clamp[0]), clamp[1]))
                    level = np.uint32(0)
                    for s in range(bounds.shape[0]):
                        level |= np.uint32(value >= bounds[s]) << np.uint32(s)
                    out[c, a, b, d] = level
