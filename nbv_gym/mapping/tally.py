"""Running totals of the occupancy map per cell of a coarse grid (G): what the quality metrics need
of every cuboid a scan touched — Σ p, whether it is observed, and whether a voxel's probability
crossed a coverage threshold (else its coverage cannot have changed) — without re-reading its
voxels.

:meth:`OccupancyMap.insert <nbv_gym.mapping.OccupancyMap.insert>` logs every voxel whose value
changes while it inserts a scan — except first misses (unknown to the miss log-odds, most of a
scan's changes), which it counts per cell — then the tally applies the log and the counts
(:meth:`CellTally.apply`); a scan that logs more changes than the log holds is recounted from the
map instead (and the log grows).

The sums are exact, not approximations of a fresh sum: every probability of a known voxel is a
float32 of at least the map's lower clamp, hence a multiple of the float32 spacing at that clamp
(2⁻²⁷ at p = 0.12), and a cell's sum needs fewer than 53 bits of such multiples, so float64 holds
every partial sum exactly, in any order. The constructor checks this for its configuration.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nbv_gym.core.config import check
from nbv_gym.mapping.probability import probabilities_in_place, sigmoid_one

#: Changes the log holds at first (12 bytes each: 1.5 MiB); a benchmark scan changes 100–250 k voxels,
#: of which it logs 0–50 k (the others are first misses, counted per cell).
LOG_CAPACITY = 1 << 17


class CellTally:
    """Per-cell Σ p (unknown voxels count 0.5), the number of voxels whose p lies outside the
    open ``band`` (low, high), and flags of the cells where a voxel's p crossed one of the
    ``thresholds``, over a coarse grid aligned to the map.

    Args:
        shape: (a, b, c) cells of the coarse grid.
        voxels_per_cell: map voxels per cell side (G: 10).
        band: the open probability band (low, high) of "unobserved"; compared in float32.
        p_min: the map's lower clamp (the least probability of a known voxel).
        thresholds: probabilities t whose crossings are flagged: a voxel crosses t when ``p > t``
            changes (compared in float32, unknown = 0.5): the coverage thresholds.

    Attributes:
        sums: (a, b, c) float64 Σ p of each cell's voxels.
        outside: (a, b, c) int32 count of each cell's voxels with p ≤ low or p ≥ high.
        crossed: (a, b, c) bool cells holding a voxel that crossed a threshold since
            :meth:`take_crossed`.
        band: (2,) float32 (low, high).
    """

    def __init__(
        self,
        shape: tuple[int, int, int],
        voxels_per_cell: int,
        band: tuple[float, float],
        p_min: float,
        thresholds: tuple[float, ...] = (),
    ):
        spacing = math.floor(math.log2(np.float32(p_min))) - 23  # float32 spacing at p_min: 2^this
        bits = math.log2(voxels_per_cell**3) - spacing
        check(
            bits <= 53,
            "mapping.map.p_clamp_min",
            f"a lower clamp of {p_min} makes per-cuboid sums of {voxels_per_cell}³ probabilities "
            f"inexact in float64 ({bits:.0f} bits > 53); use p_clamp_min ≥ 1e-6",
        )
        self.band = np.array(band, np.float32)
        self.thresholds = np.unique(np.array(thresholds, np.float32))
        self.unknown_sum = 0.5 * voxels_per_cell**3
        self.sums = np.empty(shape, np.float64)
        self.outside = np.empty(shape, np.int32)
        self.crossed = np.empty(shape, bool)
        self.log = new_log(LOG_CAPACITY, math.prod(shape))
        self.clear()

    def clear(self) -> None:
        """Every voxel unknown again."""
        self.sums.fill(self.unknown_sum)
        self.outside.fill(0)
        self.crossed.fill(False)

    def take_crossed(self) -> np.ndarray:
        """(k,) int64 flat (C-order) indices of the cells flagged in :attr:`crossed`, and clear
        the flags."""
        flat = np.flatnonzero(self.crossed)
        self.crossed.reshape(-1)[flat] = False
        return flat

    def apply(
        self,
        count: int,
        cache: tuple[np.ndarray, np.ndarray],
        first_miss: np.float32,
        touched: np.ndarray,
    ) -> bool:
        """Add the ``count`` logged changes of a scan and its counted first misses (voxels
        going from unknown to the float32 log-odds ``first_miss``) to the totals (probabilities
        through the ``cache`` of :mod:`~nbv_gym.mapping.probability`); ``touched``: (k,) int64
        flat indices of the cells the scan changed (those holding its first misses, among
        others: the work follows them, not the grid). False if the log
        overflowed: then nothing was added, the log is large enough for the next scan, and the
        caller recounts the touched cells (:meth:`recount`)."""
        cell, old, new, first_misses = self.log
        if count > len(cell):
            first_misses.fill(0)
            self.log = new_log(max(2 * len(cell), count), len(first_misses))
            return False
        probabilities_in_place(old, count, cache)
        probabilities_in_place(new, count, cache)
        totals = (self.band, self.thresholds, self.sums.reshape(-1), self.outside.reshape(-1),
                  self.crossed.reshape(-1))  # fmt: skip
        _apply(cell, old, new, count, *totals)
        _apply_first_misses(touched, first_misses, sigmoid_one(first_miss), *totals)
        return True

    def recount(self, cells: np.ndarray, blocks: np.ndarray) -> None:
        """Set the totals of the (k, 3) ``cells`` from their (k, f, f, f) float32 probability
        ``blocks`` (:meth:`OccupancyMap.probability_blocks`), and flag them all as crossed (what
        changed inside them is not known)."""
        index = tuple(np.asarray(cells).T)
        self.crossed[index] = True
        self.sums[index] = blocks.sum(axis=(1, 2, 3), dtype=np.float64)
        outside = (blocks <= self.band[0]) | (blocks >= self.band[1])
        self.outside[index] = outside.sum(axis=(1, 2, 3))


def new_log(capacity: int, cells: int) -> tuple[np.ndarray, ...]:
    """An empty change log of ``capacity`` entries over a coarse grid of ``cells`` cells for
    the insertion kernel: (cell, old, new, first_misses) — see
    :func:`~nbv_gym.mapping.insertion.insert_scan`."""
    cell = np.empty(capacity, np.int32)
    first_misses = np.zeros(cells, np.int32)
    return cell, np.empty(capacity, np.float32), np.empty(capacity, np.float32), first_misses


@njit(cache=True)
def _apply(cell, old, new, count, band, thresholds, sums, outside, crossed):
    """Add the ``count`` logged changes — flat ``cell``, probabilities ``old`` and ``new`` — to
    ``sums`` and ``outside`` and flag in ``crossed`` the cells where one crossed a threshold
    (flat per-cell arrays); ``band`` (low, high)."""
    low, high, lowest = band[0], band[1], thresholds[0] if thresholds.size else np.inf
    for e in range(count):
        c, before, after = cell[e], old[e], new[e]
        sums[c] += np.float64(after) - np.float64(before)
        outside[c] += (after <= low or after >= high) - (before <= low or before >= high)
        if max(before, after) > lowest:  # else below every (ascending) threshold: no crossing
            for t in thresholds:
                if (before > t) != (after > t):
                    crossed[c] = True


@njit(cache=True)
def _apply_first_misses(cells, first_misses, p, band, thresholds, sums, outside, crossed):
    """Add ``first_misses[c]`` changes from unknown (p = 0.5) to probability ``p`` to each cell
    c of ``cells`` (the others hold none) as :func:`_apply` would one by one (the sums are
    exact: one product is their sum), and zero the counts."""
    change = np.float64(p) - np.float64(np.float32(0.5))
    out = (p <= band[0] or p >= band[1]) - (
        np.float32(0.5) <= band[0] or np.float32(0.5) >= band[1]
    )
    crossing = False
    for t in thresholds:
        crossing |= (np.float32(0.5) > t) != (p > t)
    for c in cells:
        n = first_misses[c]
        if n:
            sums[c] += n * change
            outside[c] += n * out
            crossed[c] |= crossing
            first_misses[c] = 0


#: The log of a map that keeps no tally: every change overflows it, nothing is written.
NO_LOG = new_log(0, 0)
