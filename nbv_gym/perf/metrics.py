"""Throughput of the metrics (``nbv-gym bench``): incremental Q, WD_occ vs POT, Empir3D vs Chamfer.

Keys: ``q_update_ms`` (incremental Q after one lidar scan's touched cuboids on ``pp1-trees``,
given their probabilities), ``q_map_read_ms`` (reading those probabilities from the map),
``wd_cuboid_ms`` (our batched WD_occ, per cuboid), ``pot_wd_cuboid_ms`` (POT's dense
``ot.sinkhorn2`` on the same cuboids), ``empir3d_s`` (the four Empir3D scores) and ``chamfer_s``
(a plain cKDTree Chamfer distance) on the same two clouds of 10⁶ points (the paper claims Empir3D
is at least twice as fast as Chamfer: ``empir3d_s ≤ 0.5 chamfer_s``).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from nbv_gym.perf import PERF_WORLD

SCANS = 10
WD_CUBOIDS = 64
POT_CUBOIDS = 4
CLOUD_POINTS = 1_000_000


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """The metrics suite; see the module docstring for the keys."""
    from nbv_gym.metrics.cuboids import benchmark_grid
    from nbv_gym.worlds import load_world

    world = load_world(PERF_WORLD)
    grid = benchmark_grid()
    truth = world.ground_truth.occupancy(grid)
    progress(f"incremental Q: {SCANS} scans on {PERF_WORLD}")
    results = _q_update_ms(world, truth, grid)
    progress(f"WD_occ: {WD_CUBOIDS} cuboids batched vs POT on {POT_CUBOIDS}")
    results.update(_wd_ms(truth))
    progress(f"Empir3D vs Chamfer on two clouds of {CLOUD_POINTS} points")
    results.update(_empir3d_s(world))
    return results


def _q_update_ms(world, truth, grid) -> dict[str, float]:
    """Median times of one incremental update as the environment runs it: ``q_map_read_ms``
    reads the touched cuboids' probabilities from the map, ``q_update_ms`` recomputes their
    metrics and summarises."""
    from nbv_gym.core.grid import GridSpec
    from nbv_gym.core.pose import Pose
    from nbv_gym.mapping import MapConfig, OccupancyMap
    from nbv_gym.metrics.tracker import QualityTracker
    from nbv_gym.sensor.lidar import Lidar

    rng = np.random.default_rng(0)
    occupancy = OccupancyMap.from_config(MapConfig(), 20.0)
    cuboids = GridSpec(grid.origin, grid.res * 10, tuple(s // 10 for s in grid.shape))
    tracker = QualityTracker(truth)
    lidar = Lidar.for_world(world, noise=1)
    read, update = [], []
    for x, y, yaw in rng.uniform([-15, -15, 0], [15, 15, 6], (SCANS, 3)):
        scan = lidar.scan(Pose(x, y, 0.0, yaw), rng)
        touched = occupancy.insert(scan.origin, scan.points_map, cuboids).touched
        flat = np.flatnonzero(touched)
        start = time.perf_counter()
        blocks = occupancy.probability_blocks(cuboids, cuboids.unravel(flat))
        middle = time.perf_counter()
        tracker.update_blocks(flat, blocks)
        read.append(middle - start)
        update.append(time.perf_counter() - middle)
    return {
        "q_update_ms": 1e3 * float(np.median(update)),
        "q_map_read_ms": 1e3 * float(np.median(read)),
    }


def touched_cuboids(
    origin: np.ndarray, points: np.ndarray, grid, step_m: float = 0.25
) -> np.ndarray:
    """(m, 3) int64 unique cuboid indices (1 m cells of ``grid``) along the rays origin → points."""
    cuboid = grid.res * 10
    t = np.arange(0.0, 1.0 + 1e-9, step_m / 20.0)
    samples = origin + (points - origin)[:, None, :] * t[None, :, None]
    index = np.floor((samples.reshape(-1, 3) - grid.low) / cuboid).astype(np.int64)
    shape = np.asarray(grid.shape) // 10
    inside = np.all((index >= 0) & (index < shape), axis=1)
    return np.unique(index[inside], axis=0)


def _wd_ms(truth) -> dict[str, float]:
    from nbv_gym.metrics.cuboids import cuboid_view, occupied_cuboids
    from nbv_gym.metrics.wasserstein import pot_wd_occ, wd_occ_cuboids

    rng = np.random.default_rng(1)
    occupied = np.argwhere(occupied_cuboids(truth, 10))[:WD_CUBOIDS]
    gt = cuboid_view(truth, 10)[tuple(occupied.T)].astype(np.float64)
    rec = np.clip(gt * 0.8 + rng.uniform(0.0, 0.4, gt.shape), 0.0, 1.0)  # a noisy reconstruction
    wd_occ_cuboids(rec[:1], gt[:1])  # compile
    ours = _seconds(lambda: wd_occ_cuboids(rec, gt)) / len(gt)
    pot = _seconds(
        lambda: [pot_wd_occ(r, g) for r, g in zip(rec[:POT_CUBOIDS], gt[:POT_CUBOIDS], strict=True)]
    )
    return {"wd_cuboid_ms": 1e3 * ours, "pot_wd_cuboid_ms": 1e3 * pot / POT_CUBOIDS}


def _empir3d_s(world) -> dict[str, float]:
    from nbv_gym.metrics.empir3d import empir3d

    rng = np.random.default_rng(2)
    reference = surface_points(world, CLOUD_POINTS, rng)
    candidate = reference + rng.normal(0.0, 0.01, reference.shape)
    empir3d(reference[:1000], candidate[:1000])
    return {
        "empir3d_s": _seconds(lambda: empir3d(reference, candidate)),
        "chamfer_s": _seconds(lambda: plain_chamfer(reference, candidate)),
    }


def surface_points(world, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 3) points sampled uniformly (by area) on the world's asset surfaces, in random order."""
    vertices = np.asarray(world.vertices, float)
    faces = np.asarray(world.faces)[: world.asset_faces]
    corners = vertices[faces]
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    chosen = rng.choice(len(faces), size=count, p=area / area.sum())
    u, v = rng.random((2, count))
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    c = corners[chosen]
    return c[:, 0] + u[:, None] * (c[:, 1] - c[:, 0]) + v[:, None] * (c[:, 2] - c[:, 0])


def plain_chamfer(a: np.ndarray, b: np.ndarray, workers: int = -1) -> float:
    """The Chamfer distance of :mod:`nbv_gym.metrics.empir3d` (the symmetric mean of eq. (1) of
    *Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment*) the usual way: two default cKDTrees, two nearest-neighbour queries."""
    from scipy.spatial import cKDTree

    return 0.5 * float(
        cKDTree(b).query(a, workers=workers)[0].mean()
        + cKDTree(a).query(b, workers=workers)[0].mean()
    )


def _seconds(work: Callable[[], object]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start
