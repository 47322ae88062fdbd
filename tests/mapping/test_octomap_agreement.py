"""Our map against OctoMap itself (pyoctomap) on the same synthetic lidar scans.

The few voxels that differ (≈ 0.1 % here, 2 in 10⁶ on pp1-trees) are free in one map and unknown in
the other: noise-free returns on the ground lie exactly on the voxel border z = 0, where OctoMap's
float32 DDA and our float64 one break the tie differently near the end of the ray.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from nbv_gym.core.pose import Pose
from nbv_gym.mapping import MapConfig, OccupancyMap
from nbv_gym.perf.mapping import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    octomap_insert,
    octomap_states,
    our_states,
    synthetic_lidar,
)

pyoctomap = pytest.importorskip("pyoctomap")


def test_voxel_states_agree_with_octomap_on_synthetic_scans():
    lidar = synthetic_lidar(seed=1, n_azimuth=256)
    rng = np.random.default_rng(0)
    poses = [Pose(0.0, 0.0, 0.0, 0.0), Pose(1.5, -1.0, 0.0, 1.0)]
    # round to float32 as OctoMap stores points, so both maps see the same coordinates
    scans = [
        replace(s, points_map=s.points_map.astype(np.float32).astype(float))
        for s in (lidar.scan(pose, rng) for pose in poses)
    ]
    occupancy = OccupancyMap.from_config(MapConfig(), max_range_m=20.0)
    for scan in scans:
        occupancy.insert(scan.origin, scan.points_map)
    tree, _ = octomap_insert(scans, occupancy.params, occupancy.grid.res)
    ours, theirs = our_states(occupancy), octomap_states(tree, occupancy.grid)
    scanned = (ours != UNKNOWN) | (theirs != UNKNOWN)
    assert scanned.sum() > 100_000
    assert np.mean(ours[scanned] == theirs[scanned]) >= 0.99
    # the occupied voxels are the returns' voxels in both
    assert (ours == OCCUPIED).sum() == pytest.approx((theirs == OCCUPIED).sum(), rel=0.01)
    assert (ours == FREE).sum() == pytest.approx((theirs == FREE).sum(), rel=0.01)
