"""Empir3D (*Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment*): resolution, accuracy, coverage and artifact scores of a point cloud, plus the
Chamfer and Hausdorff distances, against a reference (ground-truth) cloud.

Definitions (``A`` reference, ``B`` candidate; ε-cells on a lattice anchored at the origin of the
coordinate frame, cell ``i`` spanning ``[i ε, (i + 1) ε)`` on each axis; regions are blocks of
``m × m × m`` cells, ``m = round(r / ε)``, on the same lattice):

- ``q_r`` per region = mean nearest-neighbour distance inside ``reg_A`` / the same inside ``reg_B``
  (eq. 4), clipped to at most 1 (*ours*: the paper states the metrics lie in [0, 1]; a candidate
  denser than the reference scores 1). ``Q_r`` is the mean over regions.
- ``q_a`` per region = ``1 − Σ_b s(b) / (ε |reg_B|)`` with ``s(b)`` the distance from ``b`` to its
  nearest neighbour in ``reg_A`` when ``<= ε``, else 0 (eq. 5). ``Q_a`` is the mean over regions.
- ``Q_c = |S_A ∩ S_B| / |S_A|`` and ``Q_t = 1 − |S_B \\ S_A| / |S_B|`` over the ε-cells of the whole
  clouds (eqs. 6, 7); per region the same on the cells of the region.
- Chamfer ``D_c`` (*ours*, as a mean so that it reads in metres and does not grow with the number
  of points): ``½ (mean_a d(a, B) + mean_b d(b, A))``, the symmetric mean of the unsquared
  nearest-neighbour distances (eq. 1 divides its two sums by the cloud sizes and halves them; two
  copies of a cloud shifted by δ are δ apart). Hausdorff ``D_h`` = the largest of those distances
  (eq. 2).

Stability (*ours*): coordinates are first quantised to ``ε / 10⁴`` (10 µm for ε = 0.1 m) and every
score is computed on the quantised clouds. Structured clouds put points on cell faces (voxel
corners) or at cell centres (voxel centres of a grid whose origin is a multiple of ε); with the
lattice fixed at the frame's origin and faces snapped to exact integers, such clouds bin the same
after a float32 round trip (≤ 1e-6 m for coordinates below 8 m; ≤ 4e-6 m below 64 m) or a
sub-micrometre shift, and the distance ``ε`` of eq. (5) between two grid points stays exactly ε.
Anchoring cells at the smallest point, as before, put voxel centres on cell faces, where such
noise moved them between cells. A point now changes cell only when it lies within ``ε / 2·10⁴``
of a face and moves across the midpoint of a quantum — a measure-zero event for real data.

Interpretation (*ours*): ``Q_r`` and ``Q_a`` average over the regions that hold at least two points
of each cloud (``q_r`` needs a neighbour inside the region in both). Nearest neighbours are searched
inside the region only, as the paper's per-region definition says, by a compiled search over the
ε-cells around each point (a hash of occupied cells; rings of cells until the nearest found point
is closer than any unvisited cell, then the whole region): Empir3D needs only neighbours within
ε (accuracy) or within a point's own region (resolution), which a cell search finds without the
two k-d trees a Chamfer distance builds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from scipy.spatial import cKDTree

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.empir3d_config import Empir3DConfig

#: Quanta per ε: coordinates are rounded to ε / QUANTA_PER_CELL before anything else.
QUANTA_PER_CELL = 10_000
#: Rings of cells searched around a point for its nearest neighbour before the whole region is.
SEARCH_RINGS = 3


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
        out: list[dict[str, float]] = []
        for r in range(len(self.index)):
            row: dict[str, float] = {
                f"region_{a}": int(self.index[r, i]) for i, a in enumerate("xyz")
            }
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

    With ``distances`` the Chamfer (mean) and Hausdorff distances are computed too (two k-d tree
    queries). ``workers``: threads for those queries (-1: all cores).
    """
    config = config or Empir3DConfig()
    a, b = _check_cloud(reference, "reference"), _check_cloud(candidate, "candidate")
    lattice = _Lattice(a, b, config)
    regions = _region_scores(lattice, config)
    q_c, q_t = _cell_scores(lattice.a.cells, lattice.b.cells)
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
    """(Chamfer, Hausdorff) distances in metres of two (k, 3) and (m, 3) point clouds: Chamfer
    ``½ (mean_a d(a, B) + mean_b d(b, A))`` (see the module doc), Hausdorff the largest ``d``.

    Both clouds are first sorted along a 1 m grid, which makes the k-d tree queries cache-friendly.
    """
    a, b = _check_cloud(a, "reference"), _check_cloud(b, "candidate")
    a, b = a[_grid_order(a, 1.0)], b[_grid_order(b, 1.0)]
    ab = _tree(b).query(a, workers=workers)[0]
    ba = _tree(a).query(b, workers=workers)[0]
    return float(0.5 * (ab.mean() + ba.mean())), float(max(ab.max(), ba.max()))


@dataclass(frozen=True)
class _Cloud:
    """One cloud on the lattice, sorted by cell key (regions contiguous): ``points`` (n, 3) the
    quantised coordinates, metres; ``cell`` (n, 3) int64 cell indices relative to the lattice's
    lowest region corner; ``region`` (n,) region number (row of the region table); ``cells``
    sorted unique cell keys; ``start`` (len(cells) + 1,) first point of each cell; ``table`` the
    open-addressing hash of ``cells`` (key, position) pairs."""

    points: FloatArray
    cell: IntArray
    region: IntArray
    cells: IntArray
    start: IntArray
    table: IntArray


class _Lattice:
    """Both clouds quantised to ε / 10⁴ and cut into ε-cells grouped in regions of ``m³`` cells.

    A cell's int64 key is ``region key · m³ + cell within region``; ``region_keys`` are the sorted
    keys of the regions holding points, ``index`` (N, 3) their lattice indices (region ``i``
    spans ``[i m ε, (i + 1) m ε)``) and ``low`` (N, 3) their low corners, metres. ``region_start_a``
    / ``region_start_b`` (N + 1,) the first point of each region in each sorted cloud.
    """

    def __init__(self, a: FloatArray, b: FloatArray, config: Empir3DConfig):
        eps = config.epsilon_m
        self.m = max(1, int(round(config.region_m / eps)))
        quantum = eps / QUANTA_PER_CELL
        if max(np.abs(a).max(), np.abs(b).max()) / quantum >= 2.0**62:
            raise MetricInputError(f"coordinates too large for {eps} m cells; increase epsilon")
        units = [np.rint(p / quantum).astype(np.int64) for p in (a, b)]
        cells = [u // QUANTA_PER_CELL for u in units]
        low = np.minimum(cells[0].min(axis=0), cells[1].min(axis=0)) // self.m * self.m
        cells = [c - low for c in cells]
        self.origin = low * eps
        self.span = -(-(np.maximum(cells[0].max(axis=0), cells[1].max(axis=0)) + 1) // self.m)
        if np.prod(self.span.astype(float)) * float(self.m) ** 3 >= 2.0**62:
            raise MetricInputError(f"the clouds span too many {eps} m cells; increase epsilon")
        keys = [self._keys(c) for c in cells]
        orders = [np.argsort(k, kind="stable") for k in keys]
        keys = [k[o] for k, o in zip(keys, orders, strict=True)]
        self.region_keys = np.union1d(*(_sorted_unique(k // self.m**3) for k in keys))
        self.index = np.stack(np.unravel_index(self.region_keys, tuple(self.span)), -1)
        self.index = self.index.astype(np.int64) + low // self.m
        self.region_size = self.m * eps
        self.low = self.index * self.region_size
        self.a, self.b = (
            self._cloud(u[o] * quantum, c[o], k)
            for u, c, o, k in zip(units, cells, orders, keys, strict=True)
        )
        self.region_start_a, self.region_start_b = (
            np.searchsorted(k, np.append(self.region_keys, self.region_keys[-1] + 1) * self.m**3)
            for k in keys
        )

    def _keys(self, cells: IntArray) -> IntArray:
        region = cells // self.m
        local = cells - region * self.m
        span = self.span
        region_key = (region[:, 0] * span[1] + region[:, 1]) * span[2] + region[:, 2]
        local_key = (local[:, 0] * self.m + local[:, 1]) * self.m + local[:, 2]
        return region_key * self.m**3 + local_key

    def _cloud(self, points: FloatArray, cell: IntArray, keys: IntArray) -> _Cloud:
        region = np.searchsorted(self.region_keys, keys // self.m**3)
        first = np.ones(len(keys), bool)
        first[1:] = keys[1:] != keys[:-1]
        start = np.append(np.flatnonzero(first), len(keys)).astype(np.int64)
        cells = keys[first]
        return _Cloud(points, cell, region, cells, start, _hash_table(cells))

    def __len__(self) -> int:
        return len(self.index)


def _region_scores(lattice: _Lattice, config: Empir3DConfig) -> RegionScores:
    count, eps = len(lattice), config.epsilon_m
    a, b = lattice.a, lattice.b
    n_a = np.bincount(a.region, minlength=count)
    n_b = np.bincount(b.region, minlength=count)
    spacing_a = _mean_spacing(a, lattice.region_start_a, lattice, eps)
    spacing_b = _mean_spacing(b, lattice.region_start_b, lattice, eps)
    both = (n_a >= 2) & (n_b >= 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        q_r = np.where(both, np.minimum(spacing_a / spacing_b, 1.0), np.nan)
    q_a = np.where(both, _accuracy(lattice, n_b, eps), np.nan)
    q_c, q_t = _region_cell_scores(lattice)
    return RegionScores(lattice.index, lattice.low, n_a, n_b, q_r, q_a, q_c, q_t)


def _nearest(query: _Cloud, target: _Cloud, region_start, lattice: _Lattice, eps, rings, whole):
    """(n,) distance from each ``query`` point to its nearest other ``target`` point of the same
    region (see :func:`_nearest_kernel`)."""
    return _nearest_kernel(
        query.points, query.cell, query.region, lattice.origin, target.points, target.start,
        target.table, region_start, lattice.m, lattice.span, eps, rings, whole, query is target,
    )  # fmt: skip


def _mean_spacing(cloud: _Cloud, region_start, lattice: _Lattice, eps) -> FloatArray:
    """(count,) mean distance from each point to its nearest other point of the same region."""
    dist = _nearest(cloud, cloud, region_start, lattice, eps, SEARCH_RINGS, True)
    inside = np.isfinite(dist)
    total = np.bincount(cloud.region[inside], weights=dist[inside], minlength=len(lattice))
    number = np.bincount(cloud.region[inside], minlength=len(lattice))
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / number


def _accuracy(lattice: _Lattice, n_b, epsilon) -> FloatArray:
    """(count,) q_a: 1 − Σ s(b) / (ε |reg_B|), s(b) the distance to reg_A when <= ε, else 0."""
    dist = _nearest(lattice.b, lattice.a, lattice.region_start_a, lattice, epsilon, 1, False)
    valid = dist <= epsilon * (1 + 1e-12)
    error = np.bincount(lattice.b.region[valid], weights=dist[valid], minlength=len(lattice))
    with np.errstate(invalid="ignore", divide="ignore"):
        return 1.0 - error / (epsilon * n_b)


@njit(cache=True)
def _slot(key, mask):
    """Home slot of ``key`` in a hash table of ``mask + 1`` slots (Fibonacci hashing)."""
    h = key * -7046029254386353131  # 2⁶⁴ / φ as int64; overflow wraps
    return (h ^ (h >> 29)) & mask


@njit(cache=True)
def _hash_table(keys):
    """(size, 2) int64 open-addressing table of non-negative ``keys``: column 0 the key (-1
    empty), column 1 its position in ``keys``; size a power of two ≥ 2 len(keys)."""
    size = 16
    while size < 2 * len(keys):
        size *= 2
    table = np.full((size, 2), -1, np.int64)
    mask = size - 1
    for i in range(len(keys)):
        slot = _slot(keys[i], mask)
        while table[slot, 0] != -1:
            slot = (slot + 1) & mask
        table[slot, 0] = keys[i]
        table[slot, 1] = i
    return table


@njit(cache=True)
def _lookup(table, key):
    """Position of ``key`` in the keys ``table`` was built from, or -1."""
    mask = table.shape[0] - 1
    slot = _slot(key, mask)
    while table[slot, 0] != -1:
        if table[slot, 0] == key:
            return table[slot, 1]
        slot = (slot + 1) & mask
    return -1


@njit(cache=True, parallel=True)
def _nearest_kernel(points, cell, region, origin, target, start, table, region_start, m, span,
                    eps, rings, whole, same):  # fmt: skip
    """(n,) distance from each point to its nearest target point in the same region (itself
    excluded when ``same``): first the point's own cell, then those of its 26 neighbours closer
    than the nearest point found so far (``origin`` (3,): the low corner of cell (0, 0, 0),
    metres); then the cells at Chebyshev ring 2, 3, … ``rings`` until the nearest found is
    within ``(r − 1) ε`` (no unvisited cell can hold a closer point); then, with ``whole``,
    every target point of the region. inf where none is found."""
    out = np.empty(points.shape[0])
    for i in prange(points.shape[0]):
        best = _neighbours(i, points, cell, origin, target, start, table, m, span, eps, same)
        r = 1
        while best > (r * eps) ** 2 and r < rings:
            r += 1
            best = _ring(i, r, points, cell, target, start, table, m, span, same, best)
        if whole and best > (r * eps) ** 2:
            for t in range(region_start[region[i]], region_start[region[i] + 1]):
                if not (same and t == i):
                    best = min(best, _distance2(points, i, target, t))
        out[i] = np.sqrt(best)
    return out


@njit(cache=True)
def _neighbours(i, points, cell, origin, target, start, table, m, span, eps, same):
    """Squared distance from point ``i`` to its nearest target point in its own cell or in a
    neighbouring cell of its region (Chebyshev distance 1) that could hold a closer one."""
    l0, l1, l2 = cell[i, 0] % m, cell[i, 1] % m, cell[i, 2] % m
    o0 = points[i, 0] - (origin[0] + cell[i, 0] * eps)  # offsets inside the cell
    o1 = points[i, 1] - (origin[1] + cell[i, 1] * eps)
    o2 = points[i, 2] - (origin[2] + cell[i, 2] * eps)
    region_key = ((cell[i, 0] // m) * span[1] + cell[i, 1] // m) * span[2] + cell[i, 2] // m
    home = region_key * m * m * m + (l0 * m + l1) * m + l2
    best = _scan(i, _lookup(table, home), points, target, start, same, np.inf)
    for dx in range(max(-1, -l0), min(1, m - 1 - l0) + 1):
        for dy in range(max(-1, -l1), min(1, m - 1 - l1) + 1):
            for dz in range(max(-1, -l2), min(1, m - 1 - l2) + 1):
                near = _gap2(o0, dx, eps) + _gap2(o1, dy, eps) + _gap2(o2, dz, eps)
                if (dx == 0 and dy == 0 and dz == 0) or near >= best:
                    continue
                c = _lookup(table, home + (dx * m + dy) * m + dz)
                best = _scan(i, c, points, target, start, same, best)
    return best


@njit(cache=True)
def _gap2(offset, side, eps):
    """Squared distance along one axis from a point ``offset`` into its cell to the neighbouring
    cell on ``side`` (-1, 0, 1)."""
    if side < 0:
        return offset * offset
    if side > 0:
        return (eps - offset) * (eps - offset)
    return 0.0


@njit(cache=True)
def _scan(i, c, points, target, start, same, best):
    """``best`` lowered by the squared distances from point ``i`` to the target points of cell
    number ``c`` (none if ``c`` < 0)."""
    if c < 0:
        return best
    for t in range(start[c], start[c + 1]):
        if not (same and t == i):
            best = min(best, _distance2(points, i, target, t))
    return best


@njit(cache=True)
def _ring(i, r, points, cell, target, start, table, m, span, same, best):
    """``best`` lowered by the target points in the cells at Chebyshev distance ``r`` from point
    ``i``'s cell, inside its region."""
    l0, l1, l2 = cell[i, 0] % m, cell[i, 1] % m, cell[i, 2] % m
    region_key = ((cell[i, 0] // m) * span[1] + cell[i, 1] // m) * span[2] + cell[i, 2] // m
    for dx in range(max(-r, -l0), min(r, m - 1 - l0) + 1):
        for dy in range(max(-r, -l1), min(r, m - 1 - l1) + 1):
            for dz in range(max(-r, -l2), min(r, m - 1 - l2) + 1):
                if max(abs(dx), abs(dy), abs(dz)) != r:
                    continue
                key = region_key * m * m * m + ((l0 + dx) * m + l1 + dy) * m + l2 + dz
                best = _scan(i, _lookup(table, key), points, target, start, same, best)
    return best


@njit(cache=True)
def _distance2(points, i, target, t):
    dx = points[i, 0] - target[t, 0]
    dy = points[i, 1] - target[t, 1]
    dz = points[i, 2] - target[t, 2]
    return dx * dx + dy * dy + dz * dz


def _tree(points: FloatArray) -> cKDTree:
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def _grid_order(points: FloatArray, cell_m: float) -> IntArray:
    """Permutation sorting ``points`` by their cell of a ``cell_m`` grid (C order)."""
    cells = np.floor((points - points.min(axis=0)) / cell_m).astype(np.int64)
    span = cells.max(axis=0) + 1
    return np.argsort((cells[:, 0] * span[1] + cells[:, 1]) * span[2] + cells[:, 2], kind="stable")


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


def _region_cell_scores(lattice: _Lattice) -> tuple[FloatArray, FloatArray]:
    """Per-region (q_c, q_t): the cell scores restricted to each region's cells."""
    count, m3 = len(lattice), lattice.m**3
    cells_a, cells_b = lattice.a.cells, lattice.b.cells
    region_a = np.searchsorted(lattice.region_keys, cells_a // m3)
    region_b = np.searchsorted(lattice.region_keys, cells_b // m3)
    shared = np.bincount(region_a[_members(cells_a, cells_b)], minlength=count)
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
