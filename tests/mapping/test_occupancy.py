"""Occupancy map: OctoMap update semantics on hand-built rays, queries, files and bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, PoseError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping import MapConfig, OccupancyMap
from nbv_gym.mapping.mapfile import load_map, save_map

L_HIT = math.log(0.7 / 0.3)  # 0.8473
L_MISS = math.log(0.4 / 0.6)  # -0.4055
L_MIN = math.log(0.12 / 0.88)
L_MAX = math.log(0.97 / 0.03)

# A small box: voxel (i, j, k) covers [-2 + 0.1 i, ...) × [-2 + 0.1 j, ...) × [-1 + 0.1 k, ...).
BOX = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 0.1)
ORIGIN = np.array([0.05, 0.05, 0.05])  # centre of voxel (20, 20, 10)


def small_map(max_range_m: float = 20.0) -> OccupancyMap:
    return OccupancyMap(
        BOX,
        p_hit=0.7,
        p_miss=0.4,
        p_clamp_min=0.12,
        p_clamp_max=0.97,
        p_occupied=0.5,
        max_range_m=max_range_m,
    )


def test_config_defaults_are_the_spec_numbers():
    config = MapConfig()
    assert config.grid().shape == (640, 640, 90)
    assert (config.p_hit, config.p_miss, config.p_clamp_min, config.p_clamp_max) == (
        0.7,
        0.4,
        0.12,
        0.97,
    )
    with pytest.raises(ConfigError, match="p_hit"):
        MapConfig(p_hit=0.4)


def test_single_ray_along_x_marks_free_voxels_and_one_hit():
    occupancy = small_map()
    occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05]])
    lo = occupancy.logodds
    known = np.argwhere(~np.isnan(lo))
    # free: voxels 20..29 along x (the sensor's voxel included), occupied: voxel 30
    assert known.tolist() == [[i, 20, 10] for i in range(20, 31)]
    np.testing.assert_allclose(lo[20:30, 20, 10], L_MISS, rtol=1e-6)
    assert lo[30, 20, 10] == pytest.approx(L_HIT, rel=1e-6)


def test_repeated_updates_saturate_at_the_clamping_bounds():
    occupancy = small_map()
    for _ in range(10):
        occupancy.insert(ORIGIN, [[0.55, 0.05, 0.05]])
    lo = occupancy.logodds
    # 10 hits: 8.47 > L_MAX; 10 misses: -4.05 < L_MIN
    assert lo[25, 20, 10] == pytest.approx(L_MAX, rel=1e-6)
    np.testing.assert_allclose(lo[20:25, 20, 10], L_MIN, rtol=1e-6)
    assert occupancy.probability(BOX)[25, 20, 10] == pytest.approx(0.97, rel=1e-6)


def test_voxel_crossed_by_two_rays_of_one_scan_is_updated_once():
    occupancy = small_map()
    # two rays along +x and +y share only the sensor's voxel; a third, shorter ray along +x
    # shares voxels 20..24 with the first and ends inside the first ray's free pass
    occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05], [0.05, 1.05, 0.05], [0.55, 0.05, 0.05]])
    lo = occupancy.logodds
    assert lo[20, 20, 10] == pytest.approx(L_MISS, rel=1e-6)
    np.testing.assert_allclose(lo[21:25, 20, 10], L_MISS, rtol=1e-6)
    # endpoint beats free pass: voxel 25 holds a return and lies on the first ray
    assert lo[25, 20, 10] == pytest.approx(L_HIT, rel=1e-6)
    np.testing.assert_allclose(lo[26:30, 20, 10], L_MISS, rtol=1e-6)


def test_return_beyond_range_carves_to_the_range_and_marks_nothing():
    occupancy = small_map(max_range_m=3.0)
    occupancy.insert(ORIGIN, [[5.55, 0.05, 0.05]])  # 5.5 m away
    lo = occupancy.logodds
    # carving stops at 0.05 + 3.0 = 3.05 m, whose voxel (50) is excluded as OctoMap does
    known = np.argwhere(~np.isnan(lo))
    assert known.tolist() == [[i, 20, 10] for i in range(20, 50)]
    assert np.all(lo[20:50, 20, 10] < 0)


def test_diagonal_ray_follows_the_voxels_it_crosses():
    occupancy = small_map()
    # from (0.05, 0.05) to (0.35, 0.25) in the plane z = 0.05: slope 2/3. Crossings: x = 0.1 at
    # t = 1/6, y = 0.1 at t = 1/4, x = 0.2 at t = 1/2, y = 0.2 at t = 3/4, x = 0.3 at t = 5/6
    # (t along the segment), so the voxels (x, y) are 20,20 → 21,20 → 21,21 → 22,21 → 22,22 → 23,22.
    occupancy.insert(ORIGIN, [[0.35, 0.25, 0.05]])
    known = {tuple(v) for v in np.argwhere(~np.isnan(occupancy.logodds))}
    expected = {(20, 20), (21, 20), (21, 21), (22, 21), (22, 22), (23, 22)}
    assert known == {(i, j, 10) for i, j in expected}
    np.testing.assert_allclose(occupancy.occupied_points(), [[0.35, 0.25, 0.05]], atol=1e-9)


def test_non_finite_points_are_dropped_and_counted():
    occupancy = small_map()
    result = occupancy.insert(
        ORIGIN, [[np.nan, 0.0, 0.0], [1.05, 0.05, 0.05], [np.inf, 1.0, 0.0], [0.0, -np.inf, 0]]
    )
    assert (result.n_points, result.n_dropped, result.n_occupied) == (4, 3, 1)
    assert int((~np.isnan(occupancy.logodds)).sum()) == 11


def test_sensor_outside_the_box_raises_pose_error():
    occupancy = small_map()
    with pytest.raises(PoseError, match="outside the map box"):
        occupancy.insert([10.0, 0.0, 0.0], [[1.0, 0.0, 0.0]])
    with pytest.raises(PoseError):
        occupancy.insert([np.nan, 0.0, 0.0], [[1.0, 0.0, 0.0]])


def test_touched_region_flags_the_coarse_cells_with_changed_voxels():
    occupancy = small_map()
    coarse = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 1.0)
    result = occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05]], region=coarse)
    # voxels x 20..30 (metres 0.0–1.1) lie in coarse cells x 2 and 3, y 2, z 1
    assert np.argwhere(result.touched).tolist() == [[2, 2, 1], [3, 2, 1]]
    for _ in range(9):
        occupancy.insert(ORIGIN, [[0.55, 0.05, 0.05]])
    # every voxel on the short ray is clamped now: nothing changes
    assert not occupancy.insert(ORIGIN, [[0.55, 0.05, 0.05]], region=coarse).touched.any()
    with pytest.raises(ConfigError, match="aligned"):
        occupancy.insert(ORIGIN, [[1.0, 0, 0]], region=GridSpec((-1.95, -2, -1), 1.0, (2, 2, 2)))


def test_probability_and_masks_over_an_aligned_sub_box():
    occupancy = small_map()
    occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05]])
    box = GridSpec.from_bounds((0.9, 0.0, 0.0), (1.3, 0.1, 0.1), 0.1)  # voxels x 29..32
    p = occupancy.probability(box)
    assert p.dtype == np.float32 and p.shape == (4, 1, 1)
    np.testing.assert_allclose(p.ravel(), [0.4, 0.7, 0.5, 0.5], rtol=1e-6)
    assert occupancy.known_mask(box).ravel().tolist() == [True, True, False, False]
    assert occupancy.occupied_mask(box).ravel().tolist() == [False, True, False, False]
    outside = GridSpec.from_bounds((5.9, 1.9, 0.9), (6.1, 2.1, 1.1), 0.1)
    np.testing.assert_array_equal(occupancy.probability(outside), 0.5)
    with pytest.raises(ConfigError, match="aligned"):
        occupancy.probability(GridSpec((0.05, 0.0, 0.0), 0.1, (1, 1, 1)))
    with pytest.raises(ConfigError, match="resolution"):
        occupancy.probability(GridSpec((0.0, 0.0, 0.0), 0.2, (1, 1, 1)))


def test_save_load_round_trip(tmp_path):
    occupancy = small_map()
    occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05], [0.05, -1.05, 0.35]])
    save_map(occupancy, tmp_path / "map.npz")
    loaded = load_map(tmp_path / "map.npz")
    assert loaded.grid == occupancy.grid and loaded.params == occupancy.params
    np.testing.assert_array_equal(loaded.logodds, occupancy.logodds)


def test_projection_onto_columns_uses_the_voxel_centres_in_each_band():
    tall = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 2.0), 0.1)
    lo = np.full(tall.shape, np.nan, np.float32)
    # 0.5 m cells over x ∈ [0, 2.5), y ∈ [0, 0.5): cell a covers voxels x 20 + 5a … 24 + 5a
    lo[20, 20, 6] = -1.0  # centre z = -0.35: below the known band
    lo[25, 20, 7] = -1.0  # centre z = -0.25: known
    lo[30, 24, 11] = 1.0  # centre z = 0.15: known, below the occupied band
    lo[39, 24, 19] = 1.0  # centre z = 0.95: known and occupied
    lo[40, 20, 20] = 1.0  # centre z = 1.05: above both bands
    lo[44, 20, 15] = -1.0  # known, free
    occupancy = OccupancyMap.from_logodds(
        tall, lo, p_hit=0.7, p_miss=0.4, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
        max_range_m=20.0,
    )  # fmt: skip
    np.testing.assert_array_equal(occupancy.logodds, lo)
    cells = GridSpec((0.0, 0.0, 0.0), 0.5, (5, 1, 1))
    known, occupied = occupancy.project(cells, (-0.3, 1.0), (0.2, 1.0))
    assert known.ravel().tolist() == [False, True, True, True, True]
    assert occupied.ravel().tolist() == [False, False, False, True, False]
    with pytest.raises(ConfigError, match="aligned"):
        occupancy.project(GridSpec((0.05, 0.0, 0.0), 0.5, (2, 1, 1)), (0, 1), (0, 1))


def test_logodds_blocks_equal_the_dense_read_out():
    occupancy = OccupancyMap.from_config(MapConfig(), 20.0)
    points = np.random.default_rng(0).uniform([-10, -10, 0], [10, 10, 3], (3000, 3))
    occupancy.insert(np.array([0.3, 0.2, 0.42]), points)
    coarse = GridSpec.from_bounds((-30, -30, 0.2), (30, 30, 6.2), 1.0)
    fine = GridSpec.from_bounds((-30, -30, 0.2), (30, 30, 6.2), 0.1)
    cells = np.array([[25, 27, 1], [30, 30, 0], [0, 0, 5], [59, 59, 5], [22, 31, 2]])
    dense = occupancy.logodds_in(fine)
    blocks = occupancy.logodds_blocks(coarse, cells)
    for (i, j, k), block in zip(cells, blocks, strict=True):
        expected = dense[10 * i : 10 * i + 10, 10 * j : 10 * j + 10, 10 * k : 10 * k + 10]
        np.testing.assert_array_equal(block, expected)
    assert np.isfinite(blocks).any() and np.isnan(blocks).any()


def test_probability_blocks_equal_the_probability_grid():
    occupancy = OccupancyMap.from_config(MapConfig(), 20.0)
    points = np.random.default_rng(1).uniform([-8, -8, 0], [8, 8, 3], (2000, 3))
    occupancy.insert(np.array([0.1, 0.2, 0.42]), points)
    coarse = GridSpec.from_bounds((-30, -30, 0.2), (30, 30, 6.2), 1.0)
    fine = GridSpec.from_bounds((-30, -30, 0.2), (30, 30, 6.2), 0.1)
    cells = np.array([[28, 29, 0], [31, 30, 1], [2, 3, 4]])
    dense = occupancy.probability(fine)
    blocks = occupancy.probability_blocks(coarse, cells)
    assert blocks.dtype == np.float32
    for (i, j, k), block in zip(cells, blocks, strict=True):
        expected = dense[10 * i : 10 * i + 10, 10 * j : 10 * j + 10, 10 * k : 10 * k + 10]
        np.testing.assert_array_equal(block, expected)
    assert np.all(blocks[2] == 0.5)  # never observed
    assert set(np.unique(blocks[0])) >= {np.float32(0.5), np.float32(0.4)}


def test_known_voxels_read_from_the_written_blocks_equal_the_dense_map():
    rng = np.random.default_rng(7)
    occupancy = small_map()
    for episode in range(2):  # the second after a clear: blocks of the first are unknown again
        for _ in range(6):
            points = ORIGIN + rng.uniform(-3.0, 3.0, (300, 3)) * [1, 0.6, 0.3]
            occupancy.insert(ORIGIN + rng.uniform(-0.5, 0.5, 3) * [1, 1, 0.2], points)
        lo = occupancy.logodds
        for threshold in (0.0, 0.3, 0.5, 0.7, 1.0):
            keep = ~np.isnan(lo)
            if threshold >= 1:
                keep[:] = False
            elif threshold > 0:
                keep &= lo >= np.float32(math.log(threshold / (1 - threshold)))
            index, logodds = occupancy.voxels_at_least(threshold)
            np.testing.assert_array_equal(index, np.argwhere(keep))
            np.testing.assert_array_equal(logodds, lo[keep])
        assert occupancy.n_known == np.count_nonzero(~np.isnan(lo)) > 0
        if episode == 0:
            occupancy.clear()
            assert occupancy.n_known == 0 and len(occupancy.voxels_at_least(0.0)[0]) == 0
