"""The foundation suite of ``nbv-gym bench``: world build and cache load, our scan against raw
Embree."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from nbv_gym.perf import PERF_WORLD, Progress

SCANS = 200


def run(progress: Progress) -> dict[str, float]:
    """The foundation suite: world build and cache load, our scan vs raw Embree."""
    from nbv_gym.worlds import load_spec
    from nbv_gym.worlds.world import build_world, load_world

    spec = load_spec(PERF_WORLD)
    _warm_up_compiled_code()
    progress(f"building {PERF_WORLD} uncached (mesh + ground truth)")
    build_s = _seconds(lambda: build_world(spec))
    load_world(spec)
    load_s = _seconds(lambda: load_world(spec))
    world = load_world(spec)
    progress(f"{SCANS} scans on {PERF_WORLD} ({len(world.faces)} triangles)")
    scan_rate, embree_rate = _scan_rates(world)
    return {
        "world_build_s": build_s,
        "world_load_s": load_s,
        "scan_rays_per_s": scan_rate,
        "embree_rays_per_s": embree_rate,
    }


def _scan_rates(world) -> tuple[float, float]:
    from nbv_gym.core.pose import Pose
    from nbv_gym.sensor.lidar import Lidar

    lidar = Lidar.for_world(world, noise=1)
    rng = np.random.default_rng(0)
    poses = [
        Pose(x, y, 0.0, yaw) for x, y, yaw in rng.uniform([-25, -25, 0], [25, 25, 6], (SCANS, 3))
    ]
    lidar.scan(Pose(0.0, 0.0, 0.0), rng)  # builds the Embree scene (a pose not timed: the
    # first pose's cast is kept for resets)
    scan_s = _seconds(lambda: [lidar.scan(pose, rng) for pose in poses])
    rays = [
        (
            np.broadcast_to(lidar.sensor_pose(p).position, lidar.directions.shape).astype(
                np.float32
            ),
            (lidar.directions @ lidar.sensor_pose(p).rotation().T).astype(np.float32),
        )
        for p in poses
    ]
    scene = world.ray_scene()._scene
    embree_s = _seconds(lambda: [scene.run(o, d, output=1) for o, d in rays])
    n_rays = SCANS * len(lidar.directions)
    return n_rays / scan_s, n_rays / embree_s


def _warm_up_compiled_code() -> None:
    from nbv_gym.worlds import shapes, surface_voxels

    surface_voxels(*shapes.cuboid(), 0.1)


def _seconds(work: Callable[[], object]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start
