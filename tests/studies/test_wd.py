"""The WD study's operators and rules against hand-computed answers (*Measuring 3D-reconstruction quality in probabilistic volumetric maps with the Wasserstein Distance*, §III-C)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from nbv_gym.metrics.wasserstein import PAPER_BLUR_LEVELS, blurred_reconstruction
from nbv_gym.reporting.verdicts import NOT_REPRODUCED, PARTLY, REPRODUCED
from nbv_gym.studies.wd_analysis import (
    deltas,
    informative,
    map_share,
    mean_medians,
    reconstruct,
    sample_cuboids,
)
from nbv_gym.studies.wd_report import _robust_grade, delta_table


def _one_voxel(n: int = 9) -> np.ndarray:
    truth = np.zeros((1, n, n, n), bool)
    truth[0, n // 2, n // 2, n // 2] = True
    return truth


def test_blur_of_one_occupied_voxel_is_the_gaussian_kernel():
    # kernel 5, σ = 1 voxel: 1D weights exp(−x²/2) for x = −2…2, normalised; 3D = their product
    w = np.array([math.exp(-(x**2) / 2) for x in range(-2, 3)])
    w /= w.sum()
    expected = np.zeros((9, 9, 9))
    expected[2:7, 2:7, 2:7] = w[:, None, None] * w[None, :, None] * w[None, None, :]
    blurred = blurred_reconstruction(_one_voxel(), 5, 1.0, 0.0, np.random.default_rng(0))[0]
    np.testing.assert_allclose(blurred, expected, rtol=1e-12, atol=1e-15)
    assert blurred[4, 4, 4] == pytest.approx(0.065266, abs=1e-6)  # (1 / 2.483731)³


@pytest.mark.parametrize("level", ["b1", "b2"])
def test_paper_blur_levels_leave_one_voxel_in_place(level):
    # σ = 0.07 or 0.08 voxel: the neighbour's weight exp(−1 / (2σ²)) < 1e-33
    size, sigma, _ = PAPER_BLUR_LEVELS[level]
    neighbour = math.exp(-1 / (2 * sigma**2))
    assert neighbour < 1e-33
    blurred = blurred_reconstruction(_one_voxel(), size, sigma, 0.0, np.random.default_rng(0))[0]
    assert blurred[4, 4, 4] == pytest.approx(1 / (1 + 2 * neighbour) ** 3, rel=1e-12)
    assert blurred[3, 4, 4] == pytest.approx(neighbour / (1 + 2 * neighbour) ** 3, rel=1e-6)


def test_b3_noise_is_uniform_within_its_amplitude_and_clipped():
    # b3: noise U(−0.1, 0.1) per voxel, then clipped to [0, 1]
    truth = np.zeros((1, 40, 40, 40), bool)
    truth[0, 20, 20, 20] = True
    rec = reconstruct(truth, "b3", np.random.default_rng(1))[0]
    empty = np.delete(rec.ravel(), np.ravel_multi_index((20, 20, 20), rec.shape))
    assert empty.min() == 0.0 and empty.max() <= 0.1 + 1e-12
    # half of U(−0.1, 0.1) is negative and clips to 0; the positive half is U(0, 0.1), mean 0.05
    assert np.mean(empty == 0.0) == pytest.approx(0.5, abs=0.01)
    assert empty[empty > 0].mean() == pytest.approx(0.05, abs=0.002)
    assert 0.9 - 1e-12 <= rec[20, 20, 20] <= 1.0


def test_random_reconstruction_is_uniform():
    rec = reconstruct(np.zeros((2, 10, 10, 10), bool), "random", np.random.default_rng(2))
    assert rec.min() >= 0 and rec.max() < 1
    assert rec.mean() == pytest.approx(0.5, abs=0.02) and rec.var() == pytest.approx(
        1 / 12, abs=0.005
    )


def test_informative_rule():
    cov = np.array([[0.0, 0.2, 1.0]])
    wd = np.array([3.0, 5.0, 7.0])
    cov_info, wd_info = informative(cov, wd, wd_star=5.0)
    assert cov_info.tolist() == [[False, True, True]]
    assert wd_info.tolist() == [True, False, False]  # strictly below WD*_occ


def _hand_made_map():
    """Three U_occ cuboids along x, each holding a 3 × 3 plate of ground truth: a perfect
    reconstruction, the plate moved 4 voxels (0.4 m, beyond every cov distance), and an
    unobserved cuboid."""
    gt = np.zeros((30, 10, 10), bool)
    for c in range(3):
        gt[10 * c + 2 : 10 * c + 5, 3:6, 4] = True
    prob = np.full(gt.shape, 0.12, np.float32)
    prob[0:10][gt[0:10]] = 0.97
    prob[12:15, 7:10, 4] = 0.97
    prob[20:30] = 0.5
    return prob, gt


def test_informative_share_on_hand_made_cuboids():
    prob, gt = _hand_made_map()
    share = map_share(prob, gt, 0.1, wd_star=5.0, count=10, rng=np.random.default_rng(0))
    assert (share.n_u_occ, share.n_observed, share.n_sampled) == (3, 2, 2)
    assert share.share_cov == (0.5, 0.5, 0.5, 0.5)  # the perfect cuboid only
    assert share.share_wd == 0.5  # the perfect cuboid: WD_occ ≈ 1 < 5; the moved one ≈ 16 > 5
    assert share.observed_fraction == pytest.approx(2 / 3)


def test_sample_cuboids_draws_distinct_candidates_reproducibly():
    candidates = np.zeros((4, 4, 4), bool)
    candidates[1:3, :, 2] = True  # 8 candidates
    first = sample_cuboids(candidates, 5, np.random.default_rng(3))
    again = sample_cuboids(candidates, 5, np.random.default_rng(3))
    assert len({tuple(i) for i in first}) == 5 and candidates[tuple(first.T)].all()
    np.testing.assert_array_equal(first, again)
    assert len(sample_cuboids(candidates, 50, np.random.default_rng(3))) == 8


def test_deltas_on_given_medians():
    assert deltas({"b1": 2.0, "b2": 2.5, "b3": 3.0}) == {"b2": 0.25, "b3": 0.5}
    mu = mean_medians([{"b1": 1.0, "b2": 2.0, "b3": 3.0}, {"b1": 3.0, "b2": 2.0, "b3": 5.0}])
    assert mu == {"b1": 2.0, "b2": 2.0, "b3": 4.0}
    assert deltas(mu) == {"b2": 0.0, "b3": 1.0}


def test_delta_table_averages_the_medians_of_a_world_type():
    rows = []
    for world, medians in (("pp1-trees", (1.0, 1.1, 1.2)), ("pp2-trees", (3.0, 3.1, 3.4))):
        for name, wd in zip(("b1", "b2", "b3", "random"), (*medians, 20.0), strict=True):
            rows.append({"world": world, "asset": "trees", "reconstruction": name, "wd_occ": wd}
                        | {f"cov_{k}": 1.0 for k in range(1, 5)})  # fmt: skip
    table = delta_table(pd.DataFrame(rows)).set_index("metric")
    # μ_b1 = 2.0, μ_b2 = 2.1, μ_b3 = 2.3
    assert table.loc["wd_occ", "delta_2"] == pytest.approx(0.05)
    assert table.loc["wd_occ", "delta_3"] == pytest.approx(0.15)
    assert table.loc["wd_occ", "paper_delta_3"] == pytest.approx(0.062)
    assert table.loc["cov_4", "delta_3"] == 0.0


@pytest.mark.parametrize(
    ("d2", "d3", "verdict"),
    [(0.0121, 0.0393, REPRODUCED), (0.001, 0.002, PARTLY), (0.05, 0.04, NOT_REPRODUCED)],
)
def test_table2_grades(d2, d3, verdict):
    assert _robust_grade(d2, d3, 0.0121, 0.0393) == verdict


def test_ideal_study_is_seeded_and_scores_ideal_far_below_random():
    from nbv_gym.studies.wd_analysis import RECONSTRUCTIONS, ground_truth, ideal_study
    from nbv_gym.worlds import load_world

    world = load_world("pp1-cuboids")
    truth = ground_truth(world, 0.1)
    first = ideal_study(world, truth, 6, seed=3)
    again = ideal_study(world, truth, 6, seed=3)
    np.testing.assert_array_equal(first.index, again.index)
    for name in RECONSTRUCTIONS:
        np.testing.assert_array_equal(first.wd[name], again.wd[name])
    assert first.wd["b3"].max() < first.wd["random"].min()
    assert first.wd_star == pytest.approx(first.wd["random"].mean())
    assert (first.cov["b1"] == 1.0).all()  # every ground-truth voxel kept at p > 0.8
