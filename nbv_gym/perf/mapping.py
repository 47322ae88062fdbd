"""Throughput of the mapping step, and agreement of our map with OctoMap itself (via pyoctomap).

Keys of :func:`run`:
- ``map_points_per_s``: returns per second inserted into our map (single thread, compile excluded).
- ``octomap_points_per_s``: the same scans inserted by OctoMap (pyoctomap's ``insertPointCloud``,
  same resolution, sensor model and max range; lazy evaluation with one ``updateInnerOccupancy``
  at the end, timed, which is OctoMap's fastest way).
- ``map_agreement``: share of the voxels known in either map whose state (unknown, free, occupied)
  is the same in both.
- ``stats_update_ms``, ``nav_update_ms``: mean time per scan of the statistics and navigation
  updates at the benchmark's default sizes.

Scans come from ``pp1-trees`` when the worlds can be built, otherwise from a small synthetic scene.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import cast

import numpy as np

from nbv_gym.core.errors import MissingExtraError
from nbv_gym.core.grid import GridSpec
from nbv_gym.core.pose import LocalisationNoise, Pose
from nbv_gym.mapping.occupancy import OccupancyMap
from nbv_gym.mapping.state import ExplorationState, MappingConfig
from nbv_gym.sensor.lidar import Lidar, LidarConfig, Scan
from nbv_gym.worlds.raycast import RayScene

#: Robot ground poses (x, y, yaw) of the perf scans: a short walk around the start.
PERF_POSES = ((0.0, 0.0, 0.0), (2.0, 0.0, 0.5), (4.0, 1.0, 1.0), (3.0, 3.0, 1.5), (0.0, 3.0, 2.0),
               (-2.0, 2.0, 2.5), (-3.0, 0.0, 3.0), (-2.0, -2.0, 3.5))  # fmt: skip

UNKNOWN, FREE, OCCUPIED = np.int8(-1), np.int8(0), np.int8(1)


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Measure the five mapping perf keys; progress messages go to ``progress``."""
    config = MappingConfig()
    scans = perf_scans(progress)
    n_points = sum(len(s) for s in scans)
    progress(f"{len(scans)} scans, {n_points} returns")
    state = ExplorationState.from_config(config)
    _warm_up(config)
    progress("inserting into our map")
    map_s = _time_each(lambda s: state.occupancy.insert(s.origin, s.points_map), scans)
    progress("inserting into OctoMap (pyoctomap)")
    tree, octomap_s = octomap_insert(scans, state.occupancy.params, state.occupancy.grid.res)
    progress("comparing voxel states")
    agreement = map_agreement(state.occupancy, tree)
    stats_s = _time_each(lambda s: state.statistics.update(s.origin, s.points_map), scans)
    nav_s = _time_each(lambda s: state.update_navigation(s.origin[:2]), scans)
    return {
        "map_points_per_s": n_points / sum(map_s),
        "octomap_points_per_s": n_points / octomap_s,
        "map_agreement": agreement,
        "stats_update_ms": 1e3 * float(np.mean(stats_s)),
        "nav_update_ms": 1e3 * float(np.mean(nav_s)),
    }


def perf_scans(progress: Callable[[str], None], n_scans: int = len(PERF_POSES)) -> list[Scan]:
    """Scans of ``pp1-trees`` from :data:`PERF_POSES` (noise level 1, seeded), or of the synthetic
    scene if the worlds are not available."""
    try:
        from nbv_gym.worlds import load_world

        progress("loading pp1-trees")
        lidar = Lidar.for_world(load_world("pp1-trees"), LidarConfig(), noise=1)
    except ImportError:
        progress("nbv_gym.worlds unavailable: using the synthetic scene")
        lidar = synthetic_lidar()
    rng = np.random.default_rng(0)
    return [lidar.scan(Pose(x, y, 0.0, yaw), rng) for x, y, yaw in PERF_POSES[:n_scans]]


def synthetic_lidar(seed: int = 0, n_azimuth: int = 512) -> Lidar:
    """The default lidar without noise in a small scene: a 64 m ground plane, 30 boxes and 30 thin
    cylinders (0.1–0.4 m radius) placed uniformly at 3–25 m from the origin."""
    import trimesh

    rng = np.random.default_rng(seed)
    parts = [
        trimesh.creation.box(
            (64.0, 64.0, 0.02), trimesh.transformations.translation_matrix((0, 0, -0.01))
        )
    ]
    for k in range(60):
        r, phi = rng.uniform(3.0, 25.0), rng.uniform(0, 2 * np.pi)
        height = rng.uniform(1.0, 6.0)
        at = trimesh.transformations.translation_matrix(
            (r * np.cos(phi), r * np.sin(phi), height / 2)
        )
        if k % 2:
            size = rng.uniform(0.5, 2.5, 2)
            parts.append(trimesh.creation.box((*size, height), at))
        else:
            parts.append(trimesh.creation.cylinder(rng.uniform(0.1, 0.4), height, transform=at))
    mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(parts))  # meshes join into one mesh
    lidar = LidarConfig(n_azimuth=n_azimuth)
    return Lidar(RayScene(mesh.vertices, mesh.faces), lidar.directions(), lidar.mount_height_m,
                 lidar.min_range_m, lidar.min_horizontal_m, None, LocalisationNoise())  # fmt: skip


def octomap_insert(scans: Sequence[Scan], params: dict[str, float], resolution_m: float):
    """An OctoMap ``OcTree`` with ``scans`` inserted as our map would, and the seconds it took."""
    try:
        import pyoctomap
    except ImportError as error:
        raise MissingExtraError("pyoctomap", "octomap") from error
    tree = pyoctomap.OcTree(resolution_m)
    tree.setProbHit(params["p_hit"])
    tree.setProbMiss(params["p_miss"])
    tree.setClampingThresMin(params["p_clamp_min"])
    tree.setClampingThresMax(params["p_clamp_max"])
    tree.setOccupancyThres(params["p_occupied"])
    clouds = [(np.ascontiguousarray(s.points_map, np.float64), np.asarray(s.origin, np.float64))
              for s in scans]  # fmt: skip
    start = time.perf_counter()
    for points, origin in clouds:
        tree.insertPointCloud(points, origin, max_range=params["max_range_m"], lazy_eval=True)
    tree.updateInnerOccupancy()
    return tree, time.perf_counter() - start


def octomap_states(tree, grid: GridSpec) -> np.ndarray:
    """int8 state (−1 unknown, 0 free, 1 occupied) over ``grid`` (the tree's resolution, aligned)
    of every OctoMap leaf; pruned leaves fill all the voxels they cover."""
    rows = [(*it.getCoordinate(), it.getSize(), it.current_node.getLogOdds())
            for it in tree.begin_leafs()]  # fmt: skip
    leaves = np.array(rows, dtype=np.float64).reshape(-1, 5)
    occupied = leaves[:, 4] >= tree.getOccupancyThresLog()
    n = np.rint(leaves[:, 3] / grid.res).astype(np.int64)
    low = np.rint((leaves[:, :3] - leaves[:, 3:4] / 2 - grid.low) / grid.res).astype(np.int64)
    states = np.full(grid.shape, UNKNOWN, np.int8)
    single = n == 1
    inside = grid.contains(low) & single
    states[tuple(low[inside].T)] = np.where(occupied[inside], OCCUPIED, FREE)
    for k in np.flatnonzero(~single):
        a, b = np.maximum(low[k], 0), np.minimum(low[k] + n[k], grid.shape)
        if np.all(b > a):
            states[a[0] : b[0], a[1] : b[1], a[2] : b[2]] = OCCUPIED if occupied[k] else FREE
    return states


def our_states(occupancy: OccupancyMap) -> np.ndarray:
    """int8 state (−1 unknown, 0 free, 1 occupied) over the map's grid."""
    lo = occupancy.logodds
    states = np.where(lo >= occupancy.occupied_logodds, OCCUPIED, FREE).astype(np.int8)
    states[np.isnan(lo)] = UNKNOWN
    return states


def map_agreement(occupancy: OccupancyMap, tree) -> float:
    """Share of the voxels known in our map or in OctoMap's whose states are equal."""
    ours = our_states(occupancy)
    theirs = octomap_states(tree, occupancy.grid)
    scanned = (ours != UNKNOWN) | (theirs != UNKNOWN)
    return float(np.mean(ours[scanned] == theirs[scanned]))


def _warm_up(config: MappingConfig) -> None:
    """Compile the numba kernels on a tiny state so that timings exclude compilation."""
    small_map = replace(config.map, low_m=(-4.0, -4.0, -1.0), high_m=(4.0, 4.0, 2.0))
    small_stats = replace(config.statistics, low_m=(-3.0, -3.0, 0.2), high_m=(3.0, 3.0, 1.2))
    small = ExplorationState.from_config(replace(config, map=small_map, statistics=small_stats))
    origin = np.array([0.0, 0.0, LidarConfig.mount_height_m])
    small.statistics.update(origin, np.array([[3.0, 1.0, 1.0]]))
    small.occupancy.insert(origin, np.array([[3.0, 1.0, 1.0]]))
    small.update_navigation(origin[:2])


def _time_each(step: Callable[[Scan], object], scans: Sequence[Scan]) -> list[float]:
    """Seconds ``step`` took on each scan."""
    seconds = []
    for scan in scans:
        start = time.perf_counter()
        step(scan)
        seconds.append(time.perf_counter() - start)
    return seconds
