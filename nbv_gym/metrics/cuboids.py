"""Cuboid quality metrics of a reconstructed probability grid against a ground-truth grid (docs/protocol.md#metrics).

The voxel grid is split into cuboids of ``n × n × n`` voxels (``n = cuboid_voxels``, 10 in the
benchmark: the cells of the statistics grid G). Arrays are indexed ``[x, y, z]``; cuboid
``(ci, cj, ck)`` holds voxels ``[ci*n:(ci+1)*n, cj*n:(cj+1)*n, ck*n:(ck+1)*n]``.

Per cuboid (*Next-Best-View selection from observation viewpoint statistics*, §III-A, the authors' code for the unobserved case):

- ``U_occ``: the ground truth holds an occupied voxel; ``U_empty``: the rest.
- unobserved iff every reconstructed p lies in the open band ``(0.4, 0.6)``; then cov = 0 and
  L1 = 0.5·n³ (= 500), whatever the reconstruction. Thresholds are compared in the grid's own
  precision (a float32 grid against float32(0.4)), so a voxel at p_miss = 0.4 counts as observed.
- ``cov(p, d)`` on ``U_occ``: fraction of ground-truth voxels with a reconstructed voxel of
  probability ``> p`` at a centre-to-centre distance ``<= d`` metres, searched inside the same cuboid.
- ``L1``: the sum of p over the cuboid.

Qualities, each a mean over the cuboids of the **comparison volume** (docs/protocol.md#comparison-volume, the NBV paper's §III-A
``B_box1 ∩ B_box2``): by default the cuboids that intersect the ground truth's bounding box — the
reconstruction's box is the grid itself — so that the empty sky above short assets, which no scan
can observe, does not dilute the scores. ``CuboidConfig.volume = "grid"`` compares over every
cuboid instead. Summaries carry the same figures over the observed cuboids of the volume too.

- ``Q`` (*ours*, the reward): cov(0.7, 0.15) on ``U_occ``; on ``U_empty``
  ``clip((0.5·n³ − L1) / ((0.5 − 0.12)·n³), 0, 1)`` — 1 at the clamping floor 0.12, 0 when unknown.
- ``Q_paper``: equation (3) of *Next-Best-View selection from observation viewpoint statistics*: cov and L1 min–max normalised over the cuboids of their
  set at that moment. Interpretation: when a set's values are all equal (max = min, e.g. nothing
  observed yet) eq. (3) is undefined; we then use the fixed-bound value of ``Q`` for that set.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from nbv_gym.core.arrays import BoolArray, FloatArray, IntArray
from nbv_gym.core.config import check
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig
from nbv_gym.mapping.probability import logodds_bound
from nbv_gym.mapping.statistics import StatisticsConfig
from nbv_gym.metrics import MetricInputError

#: The four (p, d_m) coverage settings of the papers; the last one is the default of Q.
COV_SETTINGS: tuple[tuple[float, float], ...] = ((0.8, 0.05), (0.8, 0.10), (0.7, 0.10), (0.7, 0.15))

#: The comparison volumes: the cuboids intersecting the ground truth's bounding box, or all of G.
VOLUMES = ("ground_truth_box", "grid")


def benchmark_grid() -> GridSpec:
    """The voxel box the benchmark's metrics cover: G's box (``StatisticsConfig``) at the map's
    resolution (``MapConfig``); shape (600, 600, 60) by default."""
    statistics = StatisticsConfig()
    return GridSpec.from_bounds(statistics.low_m, statistics.high_m, MapConfig().resolution_m)


@dataclass(frozen=True)
class QualityConfig:
    """How a reconstruction is judged (defaults: docs/protocol.md#metrics): ``unknown_low``/``unknown_high``: the
    open probability band of an unobserved cuboid; ``cov_settings``: (p, d metres) pairs;
    ``q_setting``: index of the pair used by Q; ``unobserved_wd``: WD_occ of an unobserved
    cuboid; ``volume``: the comparison volume, one of :data:`VOLUMES` (``"ground_truth_box"``: the
    cuboids that intersect the ground truth's bounding box, the default; ``"grid"``: every
    cuboid).

    The geometry (voxel size, cuboid edge) and the map's lower clamp are not part of it: the
    simulator takes them from its map and statistics configs (:class:`CuboidConfig` adds them
    for metrics computed on their own).
    """

    unknown_low: float = 0.4
    unknown_high: float = 0.6
    cov_settings: tuple[tuple[float, float], ...] = COV_SETTINGS
    q_setting: int = 3
    unobserved_wd: float = 100.0
    volume: str = "ground_truth_box"

    def __post_init__(self):
        check(self.volume in VOLUMES, "volume", f"expected one of {VOLUMES}, got {self.volume!r}")
        check(
            0 <= self.unknown_low < 0.5 < self.unknown_high <= 1,
            "unknown_low",
            f"need 0 <= unknown_low < 0.5 < unknown_high <= 1, got "
            f"{self.unknown_low}, {self.unknown_high}",
        )
        check(
            1 <= len(self.cov_settings) <= 32,
            "cov_settings",
            f"needs 1 to 32 (p, d) pairs, got {len(self.cov_settings)}",
        )
        for p, d in self.cov_settings:
            check(0 <= p < 1 and d >= 0, "cov_settings", f"need 0 <= p < 1, d >= 0; got {p, d}")
        check(
            0 <= self.q_setting < len(self.cov_settings),
            "q_setting",
            f"must index cov_settings (0..{len(self.cov_settings) - 1}), got {self.q_setting}",
        )


@dataclass(frozen=True)
class CuboidConfig(QualityConfig):
    """A :class:`QualityConfig` with the grid it is computed on, for metrics of arrays computed
    on their own (the simulator derives these three from its map: see
    :meth:`for_map`).

    ``cuboid_voxels``: voxels per cuboid edge; ``resolution_m``: voxel edge in metres (turns the
    coverage distances into voxel offsets); ``clamp_min_p``: the map's lower clamp, the best
    empty-cuboid p. Defaults: the benchmark's map and G (:class:`MapConfig`,
    :class:`StatisticsConfig`).
    """

    cuboid_voxels: int = round(StatisticsConfig.cell_m / MapConfig.resolution_m)
    resolution_m: float = MapConfig.resolution_m
    clamp_min_p: float = MapConfig.p_clamp_min

    def __post_init__(self):
        super().__post_init__()
        check(self.cuboid_voxels >= 1, "cuboid_voxels", f"must be >= 1, got {self.cuboid_voxels}")
        check(self.resolution_m > 0, "resolution_m", f"must be > 0, got {self.resolution_m}")
        check(
            0 <= self.clamp_min_p < 0.5,
            "clamp_min_p",
            f"must be in [0, 0.5), got {self.clamp_min_p}",
        )

    @classmethod
    def for_map(
        cls, quality: QualityConfig, resolution_m: float, cell_m: float, clamp_min_p: float
    ) -> CuboidConfig:
        """``quality`` on cuboids of ``cell_m`` (G's cells) of a map with voxels of
        ``resolution_m`` and lower clamp ``clamp_min_p``; ConfigError unless a cell is a whole
        number of voxels."""
        ratio = cell_m / resolution_m
        check(
            abs(ratio - round(ratio)) < 1e-6 and round(ratio) >= 1,
            "mapping.statistics.cell_m",
            f"G's cells ({cell_m} m) must be a whole number of map voxels "
            f"(mapping.map.resolution_m = {resolution_m} m)",
        )
        fields = {f.name: getattr(quality, f.name) for f in dataclasses.fields(QualityConfig)}
        return cls(**fields, cuboid_voxels=round(ratio), resolution_m=resolution_m,
                   clamp_min_p=clamp_min_p)  # fmt: skip

    @property
    def cuboid_size(self) -> int:
        """Voxels per cuboid (n³)."""
        return self.cuboid_voxels**3

    @property
    def unobserved_l1(self) -> float:
        """L1 of an unobserved cuboid: 0.5 · n³ (500 for n = 10)."""
        return 0.5 * self.cuboid_size

    @property
    def best_l1(self) -> float:
        """L1 of an empty cuboid at the clamping floor: clamp_min_p · n³ (120 for n = 10)."""
        return self.clamp_min_p * self.cuboid_size


@dataclass(frozen=True)
class QualitySummary:
    """Scalar qualities over the comparison volume.

    ``q``, ``q_paper`` in [0, 1]; ``cov``: mean cov over U_occ per setting (same order as
    ``CuboidConfig.cov_settings``); ``l1``: mean L1 over U_empty; counts of the volume's cuboids
    (``n_occ + n_empty`` is the volume). The ``*_observed`` fields are the same figures over the
    volume's observed cuboids only (NaN while none is observed).
    """

    q: float
    q_paper: float
    cov: tuple[float, ...]
    l1: float
    n_occ: int
    n_empty: int
    n_observed: int
    q_observed: float
    q_paper_observed: float
    cov_observed: tuple[float, ...]
    l1_observed: float


@dataclass
class CuboidMetrics:
    """Per-cuboid metrics, each array of the cuboid grid's shape ``(cx, cy, cz)``.

    ``u_occ``/``observed``/``volume`` bool (``volume``: the comparison volume); ``cov``
    (s, cx, cy, cz) float64 (NaN on U_empty); ``l1`` float64 (all cuboids); ``quality`` float64:
    the per-cuboid term of Q.
    """

    u_occ: BoolArray
    observed: BoolArray
    cov: FloatArray
    l1: FloatArray
    quality: FloatArray
    config: CuboidConfig = field(default_factory=CuboidConfig)
    volume: BoolArray | None = None

    def __post_init__(self):
        if self.volume is None:
            self.volume = np.ones(self.u_occ.shape, bool)

    def summary(self) -> QualitySummary:
        """The :class:`QualitySummary` over the comparison volume and its observed part."""
        return _summary(self.u_occ, self.volume, self.observed, self.cov, self.l1, self.quality,
                        self.config)  # fmt: skip


def _summary(u_occ, volume, observed, cov, l1, quality, config: CuboidConfig) -> QualitySummary:
    """The :class:`QualitySummary` of per-cuboid arrays of one shape (``cov`` with a leading
    setting axis; its values off U_occ are never read).

    An unobserved cuboid holds fixed values (cov 0, L1 = 0.5·n³ and the term of Q they give),
    so the figures over the volume add the observed cuboids' values to the number of unobserved
    ones times those values: the work follows the observed cuboids, not the volume (345 600
    cuboids in a 240 m world, 11 000 of them observed after eight scans). The figures over the
    observed cuboids are their plain means."""
    u_occ, volume, observed, l1, quality = (
        a.reshape(-1) for a in (u_occ, volume, observed, l1, quality)
    )
    cov = cov.reshape(len(cov), -1)
    seen = np.flatnonzero(volume & observed)
    holding = u_occ[seen]
    values = (quality[seen], cov.take(seen[holding], axis=1), l1[seen[~holding]])
    n_occ = int(np.count_nonzero(u_occ & volume))
    n_empty = int(np.count_nonzero(volume)) - n_occ
    seen_occ = int(holding.sum())
    every = _means(*values, n_occ - seen_occ, n_empty - (len(seen) - seen_occ), config)
    observed_means = _means(*values, 0, 0, config)
    return QualitySummary(
        *every,
        n_occ=n_occ,
        n_empty=n_empty,
        n_observed=len(seen),
        q_observed=observed_means[0],
        q_paper_observed=observed_means[1],
        cov_observed=observed_means[2],
        l1_observed=observed_means[3],
    )


def _means(
    terms, covs, l1s, unseen_occ: int, unseen_empty: int, config
) -> tuple[float, float, tuple[float, ...], float]:
    """(Q, Q_paper, cov per setting, L1) over observed cuboids — (k,) ``terms`` of Q, (s, a)
    ``covs`` of those holding ground truth, (b,) ``l1s`` of the others — and ``unseen_occ`` +
    ``unseen_empty`` unobserved ones; NaN where a set is empty."""
    nan = float("nan")
    n = len(terms) + unseen_occ + unseen_empty
    # an unobserved cuboid's coverage is 0, so is the term of one holding ground truth
    q = _with_unseen(terms.sum(), unseen_empty, empty_quality(config.unobserved_l1, config))
    n_occ, n_empty = covs.shape[1] + unseen_occ, len(l1s) + unseen_empty
    cov_sums = covs.sum(axis=1)  # row by row
    l1_sum = _with_unseen(l1s.sum(), unseen_empty, config.unobserved_l1)
    return (
        float(q / n) if n else nan,
        _paper(covs[config.q_setting], l1s, unseen_occ, unseen_empty, config),
        tuple((cov_sums / n_occ).tolist()) if n_occ else (nan,) * len(covs),
        float(l1_sum / n_empty) if n_empty else nan,
    )


def _with_unseen(total, unseen: int, value):
    """``total`` plus ``unseen`` × ``value`` (``total`` itself, bit for bit, when none)."""
    return total + unseen * value if unseen else total


def cuboid_shape(grid_shape: tuple[int, ...], cuboid_voxels: int) -> tuple[int, int, int]:
    """Shape ``(cx, cy, cz)`` of the cuboid grid; raises if ``grid_shape`` is not a whole multiple."""
    if len(grid_shape) != 3 or any(s <= 0 or s % cuboid_voxels for s in grid_shape):
        raise MetricInputError(
            f"grid shape {tuple(grid_shape)} is not a positive whole number of "
            f"{cuboid_voxels}-voxel cuboids along each of x, y, z"
        )
    return tuple(s // cuboid_voxels for s in grid_shape)


def check_grids(prob: FloatArray, gt: BoolArray, cuboid_voxels: int) -> tuple[int, int, int]:
    """Check a probability grid and a ground-truth grid against each other; return the cuboid shape."""
    prob, gt = np.asarray(prob), np.asarray(gt)
    if prob.shape != gt.shape:
        raise MetricInputError(
            f"reconstruction grid shape {prob.shape} differs from ground-truth shape {gt.shape}; "
            "both must cover the same voxel box at the same resolution"
        )
    if not np.issubdtype(prob.dtype, np.floating):
        raise MetricInputError(f"reconstruction must hold probabilities (float), got {prob.dtype}")
    return cuboid_shape(prob.shape, cuboid_voxels)


def cuboid_view(grid: np.ndarray, cuboid_voxels: int) -> np.ndarray:
    """(cx, cy, cz, n, n, n) view of a (cx·n, cy·n, cz·n) grid, no copy."""
    cx, cy, cz = cuboid_shape(grid.shape, cuboid_voxels)
    n = cuboid_voxels
    return grid.reshape(cx, n, cy, n, cz, n).transpose(0, 2, 4, 1, 3, 5)


def occupied_cuboids(gt: BoolArray, cuboid_voxels: int) -> BoolArray:
    """(cx, cy, cz) bool: U_occ, the cuboids whose ground truth holds an occupied voxel."""
    return cuboid_view(np.asarray(gt, bool), cuboid_voxels).any(axis=(3, 4, 5))


def comparison_volume(u_occ: BoolArray, volume: str = "ground_truth_box") -> BoolArray:
    """(cx, cy, cz) bool: the cuboids over which qualities are compared (see :data:`VOLUMES`).

    ``"ground_truth_box"``: the cuboids that intersect the ground truth's bounding box, i.e. the
    box spanned by the cuboids of ``u_occ`` (a voxel box's bounding box in cuboid units); all
    False when the ground truth is empty. ``"grid"``: every cuboid.
    """
    if volume == "grid":
        return np.ones(u_occ.shape, bool)
    inside = np.zeros(u_occ.shape, bool)
    if u_occ.any():
        cells = np.argwhere(u_occ)
        low, high = cells.min(axis=0), cells.max(axis=0) + 1
        inside[low[0] : high[0], low[1] : high[1], low[2] : high[2]] = True
    return inside


def coverage_offsets(distance_m: float, resolution_m: float) -> IntArray:
    """(k, 3) int64 voxel offsets whose centre distance ``|o|·resolution_m`` is ``<= distance_m``."""
    reach = int(np.floor(distance_m / resolution_m + 1e-9))
    axis = np.arange(-reach, reach + 1)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1).reshape(-1, 3)
    limit = (distance_m / resolution_m) ** 2 + 1e-9
    return grid[(grid**2).sum(axis=1) <= limit].astype(np.int64)


def evaluate_cuboids(
    prob: FloatArray, gt: BoolArray, config: CuboidConfig | None = None
) -> CuboidMetrics:
    """All per-cuboid metrics of reconstruction ``prob`` (X, Y, Z) float against ``gt`` (X, Y, Z) bool."""
    tracker = QualityTracker(gt, config)
    tracker.update(prob)
    return tracker.metrics()


def q_paper(cov: FloatArray, l1: FloatArray, config: CuboidConfig) -> float:
    """Eq. (3) of *Next-Best-View selection from observation viewpoint statistics*: mean of min–max normalised cov (U_occ) and 1 − normalised L1 (U_empty).

    ``cov`` (n,) and ``l1`` (m,) float. A set whose values are all equal falls back to the
    fixed-bound terms of Q (see the module docstring). Empty input gives NaN.
    """
    return _paper(np.asarray(cov, float), np.asarray(l1, float), 0, 0, config)


def _paper(cov: FloatArray, l1: FloatArray, unseen_occ: int, unseen_empty: int, config) -> float:
    """:func:`q_paper` of the sets ``cov`` with ``unseen_occ`` more coverages of 0 and ``l1``
    with ``unseen_empty`` more L1 of an unobserved cuboid."""
    if cov.size + unseen_occ + l1.size + unseen_empty == 0:
        return float("nan")

    def fixed_l1(v: FloatArray) -> FloatArray:  # normalised L1 (0 = best) with fixed bounds
        return 1 - empty_quality(v, config)

    covered = _normalised_sum(cov, unseen_occ, 0.0, lambda v: v, flip=False)
    empty = _normalised_sum(l1, unseen_empty, config.unobserved_l1, fixed_l1, flip=True)
    return float((covered + empty) / (cov.size + unseen_occ + l1.size + unseen_empty))


def empty_quality(l1: FloatArray, config: CuboidConfig) -> FloatArray:
    """Q's term of an empty cuboid: ``clip((0.5·n³ − L1) / ((0.5 − clamp_min_p)·n³), 0, 1)``."""
    span = config.unobserved_l1 - config.best_l1
    return np.clip((config.unobserved_l1 - np.asarray(l1, float)) / span, 0.0, 1.0)


def _normalised_sum(
    values: FloatArray, unseen: int, unseen_value: float, fixed: Callable, flip: bool
) -> float:
    """Σ of the min–max normalised ``values`` and ``unseen`` copies of ``unseen_value`` (of
    1 − it when ``flip``); for a set whose values are all equal, of ``fixed(value)`` instead
    (the fallback of eq. (3))."""
    if values.size + unseen == 0:
        return 0.0
    extremes = [
        *((values.min(), values.max()) if values.size else ()),
        *([unseen_value] if unseen else []),
    ]
    low, high = min(extremes), max(extremes)

    def normalise(v):
        scaled = fixed(v) if high == low else (v - low) / (high - low)
        return 1 - scaled if flip else scaled

    return _with_unseen(normalise(values).sum(), unseen, normalise(np.float64(unseen_value)))


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
        _coverages(
            np.ascontiguousarray(levels), flat, n, self.shape, self._gt_start, self._gt_voxels,
            self._offsets, self._within, self._found,
        )  # fmt: skip

    def _store(self, flat: IntArray, observed: BoolArray, sums: FloatArray) -> None:
        """Set the cuboids ``flat``: observed or not, L1 (their ``sums`` if observed), coverage
        (the search's result where observed and holding ground truth, else 0)."""
        self._observed[flat] = observed
        self._l1[flat] = np.where(observed, sums, self.config.unobserved_l1)
        self._cov[:, flat] = np.where(observed & self._occupied[flat], self._found[:, flat], 0.0)
        self._terms[flat] = self._term(self._cov[:, flat], self._l1[flat], self._occupied[flat])

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
        return _summary(self.u_occ, self.volume, self._observed.reshape(self.shape), cov, l1,
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
    n) uint32 ``levels``, in place (:func:`_coverage`)."""
    for t in prange(flat.shape[0]):
        f = flat[t]
        corner = (f // (shape[1] * shape[2]) * n, (f // shape[2]) % shape[1] * n, f % shape[2] * n)
        _coverage(levels[t], gt_voxels[gt_start[f] : gt_start[f + 1]], corner, offsets, within,
                  cov[:, f])  # fmt: skip


@njit(cache=True)
def _levels(probabilities, thresholds, out):
    """``out[i]``: the bitmask of the ``thresholds`` that ``probabilities[i]`` exceeds."""
    for i in range(probabilities.shape[0]):
        p, level = probabilities[i], np.uint32(0)
        for s in range(thresholds.shape[0]):
            level |= np.uint32(p > thresholds[s]) << np.uint32(s)
        out[i] = level


@njit(cache=True, fastmath={"reassoc", "nsz"})
def _scan_cuboid(prob, i0, j0, k0, n, low, high):
    """(observed, Σp in float64) of the cuboid with low voxel corner (i0, j0, k0).

    The sum may be reassociated (vectorised): it is still a pure function of the cuboid, so a
    cuboid recomputed alone gives the same bits as in a full pass.
    """
    total = 0.0
    lowest = np.inf
    highest = -np.inf
    for i in range(i0, i0 + n):
        for j in range(j0, j0 + n):
            for k in range(k0, k0 + n):
                p = prob[i, j, k]
                total += p
                lowest = min(lowest, p)
                highest = max(highest, p)
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
