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

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nbv_gym.core.arrays import BoolArray, FloatArray, IntArray
from nbv_gym.core.config import check
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig
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
        return summarise(self.u_occ, self.volume, self.observed, self.cov, self.l1, self.quality,
                        self.config)  # fmt: skip


def summarise(u_occ, volume, observed, cov, l1, quality, config: CuboidConfig) -> QualitySummary:
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
    values = _Observed(quality[seen], cov.take(seen[holding], axis=1), l1[seen[~holding]])
    n_occ = int(np.count_nonzero(u_occ & volume))
    n_empty = int(np.count_nonzero(volume)) - n_occ
    seen_occ = int(holding.sum())
    every = _means(values, n_occ - seen_occ, n_empty - (len(seen) - seen_occ), config)
    observed_means = _means(values, 0, 0, config)
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


class _Observed:
    """The observed cuboids of a summary — (k,) ``terms`` of Q, (s, a) ``covs`` of those holding
    ground truth, (b,) ``l1s`` of the others — with their sums, taken once for both means."""

    def __init__(self, terms: FloatArray, covs: FloatArray, l1s: FloatArray):
        self.terms, self.covs, self.l1s = terms, covs, l1s
        self.terms_sum, self.cov_sums, self.l1_sum = terms.sum(), covs.sum(axis=1), l1s.sum()


def _means(
    values: _Observed, unseen_occ: int, unseen_empty: int, config
) -> tuple[float, float, tuple[float, ...], float]:
    """(Q, Q_paper, cov per setting, L1) over the observed cuboids ``values`` and
    ``unseen_occ`` + ``unseen_empty`` unobserved ones; NaN where a set is empty."""
    nan = float("nan")
    covs, l1s = values.covs, values.l1s
    n_occ, n_empty = covs.shape[1] + unseen_occ, len(l1s) + unseen_empty
    l1_sum = _with_unseen(values.l1_sum, unseen_empty, config.unobserved_l1)
    return (
        _mean_of(values.terms_sum, len(values.terms), unseen_occ, unseen_empty, config),
        _paper(covs[config.q_setting], l1s, unseen_occ, unseen_empty, config),
        tuple((values.cov_sums / n_occ).tolist()) if n_occ else (nan,) * len(covs),
        float(l1_sum / n_empty) if n_empty else nan,
    )


def mean_quality(terms: FloatArray, unseen_occ: int, unseen_empty: int, config) -> float:
    """Q over the observed cuboids' (k,) float64 ``terms`` and ``unseen_occ`` + ``unseen_empty``
    unobserved ones (NaN when there are none)."""
    return _mean_of(terms.sum(), len(terms), unseen_occ, unseen_empty, config)


def _mean_of(total, n_terms: int, unseen_occ: int, unseen_empty: int, config) -> float:
    """:func:`mean_quality` of ``n_terms`` terms summing to ``total``."""
    n = n_terms + unseen_occ + unseen_empty
    # an unobserved cuboid's coverage is 0, so is the term of one holding ground truth
    q = _with_unseen(total, unseen_empty, empty_quality(config.unobserved_l1, config))
    return float(q / n) if n else float("nan")


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
    cx, cy, cz = (s // cuboid_voxels for s in grid_shape)
    return cx, cy, cz


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
    return np.asarray(cuboid_view(np.asarray(gt, bool), cuboid_voxels).any(axis=(3, 4, 5)))


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
