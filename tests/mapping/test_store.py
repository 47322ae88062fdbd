"""The map's voxel store: zero bits mean unknown, a known log-odds of exactly 0 stays known, and
forgetting voxels zeroes exactly the range asked for."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping import OccupancyMap
from nbv_gym.mapping.mapfile import load_map, save_map
from nbv_gym.mapping.probability import logodds_bound, probabilities
from nbv_gym.mapping.store import BLOCK, ZeroPages, decoded, encoded
from nbv_gym.mapping.traversal import BRICK, axis_offsets

BOX = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 0.1)
ORIGIN = np.array([0.05, 0.05, 0.05])  # centre of voxel (20, 20, 10)
L_HIT, L_MISS = np.float32(math.log(0.7 / 0.3)), np.float32(math.log(0.4 / 0.6))


def test_a_hit_then_a_miss_of_equal_weight_leaves_a_known_voxel_at_log_odds_zero(tmp_path):
    # p_miss = 1 − p_hit: a hit and a miss cancel exactly; the voxel is known, with p = 0.5
    occupancy = OccupancyMap(
        BOX, p_hit=0.7, p_miss=0.3, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
        max_range_m=20.0,
    )  # fmt: skip
    assert np.float32(math.log(0.7 / 0.3)) == -np.float32(math.log(0.3 / 0.7))
    occupancy.insert(ORIGIN, [[1.05, 0.05, 0.05]])  # hit at voxel (30, 20, 10)
    occupancy.insert(ORIGIN, [[2.05, 0.05, 0.05]])  # passes through it: a miss
    lo = occupancy.logodds
    assert lo[30, 20, 10] == 0.0 and not np.signbit(lo[30, 20, 10])
    assert occupancy.known_mask(BOX)[30, 20, 10] and occupancy.occupied_mask(BOX)[30, 20, 10]
    assert occupancy.probability(BOX)[30, 20, 10] == 0.5
    assert occupancy.n_known == int((~np.isnan(lo)).sum()) == 21  # voxels 20..40 along x
    coarse = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 1.0)
    block = occupancy.logodds_blocks(coarse, [[3, 2, 1]])[0]  # voxels (30…39, 20…29, 10…19)
    assert block[0, 0, 0] == 0.0 and np.isnan(block[0, 1, 0])
    nav = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 0.5)
    known, occupied = occupancy.project(nav, (-0.3, 1.0), (0.0, 1.0))
    assert (
        known[6, 4] and occupied[6, 4] and occupied[8, 4] and occupied.sum() == 2
    )  # p = 0.5: occupied
    save_map(occupancy, tmp_path / "map.npz")
    np.testing.assert_array_equal(load_map(tmp_path / "map.npz").logodds, lo)
    occupancy.insert(ORIGIN, [[2.05, 0.05, 0.05]])  # another miss starts from 0
    assert occupancy.logodds[30, 20, 10] == np.float32(math.log(0.3 / 0.7))
    occupancy.clear()
    assert occupancy.n_known == 0 and np.isnan(occupancy.logodds).all()


def test_encoding_round_trips_unknown_zero_and_values():
    logodds = np.array([np.nan, 0.0, -0.0, 1.5, -2.0], np.float32)
    stored = encoded(logodds)
    assert stored.view(np.uint32).tolist()[:3] == [0, 1, 1]  # 1: the smallest subnormal
    back = decoded(stored)
    assert np.isnan(back[0]) and back[1:].tolist() == [0.0, 0.0, 1.5, -2.0]
    assert not np.signbit(back[1:3]).any()


def test_zero_pages_zero_exactly_the_range_and_pickle():
    pages = ZeroPages(10_000)
    pages.array[:] = np.arange(1, 10_001)
    pages.zero(1_500, 7_300)  # unaligned at both ends, whole pages inside
    pages.zero(9_000, 9_010)  # inside one page
    expected = np.arange(1, 10_001, dtype=np.float32)
    expected[1_500:7_300] = expected[9_000:9_010] = 0
    np.testing.assert_array_equal(pages.array, expected)
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(pages)).array, expected)


def test_zero_blocks_zero_the_flagged_blocks_kept_or_handed_back():
    pages = ZeroPages(7 * BLOCK + 10)  # a partial last block
    flagged = np.array([True, False, True, True, False, True, False, True])
    values = np.pad(pages.array, (0, BLOCK - 10)).reshape(8, BLOCK)  # a copy: the expectation
    values[flagged] = 7.0  # blocks not flagged are zero (nothing wrote them)
    pages.array[:] = values.reshape(-1)[: pages.array.size]
    pages.array[-5:] = 7.0
    resident = np.array([False, False, True, False, False, False, False, True])
    pages.zero_blocks(flagged, resident)
    assert not pages.array.any()


def test_voxel_index_is_a_bijection_whose_bricks_are_store_blocks():
    bx, by, bz = 3, 2, 2  # bricks
    shape = (bx * BRICK[0], by * BRICK[1], bz * BRICK[2])
    i, j, k = (a.ravel() for a in np.indices(shape))
    x, y, z = axis_offsets((bx, by, bz))
    index = x[i] + y[j] + z[k]
    assert np.array_equal(np.sort(index), np.arange(len(index)))
    brick = ((k // BRICK[2]) * bx + i // BRICK[0]) * by + j // BRICK[1]
    assert np.array_equal(index // BLOCK, brick) and math.prod(BRICK) == BLOCK
    tile = (k % 4 * 4 + i % 16 // 4) * 4 + j % 16 // 4  # 4 × 4 × 4 tiles of 16 voxels
    assert np.array_equal(index % BLOCK, tile * 16 + i % 4 * 4 + j % 4)


@pytest.mark.parametrize("threshold", [0.0, 0.12, 0.4, 0.5, 0.6, 0.7, 0.97, 0.999])
def test_a_probability_exceeds_a_threshold_iff_its_log_odds_reach_the_bound(threshold):
    bound = logodds_bound(threshold)
    up, down = [bound], [bound]
    for _ in range(300):  # 300 float32 steps on either side of the bound
        up.append(np.nextafter(up[-1], np.float32(np.inf)))
        down.append(np.nextafter(down[-1], np.float32(-np.inf)))
    near = up + down
    rng = np.random.default_rng(1)
    values = np.concatenate([np.array(near, np.float32), rng.uniform(-8, 8, 20_000).astype(np.float32),
                             np.float32([0.0, -0.0, L_HIT, L_MISS, 2 * L_HIT, L_HIT + L_MISS])])  # fmt: skip
    exceeds = probabilities(values) > np.float32(threshold)
    np.testing.assert_array_equal(exceeds, values >= bound)


def test_level_blocks_equal_thresholded_probability_blocks():
    from nbv_gym.metrics.tracker import QualityTracker

    occupancy = OccupancyMap(
        BOX, p_hit=0.7, p_miss=0.3, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
        max_range_m=20.0,
    )  # fmt: skip
    rng = np.random.default_rng(3)
    for _ in range(4):  # hits and misses of equal weight: some voxels at log-odds 0
        occupancy.insert(ORIGIN, rng.uniform((-2, -2, -1), (6, 2, 1), (300, 3)))
    coarse = GridSpec.from_bounds((-3.0, -3.0, -2.0), (7.0, 3.0, 2.0), 1.0)  # cells outside too
    cells = np.argwhere(np.ones(coarse.shape, bool))
    tracker = QualityTracker(np.zeros((10, 10, 10), bool))
    assert (occupancy.logodds_blocks(coarse, cells) == 0).any()
    np.testing.assert_array_equal(
        occupancy.level_blocks(coarse, cells, tracker.bounds),
        tracker.levels(occupancy.probability_blocks(coarse, cells)),
    )


@pytest.mark.parametrize("threshold", [1.2, 0.0, -0.3, float(L_HIT)])
def test_cells_reaching_a_log_odds_equal_thresholded_logodds_blocks(threshold):
    # unknown voxels (NaN) never reach, not even a threshold ≤ 0; a known 0 reaches those; one
    # exact hit reaches L_HIT. Scans reach x < 2 m only: the map's cells beyond are unknown.
    occupancy = OccupancyMap(
        BOX, p_hit=0.7, p_miss=0.3, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
        max_range_m=20.0,
    )  # fmt: skip
    rng = np.random.default_rng(4)
    for _ in range(4):
        occupancy.insert(ORIGIN, rng.uniform((-2, -2, -1), (2, 2, 1), (300, 3)))
    coarse = GridSpec.from_bounds((-3.0, -3.0, -2.0), (7.0, 3.0, 2.0), 1.0)  # cells outside too
    cells = np.argwhere(np.ones(coarse.shape, bool))
    blocks = occupancy.logodds_blocks(coarse, cells).reshape(len(cells), -1)
    want = (blocks >= np.float32(threshold)).any(axis=1)
    assert 0 < want.sum() < len(cells)  # the case is not trivial
    x = coarse.centres(cells)[:, 0]
    assert np.isnan(blocks[(x > 3.0) & (x < 6.0)]).all()  # cells of the map no scan reached
    np.testing.assert_array_equal(occupancy.cells_reaching(coarse, cells, threshold), want)


def test_column_counts_kept_by_insertion_equal_a_count_of_the_map():
    occupancy = OccupancyMap(
        BOX, p_hit=0.7, p_miss=0.3, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
        max_range_m=20.0,
    )  # fmt: skip
    nav = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 0.5)
    known_band, occupied_band = (-0.3, 0.5), (0.0, 0.5)
    counts = occupancy.column_counts(nav, known_band, occupied_band)
    rng = np.random.default_rng(5)
    for origin in ([0.05, 0.05, 0.05], [2.05, -1.05, 0.35], [0.05, 0.05, 0.05]):
        # hits, then misses through them: occupied voxels turn free and back
        occupancy.insert(np.array(origin), rng.uniform((-2, -2, -1), (6, 2, 1), (400, 3)),
                         columns=counts)  # fmt: skip
        lo = occupancy.logodds
        z = BOX.low[2] + (np.arange(lo.shape[2]) + 0.5) * BOX.res
        known_layers = (z >= known_band[0]) & (z <= known_band[1])
        occupied_layers = (z >= occupied_band[0]) & (z <= occupied_band[1])
        per_cell = lambda mask: mask.reshape(16, 5, 8, 5, -1).sum(axis=(1, 3, 4))  # noqa: E731
        known = ~np.isnan(lo) & known_layers
        occupied = (lo >= 0) & occupied_layers  # NaN compares False
        np.testing.assert_array_equal(counts.known, per_cell(known))
        np.testing.assert_array_equal(counts.occupied, per_cell(occupied))
        projected = occupancy.project(nav, known_band, occupied_band)
        np.testing.assert_array_equal(counts.known > 0, projected[0])
        np.testing.assert_array_equal(counts.occupied > 0, projected[1])
    assert counts.occupied.sum() > 0 and counts.take_changed().size and not counts.changed.any()


def test_each_episode_after_a_clear_equals_one_in_a_fresh_map():
    # a clear keeps the last episode's pages mapped and hands back older ones: over episodes
    # that write other blocks, each starts from an empty map all the same
    params = {"p_hit": 0.7, "p_miss": 0.4, "p_clamp_min": 0.12, "p_clamp_max": 0.97,
              "p_occupied": 0.5, "max_range_m": 20.0}  # fmt: skip
    reused = OccupancyMap(BOX, **params)
    rng = np.random.default_rng(3)
    for x in (-1.5, 3.5, -1.5, 1.0, 4.5):  # the third episode's blocks are the first's again
        origin = np.array([x, 0.05, 0.05])
        points = origin + rng.uniform(-1.5, 1.5, (200, 3)) * [1, 1, 0.5]
        points = np.clip(points, BOX.low + 0.01, BOX.high - 0.01)
        fresh = OccupancyMap(BOX, **params)
        for occupancy in (reused, fresh):
            occupancy.insert(origin, points)
        np.testing.assert_array_equal(reused.logodds, fresh.logodds)
        assert np.array_equal(reused.written_blocks(), fresh.written_blocks())
        reused.clear()
        assert reused.n_known == 0 and not reused._store.any()
