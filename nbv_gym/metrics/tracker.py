"""The incremental quality tracker: per-cuboid metrics of a changing reconstruction, recomputed
only where a scan changed it (definitions in :mod:`nbv_gym.metrics.cuboids`)."""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
from numba import njit, prange

from nbv_gym.core.arrays import BoolArray, FloatArray, IntArray
from nbv_gym.mapping.overlay import TrialTotals
from nbv_gym.mapping.probability import logodds_bound
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.cuboids import (
    CuboidConfig,
    CuboidMetrics,
    QualitySummary,
    check_grids,
    comparison_volume,
    coverage_offsets,
    cuboid_shape,
    cuboid_view,
    empty_quality,
    mean_quality,
    summarise,
)

#: The fewest cuboids whose coverage is searched on numba's threads. A step searches a few
#: dozen at most; threads for so few cost more CPU time (their start and their spin-wait after
#: the work) than the search itself: on a loaded 2-core machine, 2–3 raw casts a step instead
#: of ~0.5.
THREADED_CUBOIDS = 256


def evaluate_cuboids(
    prob: FloatArray, gt: BoolArray, config: CuboidConfig | None = None
) -> CuboidMetrics:
    """All per-cuboid metrics of reconstruction ``prob`` (X, Y, Z) float against ``gt`` (X, Y, Z) bool."""
    tracker = QualityTracker(gt, config)
    tracker.update(prob)
    return tracker.metrics()


class QualityTracker:
    """Per-cuboid metrics of a changing reconstruction, recomputed only where it changed.

    Built once from the ground truth ``gt`` (X, Y, Z) bool; :meth:`update` takes the current
    probability grid and the cuboids a scan touched, recomputes only those and returns the
    :class:`QualitySummary`. Each cuboid's values come from the same kernel whether it is
    recomputed alone or in a full pass, and the means are taken over the whole per-cuboid arrays,
    so an incremental result equals a full recomputation exactly.

    A cuboid's coverage search is a function of its voxels' *levels* alone (which thresholds
    each p exceeds); the tracker keeps its result for every cuboid holding ground truth, observed
    or not, and searches again only where levels changed (:meth:`update_totals`: a scan changes
    the levels of a few dozen cuboids while it touches hundreds).
    """

    def __init__(self, gt: BoolArray, config: CuboidConfig | None = None):
        gt = np.asarray(gt)
        if gt.dtype != bool:
            raise MetricInputError(f"ground truth must be a bool grid, got {gt.dtype}")
        self._build(np.argwhere(gt), gt.shape, config)

    @classmethod
    def from_voxels(
        cls, voxels: IntArray, grid_shape: tuple[int, int, int], config: CuboidConfig | None = None
    ) -> QualityTracker:
        """The tracker of the ground truth whose occupied voxels are ``voxels`` (k, 3) int
        indices into a grid of ``grid_shape``, unique and in C order (as ``np.argwhere`` lists
        them): the same tracker as ``QualityTracker(gt)``, without the dense grid (a world
        switch builds one per world)."""
        tracker = cls.__new__(cls)
        tracker._build(_checked_voxels(voxels, grid_shape), tuple(grid_shape), config)
        return tracker

    def _build(self, voxels: IntArray, grid_shape: tuple[int, ...], config) -> None:
        """Set up from the (k, 3) occupied ``voxels`` (C order) of a grid of ``grid_shape``."""
        self.config = config or CuboidConfig()
        n = self.config.cuboid_voxels
        self.grid_shape = grid_shape
        self.shape = cuboid_shape(grid_shape, n)
        self._gt_start, self._gt_voxels = _ground_truth_lists(voxels, self.shape, n)
        self.u_occ = (np.diff(self._gt_start) > 0).reshape(self.shape)  # = occupied_cuboids
        self.volume = comparison_volume(self.u_occ, self.config.volume)
        self._occupied = self.u_occ.ravel()
        self._offsets, self._within = _stencil(self.config)
        self._thresholds = np.array([p for p, _ in self.config.cov_settings])
        #: (s,) float32 log-odds bounds of the settings' thresholds (``p > t`` iff ``l >= b``)
        self.bounds = np.array([logodds_bound(p) for p in self._thresholds], np.float32)
        size = int(np.prod(self.shape))
        self._observed = np.zeros(size, bool)
        self._l1 = np.full(size, self.config.unobserved_l1)
        self._terms = np.empty(size)  # the per-cuboid term of Q (:meth:`_quality`), kept current
        self._cov = np.zeros((len(self.config.cov_settings), size))
        #: (s, size) the coverage search's result for the current levels (cuboids holding ground
        #: truth): all voxels unknown at first, which every ground-truth voxel finds in itself
        self._found = np.empty_like(self._cov)
        self._unknown_found = (0.5 > self._thresholds.astype(np.float32)).astype(float)
        self._found[:] = self._unknown_found[:, None]
        self._unobserved_terms = self._term(self._cov, self._l1, self._occupied)
        self._terms[:] = self._unobserved_terms

    def update(self, prob: FloatArray, touched: IntArray | None = None) -> QualitySummary:
        """Recompute the cuboids in ``touched`` (all when None) from ``prob`` and summarise.

        ``prob`` (X, Y, Z) float probabilities (unknown = 0.5) of the ground truth's shape;
        ``touched``: (m, 3) int cuboid indices or (m,) flat (C-order) cuboid indices.
        """
        prob = np.asarray(prob)
        check_grids(prob, np.broadcast_to(False, self.grid_shape), self.config.cuboid_voxels)
        flat = self._flat_indices(touched)
        n = self.config.cuboid_voxels
        blocks = cuboid_view(prob, n)[np.unravel_index(flat, self.shape)]
        self._recompute(flat, np.ascontiguousarray(blocks))
        return self.summary()

    def update_blocks(self, touched: IntArray, blocks: FloatArray) -> QualitySummary:
        """Recompute the (m,) flat cuboid indices ``touched`` from their (m, n, n, n)
        probability ``blocks`` and summarise: the fast path after a scan, which never needs the
        whole grid. Gives the same bits as :meth:`update` on a grid holding these blocks."""
        n = self.config.cuboid_voxels
        if blocks.shape != (len(touched), n, n, n):
            raise MetricInputError(
                f"expected ({len(touched)}, {n}, {n}, {n}) probability blocks, got {blocks.shape}"
            )
        self._recompute(self._checked(touched), np.ascontiguousarray(blocks))
        return self.summary()

    def update_totals(
        self,
        touched: IntArray,
        sums: FloatArray,
        outside: IntArray,
        searched: IntArray,
        levels: np.ndarray,
    ) -> QualitySummary:
        """Recompute the (m,) flat cuboid indices ``touched`` from running totals of their voxels
        — (m,) float64 ``sums`` Σ p and (m,) int ``outside``, the number of voxels outside the
        unobserved band (:class:`~nbv_gym.mapping.tally.CellTally`) — and summarise. The
        coverage search runs on the (k,) flat cuboids ``searched`` alone, from their (k, n, n,
        n) uint32 ``levels``: per voxel the bitmask of the settings whose threshold its p
        exceeds (:meth:`levels`, or :meth:`OccupancyMap.level_blocks
        <nbv_gym.mapping.OccupancyMap.level_blocks>` with :attr:`bounds`). ``searched`` must
        hold every cuboid with ground truth (:meth:`needs_coverage`) whose levels changed since
        its last search (the tally's crossed cells); the others keep their result. Same bits as
        :meth:`update_blocks`."""
        self._search(self._checked(searched), levels)
        self._store(self._checked(touched), np.asarray(outside) > 0, np.asarray(sums, np.float64))
        return self.summary()

    def levels(self, blocks: FloatArray) -> np.ndarray:
        """(k, n, n, n) uint32 bitmasks of the settings whose threshold each voxel's
        probability in the (k, n, n, n) ``blocks`` exceeds (compared in the blocks' precision)."""
        blocks = np.ascontiguousarray(blocks)
        out = np.empty(blocks.shape, np.uint32)
        _levels(blocks.reshape(-1), self._thresholds.astype(blocks.dtype), out.reshape(-1))
        return out

    def needs_coverage(self, cuboids: IntArray) -> IntArray:
        """The flat cuboid indices among ``cuboids`` that hold ground truth: those whose
        coverage is searched when their levels change."""
        cuboids = np.asarray(cuboids, np.int64)
        return cuboids[self._occupied[cuboids]]

    def _checked(self, touched: IntArray) -> IntArray:
        touched = np.asarray(touched, dtype=np.int64)
        if len(touched) and (touched.min() < 0 or touched.max() >= self.u_occ.size):
            raise MetricInputError(f"cuboid indices must lie in [0, {self.u_occ.size})")
        return touched

    def _recompute(self, flat: IntArray, blocks: FloatArray) -> None:
        """Recompute the cuboids ``flat`` from their probability ``blocks``, in place."""
        same = blocks.dtype.type  # thresholds in the grid's precision: float32 0.4 is "<= 0.4"
        band = (same(self.config.unknown_low), same(self.config.unknown_high))
        observed, sums = _block_totals(blocks, *band)
        holding = self._occupied[flat]
        self._search(flat[holding], self.levels(blocks[holding]))
        self._store(flat, observed, sums)

    def _search(self, flat: IntArray, levels: np.ndarray) -> None:
        """Search the coverage of the cuboids ``flat`` in their (k, n, n, n) uint32 ``levels``
        (:meth:`levels`)."""
        n = self.config.cuboid_voxels
        if levels.shape != (len(flat), n, n, n) or levels.dtype != np.uint32:
            raise MetricInputError(
                f"expected ({len(flat)}, {n}, {n}, {n}) uint32 levels of the searched cuboids, "
                f"got {levels.dtype} {levels.shape}"
            )
        self._found[:, flat] = 0.0
        search = _coverages if len(flat) >= THREADED_CUBOIDS else _serial_coverages
        search(
            np.ascontiguousarray(levels), flat, n, self.shape, self._gt_start, self._gt_voxels,
            self._offsets, self._within, self._found,
        )  # fmt: skip

    def _store(self, flat: IntArray, observed: BoolArray, sums: FloatArray) -> None:
        """Set the cuboids ``flat``: observed or not, L1 (their ``sums`` if observed), coverage
        (the search's result where observed and holding ground truth, else 0)."""
        c = self.config
        _store_cuboids(flat, np.asarray(observed, bool), sums, self._occupied, self._found,
                       c.q_setting, c.unobserved_l1, c.unobserved_l1 - c.best_l1,
                       self._observed, self._l1, self._cov, self._terms)  # fmt: skip

    def scratch(self) -> QualityTracker:
        """A tracker sharing this one's ground truth, with its own copy of the per-cuboid state
        (for trials: :meth:`restore` brings it back)."""
        other = copy.copy(self)
        for name in _CUBOID_STATE:
            setattr(other, name, getattr(self, name).copy())
        return other

    def restore(self, source: QualityTracker) -> None:
        """Set the per-cuboid state to ``source``'s (a tracker of the same ground truth, e.g.
        the one :meth:`scratch` came from)."""
        for name in _CUBOID_STATE:
            np.copyto(getattr(self, name), getattr(source, name))

    def reset(self) -> None:
        """Every cuboid unobserved again (a new episode on the same ground truth): clears the
        per-cuboid arrays in place; the ground-truth lists built in ``__init__`` are kept."""
        self._observed[:] = False
        self._l1[:] = self.config.unobserved_l1
        self._cov[:] = 0.0
        self._found[:] = self._unknown_found[:, None]
        self._terms[:] = self._unobserved_terms

    def summary(self) -> QualitySummary:
        """The current :class:`QualitySummary` (no recomputation, no copies of the arrays)."""
        cov = self._cov.reshape(-1, *self.shape)
        l1 = self._l1.reshape(self.shape)
        return summarise(self.u_occ, self.volume, self._observed.reshape(self.shape), cov, l1,
                        self._terms.reshape(self.shape), self.config)  # fmt: skip

    def metrics(self) -> CuboidMetrics:
        """The current per-cuboid arrays as :class:`CuboidMetrics` (copies)."""
        cov = self._cov.reshape(-1, *self.shape).copy()
        cov[:, ~self.u_occ] = np.nan
        l1 = self._l1.reshape(self.shape).copy()
        observed = self._observed.reshape(self.shape).copy()
        return CuboidMetrics(self.u_occ.copy(), observed, cov, l1, self._quality(cov, l1),
                             self.config, self.volume.copy())  # fmt: skip

    def _quality(self, cov: FloatArray, l1: FloatArray) -> FloatArray:
        """(cx, cy, cz) float64 per-cuboid term of Q."""
        return self._term(cov, l1, self.u_occ)

    def _term(self, cov: FloatArray, l1: FloatArray, occupied: BoolArray) -> FloatArray:
        """The term of Q of cuboids with coverages ``cov`` (s, ...), L1 ``l1`` and ground truth
        or not (``occupied``): element by element, so kept per cuboid it equals the full
        arrays' terms bit for bit."""
        return np.where(occupied, cov[self.config.q_setting], empty_quality(l1, self.config))

    def _flat_indices(self, touched: IntArray | None) -> IntArray:
        size = int(np.prod(self.shape))
        if touched is None:
            return np.arange(size, dtype=np.int64)
        touched = np.asarray(touched, dtype=np.int64)
        if touched.ndim == 2 and touched.shape[1] == 3:
            inside = np.all((touched >= 0) & (touched < np.asarray(self.shape)), axis=1)
            touched = np.ravel_multi_index(tuple(touched[inside].T), self.shape)
        elif touched.ndim != 1:
            raise MetricInputError(
                f"touched cuboids must be (m, 3) or (m,) indices, got {touched.shape}"
            )
        touched = touched[(touched >= 0) & (touched < size)]
        return np.unique(touched)


class TrialQuality:
    """Q of ``tracker``'s state with the totals of some cuboids changed by a trial scan, without
    changing the tracker: the ``q`` that :meth:`QualityTracker.update_totals` would summarise
    after the scan, bit for bit, computing only the coverage of Q's setting (the others do not
    enter Q). For a look-ahead over many trial scans of one state: :meth:`begin` once per state,
    then :meth:`q` per trial; one instance per thread (its search releases the GIL).
    """

    def __init__(self, tracker: QualityTracker):
        self.tracker = tracker
        setting = tracker.config.q_setting
        #: the probability threshold of Q's coverage setting: a trial's totals must flag the
        #: cuboids where a voxel crosses it (:meth:`q`)
        self.threshold = tracker.config.cov_settings[setting][0]
        self._setting = setting
        self._within = (tracker._within >> setting) & 1
        self._volume = tracker.volume.reshape(-1)
        self._n_occ = int(np.count_nonzero(self._volume & tracker._occupied))
        self._n_empty = int(np.count_nonzero(self._volume)) - self._n_occ
        self._terms = np.empty(0)
        self._seen = np.empty(0, bool)

    def begin(self) -> None:
        """Read the tracker's state now (before the trials on a state)."""
        self._terms = self.tracker._terms.copy()
        self._seen = self.tracker._observed & self._volume

    def q(self, totals: TrialTotals, levels: Callable[[IntArray], np.ndarray]) -> float:
        """Q after a trial scan whose ``totals`` (:class:`~nbv_gym.mapping.overlay.TrialTotals`:
        the cuboids it changes, their Σ p and outside counts after it, and the flags of those
        where a voxel crosses :attr:`threshold`) and whose ``levels(cells)`` ((k, n, n, n)
        uint32, bit 0: p > :attr:`threshold`, of the (k,) flat ``cells`` after the scan) are
        given."""
        t = self.tracker
        cells = totals.cells
        search = totals.crossed & t._occupied[cells]
        found = t._found[self._setting, cells]
        searched = np.empty(int(search.sum()))
        _trial_coverages(levels(cells[search]), cells[search], t.config.cuboid_voxels, t.shape,
                         t._gt_start, t._gt_voxels, t._offsets, self._within, searched)  # fmt: skip
        found[search] = searched
        return self._q_with(cells, totals.outside > 0, totals.sums, found)

    def _q_with(self, cells: IntArray, observed: BoolArray, sums: FloatArray, found) -> float:
        """Q with the (m,) ``cells`` observed or not, of L1 ``sums`` if observed and of Q's
        coverage ``found`` if observed and holding ground truth (:meth:`QualityTracker._store`),
        summed as :func:`~nbv_gym.metrics.cuboids.summarise` sums Q."""
        t = self.tracker
        occupied = t._occupied[cells]
        l1 = np.where(observed, sums, t.config.unobserved_l1)
        cov = np.where(observed & occupied, found, 0.0)
        kept_terms, kept_seen = self._terms[cells], self._seen[cells]
        self._terms[cells] = np.where(occupied, cov, empty_quality(l1, t.config))
        self._seen[cells] = observed & self._volume[cells]
        seen = np.flatnonzero(self._seen)
        seen_occ = int(np.count_nonzero(t._occupied[seen]))
        unseen = (self._n_occ - seen_occ, self._n_empty - (len(seen) - seen_occ))
        q = mean_quality(self._terms[seen], *unseen, t.config)
        self._terms[cells], self._seen[cells] = kept_terms, kept_seen
        return q


#: The attributes of a :class:`QualityTracker` that change with the map.
_CUBOID_STATE = ("_observed", "_l1", "_cov", "_found", "_terms")


def _stencil(config: CuboidConfig) -> tuple[IntArray, IntArray]:
    """(o, 3) offsets of the widest coverage setting, sorted by length, and (o,) int64 the
    bitmask of the settings whose distance reaches each (bit s: ``cov_settings[s]``)."""
    widest = max(d for _, d in config.cov_settings)
    offsets = coverage_offsets(widest, config.resolution_m)
    d2 = (offsets**2).sum(axis=1).astype(float)
    order = np.argsort(d2, kind="stable")
    radius2 = np.array([(d / config.resolution_m) ** 2 + 1e-9 for _, d in config.cov_settings])
    within = (d2[order, None] <= radius2[None, :]) << np.arange(len(radius2))
    return offsets[order], within.sum(axis=1).astype(np.int64)


def _checked_voxels(voxels: IntArray, grid_shape: tuple[int, ...]) -> IntArray:
    """(k, 3) int64 ``voxels``, checked to be unique indices into ``grid_shape`` in C order."""
    voxels = np.asarray(voxels)
    if voxels.ndim != 2 or voxels.shape[1] != 3 or voxels.dtype.kind not in "iu":
        raise MetricInputError(
            f"occupied voxels must be (k, 3) integer indices, got {voxels.dtype} {voxels.shape}"
        )
    voxels = voxels.astype(np.int64, copy=False)
    if not np.all((voxels >= 0) & (voxels < np.asarray(grid_shape))):
        raise MetricInputError(f"occupied voxels must lie in the grid of shape {grid_shape}")
    if np.any(np.diff(np.ravel_multi_index(tuple(voxels.T), grid_shape)) <= 0):
        raise MetricInputError(
            "occupied voxels must be unique and in C order, as np.argwhere lists them "
            "(np.unique(voxels, axis=0) sorts them)"
        )
    return voxels


def _ground_truth_lists(voxels: IntArray, shape: tuple[int, int, int], n: int):
    """CSR lists of the occupied ground-truth ``voxels`` (k, 3) int (C order) per cuboid of the
    cuboid grid ``shape``: ``start`` (cuboids + 1,) int64, ``voxels`` (k, 3) int32."""
    cx, cy, cz = shape
    voxels = np.asarray(voxels, np.int64)
    owner = (
        np.ravel_multi_index(tuple((voxels // n).T), (cx, cy, cz))
        if len(voxels)
        else np.zeros(0, np.int64)
    )
    order = np.argsort(owner, kind="stable")
    counts = np.bincount(owner, minlength=cx * cy * cz)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return start, voxels[order].astype(np.int32)


@njit(cache=True, parallel=True)
def _block_totals(blocks, low, high):
    """(m,) bool observed and (m,) float64 Σ p of (m, n, n, n) probability ``blocks``."""
    m, n = blocks.shape[0], blocks.shape[1]
    observed = np.empty(m, np.bool_)
    sums = np.empty(m)
    for t in prange(m):
        observed[t], sums[t] = _scan_cuboid(blocks[t], 0, 0, 0, n, low, high)
    return observed, sums


@njit(cache=True, parallel=True)
def _coverages(levels, flat, n, shape, gt_start, gt_voxels, offsets, within, cov):
    """Set the coverages ``cov[:, f]`` of the flat cuboid indices ``flat`` from their (m, n, n,
    n) uint32 ``levels``, in place (:func:`_cuboid_coverage`), on the threads."""
    for t in prange(flat.shape[0]):
        _cuboid_coverage(t, levels, flat, n, shape, gt_start, gt_voxels, offsets, within, cov)


@njit(cache=True)
def _serial_coverages(levels, flat, n, shape, gt_start, gt_voxels, offsets, within, cov):
    """:func:`_coverages` in the calling thread (the same bits)."""
    for t in range(flat.shape[0]):
        _cuboid_coverage(t, levels, flat, n, shape, gt_start, gt_voxels, offsets, within, cov)


@njit(cache=True, inline="always")
def _cuboid_coverage(t, levels, flat, n, shape, gt_start, gt_voxels, offsets, within, cov):
    """Set the coverages ``cov[:, flat[t]]`` from ``levels[t]`` (:func:`_coverage`)."""
    f = flat[t]
    corner = (f // (shape[1] * shape[2]) * n, (f // shape[2]) % shape[1] * n, f % shape[2] * n)
    _coverage(levels[t], gt_voxels[gt_start[f] : gt_start[f + 1]], corner, offsets, within,
              cov[:, f])  # fmt: skip


@njit(cache=True, nogil=True)
def _trial_coverages(levels, flat, n, shape, gt_start, gt_voxels, offsets, within, out):
    """Set ``out[t]`` to the coverage of the one setting whose reach ``within`` (o,) gives
    (bit 0) of the flat cuboid ``flat[t]`` from its (n, n, n) ``levels`` (bit 0: the setting's
    threshold exceeded): :func:`_coverages` for one setting, in one thread."""
    cov = np.empty(1)
    for t in range(flat.shape[0]):
        f = flat[t]
        corner = (f // (shape[1] * shape[2]) * n, (f // shape[2]) % shape[1] * n, f % shape[2] * n)
        _coverage(levels[t], gt_voxels[gt_start[f] : gt_start[f + 1]], corner, offsets, within,
                  cov)  # fmt: skip
        out[t] = cov[0]


@njit(cache=True)
def _store_cuboids(flat, observed, sums, occupied, found, setting, unobserved_l1, span,
                   seen, l1, cov, terms):  # fmt: skip
    """:meth:`QualityTracker._store` cuboid by cuboid, into ``seen``, ``l1``, ``cov`` and
    ``terms``: the element-wise arithmetic of ``_term`` and
    :func:`~nbv_gym.metrics.cuboids.empty_quality` (``span``: unobserved − best L1), so the same
    bits, without the temporary arrays of a few hundred cuboids."""
    for t in range(len(flat)):
        cuboid = flat[t]
        seen[cuboid] = observed[t]
        l1[cuboid] = sums[t] if observed[t] else unobserved_l1
        for s in range(cov.shape[0]):
            cov[s, cuboid] = found[s, cuboid] if observed[t] and occupied[cuboid] else 0.0
        if occupied[cuboid]:
            terms[cuboid] = cov[setting, cuboid]
        else:
            terms[cuboid] = min(max((unobserved_l1 - l1[cuboid]) / span, 0.0), 1.0)


@njit(cache=True)
def _levels(probabilities, thresholds, out):
    """``out[i]``: the bitmask of the ``thresholds`` that ``probabilities[i]`` exceeds."""
    for i in range(probabilities.shape[0]):
        p, level = probabilities[i], np.uint32(0)
        for s in range(thresholds.shape[0]):
            level |= np.uint32(p > thresholds[s]) << np.uint32(s)
        out[i] = level


@njit(cache=True)
def _scan_cuboid(prob, i0, j0, k0, n, low, high):
    """(observed, Σp in float64) of the cuboid with low voxel corner (i0, j0, k0).

    The sum runs in a fixed order, whatever the CPU: one partial sum per k (the contiguous axis,
    which vectorises without reassociating), then the n partial sums in k order. (A sum that the
    compiler may reassociate varies with the CPU's vector width.)
    """
    partial = np.zeros(n)
    lowest = np.inf
    highest = -np.inf
    for i in range(i0, i0 + n):
        for j in range(j0, j0 + n):
            for k in range(n):
                p = prob[i, j, k0 + k]
                partial[k] += p
                lowest = min(lowest, p)
                highest = max(highest, p)
    total = 0.0
    for k in range(n):
        total += partial[k]
    return lowest <= low or highest >= high, total


@njit(cache=True)
def _coverage(levels, voxels, corner, offsets, within, out):
    """Fill ``out`` (s,) with the coverage of each setting for the ground-truth ``voxels`` (k, 3)
    of the cuboid whose low voxel is ``corner``, from its (n, n, n) ``levels``: per voxel the
    bitmask of the settings whose threshold its p exceeds (:func:`_levels`).

    A ground-truth voxel is covered by setting s if some voxel of ``offsets`` (sorted by length)
    inside the cuboid has bit s, where ``within`` (o,) is the bitmask of the settings whose
    radius reaches offset o. The search of a voxel stops once every setting has a match.
    """
    n = levels.shape[0]
    settings = out.shape[0]
    every = (1 << settings) - 1
    counts = np.zeros(settings, np.int64)
    for v in range(voxels.shape[0]):
        x, y, z = voxels[v, 0] - corner[0], voxels[v, 1] - corner[1], voxels[v, 2] - corner[2]
        found = 0
        for o in range(offsets.shape[0]):
            i, j, k = x + offsets[o, 0], y + offsets[o, 1], z + offsets[o, 2]
            if 0 <= i < n and 0 <= j < n and 0 <= k < n:
                found |= levels[i, j, k] & within[o]
                if found == every:
                    break
        for s in range(settings):
            counts[s] += (found >> s) & 1
    for s in range(settings):
        out[s] = counts[s] / voxels.shape[0] if voxels.shape[0] else 0.0
