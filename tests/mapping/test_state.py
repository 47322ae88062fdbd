"""The exploration state: one scan updates map, statistics and navigation together."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, PoseError
from nbv_gym.core.pose import Pose
from nbv_gym.mapping import (
    ExplorationState,
    MapConfig,
    MappingConfig,
    NavigationConfig,
    StatisticsConfig,
)
from nbv_gym.sensor.lidar import Scan

SMALL = MappingConfig(
    map=MapConfig(low_m=(-8.0, -8.0, -1.0), high_m=(8.0, 8.0, 3.0)),
    statistics=StatisticsConfig(low_m=(-6.0, -6.0, 0.2), high_m=(6.0, 6.0, 2.2)),
    navigation=NavigationConfig(),
)


SENSOR = Pose(0.05, 0.05, 0.45)


def scan_from(points_map, pose: Pose = SENSOR) -> Scan:
    points_map = np.asarray(points_map, float)
    n = len(points_map)
    return Scan(points_map - pose.position, np.linalg.norm(points_map - pose.position, axis=1),
                np.arange(n), pose, pose, points_map)  # fmt: skip


def test_config_defaults_and_box_check():
    config = MappingConfig()
    assert config.sensor_range_m == 20.0
    with pytest.raises(ConfigError, match="inside the map box"):
        MappingConfig(statistics=StatisticsConfig(low_m=(-40.0, -30.0, 0.2), high_m=(20, 30, 6.2)))


def test_apply_updates_map_statistics_and_navigation():
    state = ExplorationState.from_config(SMALL)
    # a wall of returns 3 m east of the sensor, at z = 0.45 m
    ys = np.linspace(-1.0, 1.0, 21)
    update = state.apply(scan_from(np.column_stack([np.full(21, 3.05), ys, np.full(21, 0.45)])))
    assert update.n_points == 21 and update.n_dropped == 0
    # map voxels changed between x = 0 and 3.1 m, y in [-1, 1], z = 0.4–0.5: G cells (x 6–9,
    # y 5–7, z 0) — G starts at -6 m in x, y and 0.2 m in z
    touched = {tuple(c) for c in np.argwhere(update.touched)}
    assert {(i, j, 0) for i in range(6, 10) for j in (5, 6)} <= touched
    assert all(c[2] == 0 and 6 <= c[0] <= 9 and 4 <= c[1] <= 7 for c in touched)
    assert update.touched_cells.tolist() == np.flatnonzero(update.touched).tolist()
    assert state.statistics.n_obs[9, 6, 0] == 1  # the wall's cell, 3 m away
    assert state.navigation.known.any() and state.navigation.discovered_fraction > 0


def test_non_finite_points_are_dropped_and_a_pose_outside_the_map_raises():
    state = ExplorationState.from_config(SMALL)
    update = state.apply(scan_from([[3.0, 0.0, 0.45], [np.nan, 0.0, 0.0], [np.inf, 1.0, 1.0]]))
    assert (update.n_points, update.n_dropped) == (3, 2)
    with pytest.raises(PoseError, match="outside the map box"):
        state.apply(scan_from([[3.0, 0.0, 0.45]], pose=Pose(20.0, 0.0, 0.45)))


@pytest.mark.slow
def test_full_size_map_spans_one_float_per_voxel_and_bricks_padding():
    state = ExplorationState.from_config(MappingConfig())
    occupancy = state.occupancy  # 640 × 640 × 90 voxels; bricks of 4 layers pad z to 92
    # the marking bitset: one bit per voxel of the 27 × 27 × 23 bricks a 20 m sensor's window
    # can overlap (the bricks a scan can write)
    marks = 27 * 27 * 23 * 1024 // 8
    assert occupancy.memory_bytes() == 640 * 640 * 92 * 4 + marks < 153e6


MEDIUM = MappingConfig(
    map=MapConfig(low_m=(-16.0, -16.0, -1.0), high_m=(16.0, 16.0, 8.0)),
    statistics=StatisticsConfig(low_m=(-14.0, -14.0, 0.2), high_m=(14.0, 14.0, 6.2)),
)
WALK = ((0.0, 0.0, 0.0), (3.0, 1.0, 0.7), (-2.0, 4.0, 2.0), (-5.0, -3.0, 4.0), (1.0, -6.0, 5.5))


def walk_scans():
    from nbv_gym.perf.mapping import synthetic_lidar

    lidar, rng = synthetic_lidar(n_azimuth=128), np.random.default_rng(3)
    return [lidar.scan(Pose(x, y, 0.0, yaw), rng) for x, y, yaw in WALK]


def snapshot(state: ExplorationState) -> dict[str, np.ndarray]:
    nav, stats = state.navigation, state.statistics
    arrays = {
        "logodds": state.occupancy.logodds,
        **{
            name: getattr(stats, name).copy() for name in ("n_obs", "r_min", "sector_mask", "sum_u")
        },
        **{f"column_{name}": stats.column(name).copy() for name in COLUMNS},
        **{name: getattr(nav, name).copy() for name in ("known", "occupied", "distance")},
        "goal_mask": nav.goal_mask().copy(),
        "goal_cost": nav.goal_cost().copy(),
        "frontier_goals": nav.frontier_goal_mask().copy(),
    }
    return arrays


COLUMNS = {"n_obs": np.sum, "r_min": np.min, "n_omega": np.max, "sigma_theta": np.max}


def test_incremental_updates_equal_a_full_recomputation():
    """Navigation re-projects only the columns a scan changed and the statistics re-project only
    the columns it touched; both equal a projection of the whole map, bit for bit."""
    state = ExplorationState.from_config(MEDIUM)
    for scan in walk_scans():
        update = state.apply(scan)
        assert update.columns.shape == state.navigation.grid.shape[:2] and update.columns.any()
        nav = state.navigation
        known, occupied = state.occupancy.project(nav.grid, nav.known_band_m, nav.occupied_band_m)
        np.testing.assert_array_equal(nav.known, known)
        np.testing.assert_array_equal(nav.occupied, occupied)
        fresh = ExplorationState.from_config(MEDIUM).navigation
        fresh.update(known, occupied, scan.origin[:2])
        for read_out in ("goal_path_length", "goal_mask", "goal_cost", "frontier_goal_mask"):
            np.testing.assert_array_equal(getattr(nav, read_out)(), getattr(fresh, read_out)())
        stats = state.statistics
        for name, reduce in COLUMNS.items():
            np.testing.assert_array_equal(stats.column(name), reduce(getattr(stats, name), axis=2))


def test_clear_gives_back_an_empty_state_that_replays_identically():
    scans = walk_scans()
    state = ExplorationState.from_config(MEDIUM)
    empty = snapshot(state)
    for scan in scans:
        state.apply(scan)
    first = snapshot(state)
    state.clear()
    for name, array in snapshot(state).items():
        np.testing.assert_array_equal(array, empty[name], err_msg=name)
    for scan in scans:
        state.apply(scan)
    for name, array in snapshot(state).items():
        np.testing.assert_array_equal(array, first[name], err_msg=name)


def test_goal_read_outs_are_computed_once_per_plan_and_read_only():
    state = ExplorationState.from_config(SMALL)
    state.apply(scan_from([[3.05, 0.05, 0.45]]))
    nav = state.navigation
    assert nav.goal_mask() is nav.goal_mask() and nav.goal_cost() is nav.goal_cost()
    with pytest.raises(ValueError, match="read-only"):
        nav.goal_mask()[0] = True
    before = nav.goal_mask()
    nav.plan(np.array([1.0, 1.0]))
    assert nav.goal_mask() is not before
