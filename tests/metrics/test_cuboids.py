"""Cuboid metrics against hand-computed values (docs/protocol.md#metrics)."""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.cuboids import CuboidConfig, coverage_offsets, q_paper
from nbv_gym.metrics.tracker import QualityTracker, evaluate_cuboids


def _grid(shape=(10, 10, 10), value=0.3):
    return np.full(shape, value, np.float32)


@pytest.mark.parametrize(("d", "count"), [(0.05, 1), (0.10, 7), (0.15, 19)])
def test_coverage_stencil_counts_offsets_within_distance(d, count):
    assert len(coverage_offsets(d, 0.1)) == count  # 1 + 6 faces + 12 edges


def test_perfect_reconstruction_scores_one():
    rng = np.random.default_rng(0)
    gt = np.zeros((20, 20, 10), bool)
    gt[rng.integers(0, 20, 30), rng.integers(0, 20, 30), rng.integers(0, 10, 30)] = True
    gt[10:, 10:] = False  # one empty cuboid
    prob = np.where(gt, np.float32(0.97), np.float32(0.12))
    summary = evaluate_cuboids(prob, gt).summary()
    assert summary.cov == (1.0, 1.0, 1.0, 1.0)
    assert summary.q == 1.0 and summary.q_paper == 1.0
    assert summary.l1 == pytest.approx(120.0, rel=1e-6)


def test_all_unknown_scores_the_fixed_values():
    gt = np.zeros((20, 10, 10), bool)
    gt[3, 3, 3] = True
    metrics = evaluate_cuboids(_grid(gt.shape, 0.5), gt)
    assert not metrics.observed.any()
    assert metrics.cov[:, 0, 0, 0].tolist() == [0.0] * 4
    assert metrics.l1.ravel().tolist() == [500.0, 500.0]
    summary = metrics.summary()
    assert summary.q == 0.0 and summary.q_paper == 0.0


def test_band_is_open_so_edge_values_count_as_observed():
    gt = np.zeros((10, 10, 10), bool)
    prob = _grid(value=0.5)
    prob[0, 0, 0] = 0.4  # p_miss after one miss: observed (0.4 is outside the open band)
    assert evaluate_cuboids(prob, gt).observed.all()
    prob[0, 0, 0] = 0.41
    assert not evaluate_cuboids(prob, gt).observed.any()


def test_shifted_voxels_change_coverage_as_computed_by_hand():
    gt = np.zeros((10, 10, 10), bool)
    gt[5, 5, 5] = gt[2, 2, 2] = True
    prob = _grid()
    prob[5, 5, 6] = 0.9  # one voxel away (0.10 m) from the first
    prob[2, 3, 3] = 0.75  # √2 voxels away (0.141 m) from the second
    cov = evaluate_cuboids(prob, gt).cov[:, 0, 0, 0]
    # (0.8, 0.05): none; (0.8, 0.10): first only; (0.7, 0.10): first only; (0.7, 0.15): both
    assert cov.tolist() == [0.0, 0.5, 0.5, 1.0]


def test_coverage_search_stays_inside_the_cuboid():
    gt = np.zeros((20, 10, 10), bool)
    gt[9, 5, 5] = True
    prob = _grid(gt.shape)
    prob[10, 5, 5] = 0.95  # adjacent, but in the next cuboid
    cov = evaluate_cuboids(prob, gt).cov[:, 0, 0, 0]
    assert cov.tolist() == [0.0, 0.0, 0.0, 0.0]


def test_l1_and_empty_quality_by_hand():
    gt = np.zeros((10, 10, 10), bool)
    metrics = evaluate_cuboids(_grid(value=0.31), gt)
    assert metrics.l1[0, 0, 0] == pytest.approx(310.0, rel=1e-6)
    assert metrics.quality[0, 0, 0] == pytest.approx((500 - 310) / 380, rel=1e-6)


def test_q_paper_is_equation_3_with_min_max_normalisation():
    config = CuboidConfig()
    # cov normalised: 0, 0.5, 1; L1 normalised: 0, 0.5, 1 → 1 − that: 1, 0.5, 0; mean = 3 / 6
    assert q_paper([0.2, 0.6, 1.0], [120.0, 310.0, 500.0], config) == pytest.approx(0.5)
    # a constant set falls back to the fixed bounds of Q
    assert q_paper([0.4, 0.4], [], config) == pytest.approx(0.4)


def test_q_over_the_whole_grid_is_the_mean_over_all_cuboids():
    gt = np.zeros((20, 10, 10), bool)
    gt[2, 2, 2] = gt[3, 3, 3] = True  # cuboid 0 occupied, cuboid 1 empty
    prob = _grid(gt.shape, 0.12)
    prob[2, 2, 2] = 0.9  # cov(0.7, 0.15) = 1/2
    summary = evaluate_cuboids(prob, gt, CuboidConfig(volume="grid")).summary()
    empty_l1 = 0.12 * 1000
    assert summary.q == pytest.approx((0.5 + (500 - empty_l1) / 380) / 2, rel=1e-6)
    # the default volume is the ground truth's bounding box: cuboid 0 alone
    assert evaluate_cuboids(prob, gt).summary().q == pytest.approx(0.5)


def test_comparison_volume_is_the_ground_truth_bounding_box_in_cuboids():
    # 5 × 4 × 3 cuboids; occupied voxels in cuboids (1, 0, 0) and (2, 2, 1): their box spans
    # x 1..2, y 0..2, z 0..1 → 2 · 3 · 2 = 12 cuboids, of which 2 in U_occ and 10 empty.
    gt = np.zeros((50, 40, 30), bool)
    gt[15, 5, 5] = gt[25, 25, 15] = True
    prob = _grid(gt.shape, 0.5)  # unknown everywhere …
    prob[10:20, 0:10, 0:10] = 0.12  # … but for one observed empty-looking cuboid of U_occ
    prob[15, 5, 5] = 0.9  # whose ground-truth voxel is covered
    prob[40:50, 30:40, 20:30] = 0.12  # observed, outside the box: ignored
    metrics = evaluate_cuboids(prob, gt)
    assert metrics.volume.sum() == 12
    assert metrics.volume[1:3, 0:3, 0:2].all()
    summary = metrics.summary()
    assert (summary.n_occ, summary.n_empty, summary.n_observed) == (2, 10, 1)
    assert summary.q == pytest.approx(1 / 12)  # one covered cuboid, 11 unknown (quality 0)
    assert summary.q_observed == pytest.approx(1.0)
    assert summary.cov_observed[3] == pytest.approx(1.0) and summary.cov[3] == pytest.approx(0.5)
    assert np.isnan(summary.l1_observed) and summary.l1 == pytest.approx(500.0)
    whole = evaluate_cuboids(prob, gt, CuboidConfig(volume="grid")).summary()
    assert whole.n_occ + whole.n_empty == 60 and whole.n_observed == 2
    assert whole.q == pytest.approx(2 / 60)


def test_summary_equals_plain_means_over_every_cuboid_of_the_volume():
    # the summary adds the unobserved cuboids as counts times their fixed values; the plain
    # definition averages every cuboid's array entry (numpy, over the whole volume)
    rng = np.random.default_rng(5)
    holding = np.kron(rng.random((6, 5, 3)) < 0.3, np.ones((10, 10, 10), bool))  # ~30 % of them
    gt = holding & (rng.random(holding.shape) < 0.01)
    prob = np.full(gt.shape, 0.5, np.float32)
    for ci, cj, ck in np.unique(rng.integers(0, [6, 5, 3], (25, 3)), axis=0):
        block = prob[ci * 10 : ci * 10 + 10, cj * 10 : cj * 10 + 10, ck * 10 : ck * 10 + 10]
        block[...] = rng.choice(
            [0.12, 0.3, 0.45, 0.75, 0.97], block.shape, p=[0.3, 0.3, 0.3, 0.05, 0.05]
        )
    metrics = evaluate_cuboids(prob, gt)
    summary, config = metrics.summary(), metrics.config
    assert 0 < summary.n_observed < summary.n_occ + summary.n_empty
    for where, q, q_p, cov, l1 in (
        (metrics.volume, summary.q, summary.q_paper, summary.cov, summary.l1),
        (metrics.volume & metrics.observed, summary.q_observed, summary.q_paper_observed,
         summary.cov_observed, summary.l1_observed),
    ):  # fmt: skip
        occ, empty = where & metrics.u_occ, where & ~metrics.u_occ
        assert q == pytest.approx(metrics.quality[where].mean(), rel=1e-12)
        assert cov == pytest.approx(tuple(metrics.cov[:, occ].mean(axis=1)), rel=1e-12)
        assert l1 == pytest.approx(metrics.l1[empty].mean(), rel=1e-12)
        covs, l1s = metrics.cov[config.q_setting][occ], metrics.l1[empty]
        norm_cov = (covs - covs.min()) / (covs.max() - covs.min())
        norm_l1 = (l1s - l1s.min()) / (l1s.max() - l1s.min())
        expected = (norm_cov.sum() + (1 - norm_l1).sum()) / (covs.size + l1s.size)
        assert q_p == pytest.approx(expected, rel=1e-12)


def test_unknown_volume_is_refused_naming_the_key():
    with pytest.raises(ConfigError, match="volume"):
        CuboidConfig(volume="sky")


def test_incremental_updates_equal_a_full_recomputation_exactly():
    rng = np.random.default_rng(3)
    gt = rng.random((40, 30, 20)) < 0.02
    gt[:10] = False
    prob = np.full(gt.shape, 0.5, np.float32)
    tracker = QualityTracker(gt)
    tracker.update(prob)
    for _ in range(5):
        cuboids = np.unique(rng.integers(0, [4, 3, 2], (5, 3)), axis=0)
        for ci, cj, ck in cuboids:
            block = prob[ci * 10 : ci * 10 + 10, cj * 10 : cj * 10 + 10, ck * 10 : ck * 10 + 10]
            block[...] = rng.choice([0.12, 0.3, 0.75, 0.85, 0.97], block.shape)
        incremental = tracker.update(prob, cuboids)
    full = QualityTracker(gt).update(prob)
    np.testing.assert_equal(
        astuple(incremental), astuple(full)
    )  # every field, bit for bit (NaN == NaN)
    assert 0 < full.q < 1
    np.testing.assert_equal(astuple(tracker.summary()), astuple(tracker.metrics().summary()))
    tracker.reset()  # a new episode on the same ground truth: as a new tracker, bit for bit
    np.testing.assert_equal(astuple(tracker.summary()), astuple(QualityTracker(gt).summary()))
    np.testing.assert_equal(astuple(tracker.update(prob)), astuple(full))


def test_mismatched_grids_raise_clear_errors():
    with pytest.raises(MetricInputError, match="differs from ground-truth shape"):
        evaluate_cuboids(_grid((10, 10, 10)), np.zeros((20, 10, 10), bool))
    with pytest.raises(MetricInputError, match="whole number of 10-voxel cuboids"):
        evaluate_cuboids(_grid((15, 10, 10)), np.zeros((15, 10, 10), bool))
    with pytest.raises(MetricInputError, match="bool grid"):
        QualityTracker(np.zeros((10, 10, 10), np.uint8))


def test_other_cuboid_sizes_work():
    gt = np.zeros((8, 8, 4), bool)
    gt[1, 1, 1] = True
    prob = np.full(gt.shape, 0.12, np.float32)
    prob[1, 1, 2] = 0.9
    metrics = evaluate_cuboids(prob, gt, CuboidConfig(cuboid_voxels=4))
    assert metrics.u_occ.shape == (2, 2, 1)
    assert metrics.cov[:, 0, 0, 0].tolist() == [0.0, 1.0, 1.0, 1.0]
    assert metrics.l1[1, 1, 0] == pytest.approx(0.12 * 64, rel=1e-6)


def test_update_blocks_equals_update_on_the_whole_grid():
    rng = np.random.default_rng(5)
    gt = np.zeros((20, 20, 10), bool)
    gt[:10, :10] = rng.random((10, 10, 10)) < 0.05  # one occupied cuboid, three empty ones
    prob = np.where(rng.random(gt.shape) < 0.5, 0.5, rng.random(gt.shape)).astype(np.float32)
    whole = CuboidConfig(volume="grid")
    full = QualityTracker(gt, whole)
    full.update(prob)
    by_blocks = QualityTracker(gt, whole)
    touched = np.array([0, 3, 5, 7])
    blocks = np.stack([prob[i * 10 : i * 10 + 10, j * 10 : j * 10 + 10, :] for i in (0, 1)
                       for j in (0, 1)])[[0, 1, 2, 3]]  # fmt: skip
    # cuboid grid (2, 2, 1): flat index i·2 + j; recompute all four through blocks
    summary = by_blocks.update_blocks(np.arange(4), blocks)
    np.testing.assert_equal(astuple(summary), astuple(full.summary()))
    assert summary.n_occ == 1 and summary.n_empty == 3
    np.testing.assert_array_equal(by_blocks.metrics().l1, full.metrics().l1)
    with pytest.raises(MetricInputError, match="probability blocks"):
        by_blocks.update_blocks(touched, blocks[:2])


def test_update_totals_gives_the_bits_of_update_blocks():
    """The simulator's path — Σp and out-of-band counts kept by the map, blocks only for the
    coverage search of the cuboids whose levels changed — against the blocks path, on map-like
    probabilities (≥ the 0.12 clamp), scan after scan."""
    rng = np.random.default_rng(8)
    gt = np.zeros((20, 20, 10), bool)
    gt[:, :10] = rng.random((20, 10, 10)) < 0.05  # cuboids 0 and 2 hold ground truth
    prob = np.full(gt.shape, 0.5, np.float32)
    expected, tracker = QualityTracker(gt), QualityTracker(gt)
    for _ in range(4):
        known = rng.random(gt.shape) < 0.15
        prob[known] = (0.12 + 0.85 * rng.random(gt.shape))[known]
        blocks = np.stack([prob[i * 10 : i * 10 + 10, j * 10 : j * 10 + 10] for i in (0, 1)
                           for j in (0, 1)])  # fmt: skip
        blocks[3] = 0.5  # cuboid 3 stays unobserved
        touched = np.arange(4)
        sums = blocks.astype(np.float64).sum(axis=(1, 2, 3))
        outside = ((blocks <= np.float32(0.4)) | (blocks >= np.float32(0.6))).sum(axis=(1, 2, 3))
        search = tracker.needs_coverage(touched)
        assert search.tolist() == [0, 2]
        summary = tracker.update_totals(touched, sums, outside, search,
                                        tracker.levels(blocks[search]))  # fmt: skip
        np.testing.assert_equal(astuple(summary), astuple(expected.update_blocks(touched, blocks)))
    # a cuboid whose levels did not change keeps its coverage without a search
    kept = tracker.update_totals(touched, sums, outside, search[:1], tracker.levels(blocks[:1]))
    np.testing.assert_equal(astuple(kept), astuple(summary))
    with pytest.raises(MetricInputError, match="levels of the searched cuboids"):
        tracker.update_totals(touched, sums, outside, search, tracker.levels(blocks))
    with pytest.raises(MetricInputError, match="uint32 levels"):
        tracker.update_totals(touched, sums, outside, search, blocks[search])  # probabilities
