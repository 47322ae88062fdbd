"""The WD_occ paper's study (*Measuring 3D-reconstruction quality in probabilistic volumetric maps with the Wasserstein Distance*, §III-C, §IV-C): is WD_occ meaningful, informative and robust?

Three parts, each on U_occ cuboids of ``10 × 10 × 10`` voxels (RES = 10 · res, as the paper):

1. **Ideal vs random** (Fig. 2): ``cuboids`` U_occ cuboids are drawn per world; each is
   reconstructed "ideally" — the ground truth blurred by a Gaussian, then uniform noise (levels b1, b2,
   b3 of :data:`~nbv_gym.metrics.wasserstein.PAPER_BLUR_LEVELS`, the operator
   :func:`~nbv_gym.metrics.wasserstein.blurred_reconstruction`) — and randomly (p ~ U(0, 1) per
   voxel), and scored with WD_occ and cov. The limit WD*_occ of a world is the mean WD_occ of its
   random reconstructions.
2. **Informative share** (Fig. 4): on maps of exploration runs, the share of observed U_occ cuboids
   on which each metric carries information — cov > 0, WD_occ < WD*_occ (the world's limit at that
   resolution) — per world, noise level and map resolution.
3. **Robustness** (Table II): Δ_k = (μ_bk − μ_b1) / μ_b1, with μ_b the mean over a world type's
   worlds of the median of a metric over that world's cuboids, for WD_occ and cov.

Everything random flows from one seed through keyed :class:`numpy.random.Generator` s, so a study is
reproducible part by part. The metrics are :mod:`nbv_gym.metrics`' own.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import BoolArray, FloatArray, IntArray
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.grid import GridSpec, float_triple
from nbv_gym.metrics.cuboids import (
    COV_SETTINGS,
    CuboidConfig,
    benchmark_grid,
    cuboid_view,
    occupied_cuboids,
)
from nbv_gym.metrics.tracker import QualityTracker, evaluate_cuboids
from nbv_gym.metrics.wasserstein import (
    PAPER_BLUR_LEVELS,
    blurred_reconstruction,
    random_reconstruction,
    wd_occ_cuboids,
)
from nbv_gym.studies import StudyError

RANDOM = "random"
#: The reconstructions of part 1, in order: the paper's three ideal levels, then random.
RECONSTRUCTIONS = (*PAPER_BLUR_LEVELS, RANDOM)
#: Table II of *Measuring 3D-reconstruction quality in probabilistic volumetric maps with the Wasserstein Distance*: world type → (Δ_2, Δ_3) of the median WD_occ, percent. The paper's
#: structured worlds hold cuboids and its unstructured worlds trees.
PAPER_TABLE_II = {"cuboids": (1.21, 3.93), "trees": (1.65, 6.20)}
PAPER_WORLD_TYPES = {"cuboids": "structured", "trees": "unstructured"}


def keyed_seed(seed: int, *key: object) -> int:
    """A 63-bit seed: SHA-256 of ``seed`` and ``key`` (one independent stream per purpose)."""
    text = "/".join(str(k) for k in (seed, *key))
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big") >> 1


def keyed_rng(seed: int, *key: object) -> np.random.Generator:
    """A generator seeded with :func:`keyed_seed`."""
    return np.random.default_rng(keyed_seed(seed, *key))


# -- grids and ground truth ------------------------------------------------------------------------


def study_grid(resolution_m: float) -> GridSpec:
    """The benchmark's comparison box (G's extent) at ``resolution_m``; whole 10-voxel cuboids."""
    box = benchmark_grid()
    low, high = float_triple(box.low), float_triple(box.high)
    try:
        grid = GridSpec.from_bounds(low, high, resolution_m)
    except ConfigError:
        grid = None
    if grid is None or any(s % 10 for s in grid.shape):
        raise StudyError(
            f"resolution {resolution_m} m does not cut the comparison box {low}–{high} into "
            "whole 10-voxel cuboids; use for instance 0.1 or 0.05"
        )
    return grid


def cuboid_config(resolution_m: float) -> CuboidConfig:
    """Cuboids of 10 voxels of ``resolution_m`` (RES = 10 · res, the paper's choice)."""
    return CuboidConfig(cuboid_voxels=10, resolution_m=resolution_m)


def ground_truth(world, resolution_m: float) -> BoolArray:
    """(X, Y, Z) bool ground truth of ``world`` on :func:`study_grid`: its cached voxels at their
    own resolution, else its asset surfaces voxelised at ``resolution_m``."""
    from nbv_gym.worlds import surface_voxels

    truth = world.ground_truth
    if not np.isclose(truth.res, resolution_m):
        faces = world.faces[: world.asset_faces]
        truth = surface_voxels(world.vertices.astype(np.float64), faces, resolution_m)
    return truth.occupancy(study_grid(resolution_m))


def sample_cuboids(candidates: BoolArray, count: int, rng: np.random.Generator) -> IntArray:
    """(k, 3) int64 indices of ``min(count, candidates.sum())`` cuboids drawn without replacement
    among the True cells of ``candidates`` (cx, cy, cz), in C order."""
    index = np.argwhere(candidates)
    if len(index) > count:
        index = index[np.sort(rng.choice(len(index), size=count, replace=False))]
    return index.astype(np.int64)


# -- part 1: ideal and random reconstructions --------------------------------------------------------


def reconstruct(truth: BoolArray, name: str, rng: np.random.Generator) -> FloatArray:
    """(B, n, n, n) float reconstruction ``name`` (b1, b2, b3 or random) of (B, n, n, n) ``truth``."""
    if name == RANDOM:
        return random_reconstruction(truth.shape, rng)
    return blurred_reconstruction(truth, *PAPER_BLUR_LEVELS[name], rng)


def cuboid_scores(
    truth_grid: BoolArray, index: IntArray, blocks: FloatArray, config: CuboidConfig
) -> tuple[FloatArray, FloatArray]:
    """WD_occ (B,) and cov (s, B) of the (B, n, n, n) probability ``blocks`` standing at cuboids
    ``index`` (B, 3) of the ground truth ``truth_grid`` (X, Y, Z) bool."""
    n = config.cuboid_voxels
    truth = cuboid_view(truth_grid, n)[tuple(index.T)]
    wd = wd_occ_cuboids(blocks, truth)
    tracker = QualityTracker(truth_grid, config)
    tracker.update_blocks(np.ravel_multi_index(tuple(index.T), tracker.shape), blocks)
    return wd, tracker.metrics().cov[:, index[:, 0], index[:, 1], index[:, 2]]


@dataclass(frozen=True)
class IdealResult:
    """Part 1 on one world: ``index`` (B, 3) the drawn cuboids; ``wd`` and ``cov`` map each of
    :data:`RECONSTRUCTIONS` to WD_occ (B,) and cov (s, B)."""

    world: str
    asset: str
    index: IntArray
    wd: dict[str, FloatArray]
    cov: dict[str, FloatArray]

    @property
    def wd_star(self) -> float:
        """WD*_occ: the mean WD_occ of the random reconstructions."""
        return wd_limit(self.wd[RANDOM])

    def medians(self) -> dict[str, dict[str, float]]:
        """Reconstruction → {"wd_occ": median, "cov_<k>": median per cov setting}."""
        return {
            name: {"wd_occ": float(np.median(self.wd[name]))}
            | {f"cov_{k + 1}": float(np.median(c)) for k, c in enumerate(self.cov[name])}
            for name in RECONSTRUCTIONS
        }


def ideal_study(world, truth_grid: BoolArray, count: int, seed: int, on_step=None) -> IdealResult:
    """Part 1 on ``world`` with ground truth ``truth_grid`` (0.1 m, :func:`study_grid`):
    ``count`` U_occ cuboids, each reconstruction with its own keyed generator."""
    from nbv_gym.worlds.spec import asset_type

    config = cuboid_config(world.ground_truth.res)
    u_occ = occupied_cuboids(truth_grid, config.cuboid_voxels)
    if not u_occ.any():
        raise StudyError(f"world {world.name} has no occupied cuboid in the comparison box")
    index = sample_cuboids(u_occ, count, keyed_rng(seed, world.name, "cuboids"))
    truth = cuboid_view(truth_grid, config.cuboid_voxels)[tuple(index.T)]
    wd, cov = {}, {}
    for name in RECONSTRUCTIONS:
        blocks = reconstruct(truth, name, keyed_rng(seed, world.name, name))
        wd[name], cov[name] = cuboid_scores(truth_grid, index, blocks, config)
        if on_step:
            on_step(f"{world.name} {name}")
    return IdealResult(world.name, asset_type(world.spec), index, wd, cov)


def wd_limit(random_wd: FloatArray) -> float:
    """WD*_occ: the mean of the WD_occ values of random reconstructions (paper §III-C)."""
    random_wd = np.asarray(random_wd, float)
    if random_wd.size == 0:
        raise StudyError("WD*_occ needs at least one random reconstruction")
    return float(random_wd.mean())


def random_limit(truth_grid: BoolArray, resolution_m: float, count: int, rng) -> tuple[float, int]:
    """(WD*_occ, cuboids used) of a ground truth (X, Y, Z) bool at ``resolution_m``: the mean
    WD_occ of random reconstructions of ``count`` of its U_occ cuboids."""
    n = cuboid_config(resolution_m).cuboid_voxels
    index = sample_cuboids(occupied_cuboids(truth_grid, n), count, rng)
    truth = cuboid_view(truth_grid, n)[tuple(index.T)]
    return wd_limit(wd_occ_cuboids(random_reconstruction(truth.shape, rng), truth)), len(index)


# -- part 3: robustness --------------------------------------------------------------------------------


def deltas(mu: dict[str, float]) -> dict[str, float]:
    """Δ_k = (μ_bk − μ_b1) / μ_b1 for every level k after b1 of ``mu`` (level → μ_b)."""
    base = mu["b1"]
    if base == 0:
        return {k: float("nan") for k in mu if k != "b1"}
    return {k: (v - base) / base for k, v in mu.items() if k != "b1"}


def mean_medians(medians: list[dict[str, float]]) -> dict[str, float]:
    """μ_b: level → mean over experiments of that level's median (``medians``: one dict per world)."""
    return {level: float(np.mean([m[level] for m in medians])) for level in medians[0]}


# -- part 2: informative share ---------------------------------------------------------------------------


def informative(cov: FloatArray, wd: FloatArray, wd_star: float) -> tuple[BoolArray, BoolArray]:
    """The paper's rule: cov (s, B) is informative where cov > 0; WD_occ (B,) where WD_occ < WD*_occ."""
    return np.asarray(cov) > 0, np.asarray(wd) < wd_star


@dataclass(frozen=True)
class MapShare:
    """Informative shares of one map: ``n_u_occ`` U_occ cuboids of which ``n_observed`` observed and
    ``n_sampled`` drawn among those; ``share_wd`` and ``share_cov`` (s,) over the drawn cuboids."""

    n_u_occ: int
    n_observed: int
    n_sampled: int
    share_wd: float
    share_cov: tuple[float, ...]

    @property
    def observed_fraction(self) -> float:
        """Observed U_occ / U_occ: multiply a share by it for the share over all of U_occ (an
        unobserved cuboid has cov = 0 and WD_occ = 100, informative for neither metric)."""
        return self.n_observed / self.n_u_occ if self.n_u_occ else float("nan")


def map_share(
    prob: FloatArray, truth_grid: BoolArray, resolution_m: float, wd_star: float, count: int, rng
) -> MapShare:
    """Informative shares of the probability grid ``prob`` (X, Y, Z) against ``truth_grid`` (same
    shape, bool) at ``resolution_m``, on ``count`` observed U_occ cuboids drawn with ``rng``."""
    config = cuboid_config(resolution_m)
    if wd_star >= config.unobserved_wd:
        raise StudyError(f"WD*_occ {wd_star:.3g} is not below the unobserved WD_occ value")
    metrics = evaluate_cuboids(prob, truth_grid, config)
    candidates = metrics.u_occ & metrics.observed
    index = sample_cuboids(candidates, count, rng)
    n = config.cuboid_voxels
    wd = wd_occ_cuboids(
        cuboid_view(prob, n)[tuple(index.T)], cuboid_view(truth_grid, n)[tuple(index.T)]
    )
    cov_info, wd_info = informative(
        metrics.cov[:, index[:, 0], index[:, 1], index[:, 2]], wd, wd_star
    )
    shares = tuple(float(c.mean()) if len(index) else float("nan") for c in cov_info)
    return MapShare(
        int(metrics.u_occ.sum()),
        int(candidates.sum()),
        len(index),
        float(wd_info.mean()) if len(index) else float("nan"),
        shares,
    )


COV_LABELS = tuple(f"cov{k + 1} (p {p}, d {d} m)" for k, (p, d) in enumerate(COV_SETTINGS))
