"""Empir3D (``004_…``): resolution, accuracy, coverage and artifact scores of a point cloud, plus the
Chamfer and Hausdorff distances, against a reference (ground-truth) cloud.

Definitions (``A`` reference, ``B`` candidate, cells of edge ε aligned on the low corner of the
union bounding box; regions are blocks of whole cells, of edge ``round(r / ε) · ε`` ≈ r):

- ``q_r`` per region = mean nearest-neighbour distance inside ``reg_A`` / the same inside ``reg_B``
  (eq. 4), clipped to at most 1 (*ours*: the paper states the metrics lie in [0, 1]; a candidate
  denser than the reference scores 1). ``Q_r`` is the mean over regions.
- ``q_a`` per region = ``1 − Σ_b s(b) / (ε |reg_B|)`` with ``s(b)`` the distance from ``b`` to its
  nearest neighbour in ``reg_A`` when ``<= ε``, else 0 (eq. 5). ``Q_a`` is the mean over regions.
- ``Q_c = |S_A ∩ S_B| / |S_A|`` and ``Q_t = 1 − |S_B \\ S_A| / |S_B|`` over the ε-cells of the whole
  clouds (eqs. 6, 7); per region the same on the cells of the region.
- Chamfer ``D_c`` = Σ over both clouds of nearest-neighbour distances (eq. 1, not squared);
  Hausdorff ``D_h`` = the largest of them (eq. 2).

Interpretation (*ours*): ``Q_r`` and ``Q_a`` average over the regions that hold at least two points
of each cloud (``q_r`` needs a neighbour inside the region in both). Nearest neighbours are searched
inside the region only, as the paper's per-region definition says; one k-d tree per cloud serves all
regions because every region is moved into its own slot of a spread-out copy of space (see
:class:`_CellSplit`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from nbv_gym.arrays import FloatArray, IntArray
from nbv_gym.config import check
from nbv_gym.metrics import MetricInputError


@dataclass(frozen=True)
class Empir3DConfig:
    """``epsilon_m``: cell size ε (the expected precision), metres; ``region_m``: region edge r, metres.

    Defaults: ε = 0.1 m as the paper's ablation (Table I); r = 5 m (*ours*; the paper uses 2–20 m).
    """

    epsilon_m: float = 0.1
    region_m: float = 5.0

    def __post_init__(self):
        check(self.epsilon_m > 0, "epsilon_m", f"must be > 0, got {self.epsilon_m}")
        check(self.region_m > 0, "region_m", f"must be > 0, got {self.region_m}")


@dataclass(frozen=True)
class RegionScores:
    """Per-region results, one row per region holding points of either cloud.

    ``index`` (N, 3) int64 region indices; ``low_m`` (N, 3) float low corners, metres;
    ``n_reference``/``n_candidate`` (N,) int64 point counts; ``q_r``, ``q_a``, ``q_c``, ``q_t`` (N,)
    float64, NaN where undefined (too few points, or no cells of that cloud).
    """

    index: IntArray
    low_m: FloatArray
    n_reference: IntArray
    n_candidate: IntArray
    q_r: FloatArray
    q_a: FloatArray
    q_c: FloatArray
    q_t: FloatArray

    def rows(self) -> list[dict[str, float]]:
        """The table as a list of plain dicts (for CSV or JSON)."""
        names = ("n_reference", "n_candidate", "q_r", "q_a", "q_c", "q_t")
        out = []
        for r in range(len(self.index)):
            row = {f"region_{a}": int(self.index[r, i]) for i, a in enumerate("xyz")}
            row.update({f"low_{a}_m": float(self.low_m[r, i]) for i, a in enumerate("xyz")})
            row.update({k: _plain(getattr(self, k)[r]) for k in names})
            out.append(row)
        return out


@dataclass(frozen=True)
class Empir3DResult:
    """The four scores in [0, 1] (1 = best), the distances in metres and the per-region table."""

    q_r: float
    q_a: float
    q_c: float
    q_t: float
    regions: RegionScores
    config: Empir3DConfig
    chamfer_m: float | None = None
    hausdorff_m: float | None = None

    def as_dict(self) -> dict[str, float | None]:
        """The scalar results as a plain dict."""
        return {
            "q_r": self.q_r,
            "q_a": self.q_a,
            "q_c": self.q_c,
            "q_t": self.q_t,
            "chamfer_m": self.chamfer_m,
            "hausdorff_m": self.hausdorff_m,
            "epsilon_m": self.config.epsilon_m,
            "region_m": self.config.region_m,
            "n_regions": len(self.regions.index),
        }


def empir3d(
    reference: FloatArray,
    candidate: FloatArray,
    config: Empir3DConfig | None = None,
    distances: bool = False,
    workers: int = -1,
) -> Empir3DResult:
    """Empir3D scores of ``candidate`` (m, 3) against ``reference`` (k, 3) float points in metres.

    With ``distances`` the Chamfer and Hausdorff distances are computed too (two more k-d tree
    queries). ``workers``: threads for the k-d tree queries (-1: all cores).
    """
    config = config or Empir3DConfig()
    a, b = _check_cloud(reference, "reference"), _check_cloud(candidate, "candidate")
    split = _CellSplit(a, b, config)
    regions = _region_scores(split, config, workers)
    q_c, q_t = _cell_scores(split.cells_a, split.cells_b)
    chamfer, hausdorff = chamfer_hausdorff(a, b, workers) if distances else (None, None)
    return Empir3DResult(
        q_r=_nanmean(regions.q_r),
        q_a=_nanmean(regions.q_a),
        q_c=q_c,
        q_t=q_t,
        regions=regions,
        config=config,
        chamfer_m=chamfer,
        hausdorff_m=hausdorff,
    )


def chamfer_hausdorff(a: FloatArray, b: FloatArray, workers: int = -1) -> tuple[float, float]:
    """(Chamfer, Hausdorff) distances in metres of two (k, 3) and (m, 3) point clouds (eqs. 1, 2).

    Both clouds are first sorted along a 1 m grid, which makes the k-d tree queries cache-friendly.
    """
    a, b = _check_cloud(a, "reference"), _check_cloud(b, "candidate")
    a, b = a[_grid_order(a, 1.0)], b[_grid_order(b, 1.0)]
    ab = _tree(b).query(a, workers=workers)[0]
    ba = _tree(a).query(b, workers=workers)[0]
    return float(ab.sum() + ba.sum()), float(max(ab.max(), ba.max()))


class _CellSplit:
    """Both clouds cut into ε-cells grouped in regions of ``m × m × m`` cells (m = round(r / ε)).

    Each point gets one int64 key ``region · m³ + cell within region``; the points are sorted by it
    (regions contiguous, which also makes the k-d tree queries cache-friendly). Attributes:
    ``index`` (N, 3) region indices of the regions holding points; ``of_a``/``of_b`` region number
    of each sorted point; ``cells_a``/``cells_b`` sorted unique keys; ``spread_a``/``spread_b`` the
    sorted points with region i moved to ``[3 R i, 3 R i + R)`` (R = m ε), so that points of different
    regions are more than R√3 apart and one k-d tree serves every region.
    """

    def __init__(self, a: FloatArray, b: FloatArray, config: Empir3DConfig):
        eps = config.epsilon_m
        self.m = max(1, int(round(config.region_m / eps)))
        origin = np.minimum(a.min(axis=0), b.min(axis=0))
        cells = [np.floor((p - origin) / eps).astype(np.int64) for p in (a, b)]
        span = -(-(np.maximum(cells[0].max(axis=0), cells[1].max(axis=0)) + 1) // self.m)
        if np.prod(span.astype(float)) * float(self.m) ** 3 >= 2.0**62:
            raise MetricInputError(f"the clouds span too many {eps} m cells; increase epsilon")
        keys = [self._keys(c, span) for c in cells]
        orders = [np.argsort(k, kind="stable") for k in keys]
        keys = [k[o] for k, o in zip(keys, orders, strict=True)]
        region_of = [k // self.m**3 for k in keys]  # sorted, like the keys
        self.region_keys = np.union1d(*(_sorted_unique(r) for r in region_of))
        self.index = np.stack(np.unravel_index(self.region_keys, tuple(span)), -1).astype(np.int64)
        self.of_a, self.of_b = (np.searchsorted(self.region_keys, r) for r in region_of)
        self.cells_a, self.cells_b = (_sorted_unique(k) for k in keys)
        size = self.m * eps
        self.spread_a, self.spread_b = (
            p[o] - origin + 2.0 * size * self.index[of]
            for p, o, of in zip((a, b), orders, (self.of_a, self.of_b), strict=True)
        )
        self.low = origin + self.index * size
        self.region_size = size

    def _keys(self, cells: IntArray, span: IntArray) -> IntArray:
        region = cells // self.m
        local = cells - region * self.m
        region_key = (region[:, 0] * span[1] + region[:, 1]) * span[2] + region[:, 2]
        local_key = (local[:, 0] * self.m + local[:, 1]) * self.m + local[:, 2]
        return region_key * self.m**3 + local_key

    def __len__(self) -> int:
        return len(self.index)


def _region_scores(split: _CellSplit, config: Empir3DConfig, workers) -> RegionScores:
    count = len(split)
    n_a = np.bincount(split.of_a, minlength=count)
    n_b = np.bincount(split.of_b, minlength=count)
    tree_a = _tree(split.spread_a)
    limit = np.sqrt(3.0) * split.region_size * (1 + 1e-9)
    spacing_a = _mean_spacing(tree_a, split.spread_a, split.of_a, count, limit, workers)
    spacing_b = _mean_spacing(
        _tree(split.spread_b), split.spread_b, split.of_b, count, limit, workers
    )
    both = (n_a >= 2) & (n_b >= 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        q_r = np.where(both, np.minimum(spacing_a / spacing_b, 1.0), np.nan)
    q_a = np.where(both, _accuracy(tree_a, split, n_b, config.epsilon_m, workers), np.nan)
    q_c, q_t = _region_cell_scores(split)
    return RegionScores(split.index, split.low, n_a, n_b, q_r, q_a, q_c, q_t)


def _tree(points: FloatArray) -> cKDTree:
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def _grid_order(points: FloatArray, cell_m: float) -> IntArray:
    """Permutation sorting ``points`` by their cell of a ``cell_m`` grid (C order)."""
    cells = np.floor((points - points.min(axis=0)) / cell_m).astype(np.int64)
    span = cells.max(axis=0) + 1
    return np.argsort((cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2], kind="stable")


def _mean_spacing(tree, points, region_of, count, limit, workers) -> FloatArray:
    """(count,) mean distance from each point to its nearest other point of the same region."""
    if len(points) < 2:
        return np.full(count, np.nan)
    dist = tree.query(points, k=2, workers=workers, distance_upper_bound=limit)[0][:, 1]
    inside = np.isfinite(dist)
    total = np.bincount(region_of[inside], weights=dist[inside], minlength=count)
    number = np.bincount(region_of[inside], minlength=count)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / number


def _accuracy(tree_a, split: _CellSplit, n_b, epsilon, workers) -> FloatArray:
    """(count,) q_a: 1 − Σ s(b) / (ε |reg_B|), s(b) the distance to reg_A when <= ε, else 0."""
    bound = epsilon * (1 + 1e-12)
    dist = tree_a.query(split.spread_b, workers=workers, distance_upper_bound=bound)[0]
    valid = np.isfinite(dist)
    error = np.bincount(split.of_b[valid], weights=dist[valid], minlength=len(split))
    with np.errstate(invalid="ignore", divide="ignore"):
        return 1.0 - error / (epsilon * n_b)


def _cell_scores(cells_a: IntArray, cells_b: IntArray) -> tuple[float, float]:
    """(Q_c, Q_t) of two sorted unique cell-key arrays."""
    common = int(_members(cells_a, cells_b).sum())
    return common / cells_a.size, common / cells_b.size


def _sorted_unique(keys: IntArray) -> IntArray:
    """Unique values of an already sorted array."""
    keep = np.ones(len(keys), bool)
    keep[1:] = keys[1:] != keys[:-1]
    return keys[keep]


def _members(keys: IntArray, sorted_keys: IntArray) -> np.ndarray:
    """(len(keys),) bool: which ``keys`` occur in the sorted array ``sorted_keys``."""
    at = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return sorted_keys[at] == keys


def _region_cell_scores(split: _CellSplit) -> tuple[FloatArray, FloatArray]:
    """Per-region (q_c, q_t): the cell scores restricted to each region's cells."""
    count = len(split)
    region_a = np.searchsorted(split.region_keys, split.cells_a // split.m**3)
    region_b = np.searchsorted(split.region_keys, split.cells_b // split.m**3)
    shared = np.bincount(region_a[_members(split.cells_a, split.cells_b)], minlength=count)
    with np.errstate(invalid="ignore", divide="ignore"):
        q_c = shared / np.bincount(region_a, minlength=count)
        q_t = shared / np.bincount(region_b, minlength=count)
    return q_c, q_t


def _check_cloud(points: FloatArray, name: str) -> FloatArray:
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3:
        raise MetricInputError(f"{name} point cloud must be (n, 3), got shape {points.shape}")
    if len(points) == 0:
        raise MetricInputError(f"{name} point cloud is empty")
    points = points.astype(np.float64, copy=False)
    if not np.isfinite(points).all():
        raise MetricInputError(f"{name} point cloud holds NaN or infinite coordinates")
    return points


def _nanmean(values: FloatArray) -> float:
    values = values[np.isfinite(values)]
    return float(values.mean()) if values.size else float("nan")


def _plain(value) -> float | int:
    return int(value) if isinstance(value, np.integer) else float(value)
