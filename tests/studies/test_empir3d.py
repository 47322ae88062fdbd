"""Each Empir3D ablation (*Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment*, Table I) on small crafted clouds whose scores are computed by hand.

Clouds sit at exact binary coordinates with ε = 1 m and one region (r = 100 m), so every point's
ε-cell is unambiguous and the scores are simple fractions.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.metrics.empir3d import Empir3DConfig
from nbv_gym.reporting.verdicts import NOT_REPRODUCED, PARTLY, REPRODUCED
from nbv_gym.studies.empir3d_analysis import (
    ABLATIONS,
    PAPER_TABLE_I,
    add_noise,
    classify,
    crop,
    downsample,
    run_ablations,
    score,
    shift,
    verdicts,
)

CONFIG = Empir3DConfig(epsilon_m=1.0, region_m=100.0)
RNG = np.random.default_rng(0)


def _scores(reference, candidate):
    return score(reference, candidate, CONFIG, None).scores


def _line(n: int = 100) -> np.ndarray:
    """n points 1 m apart along x, at cell centres (one point per cell)."""
    return np.stack([np.arange(n) + 0.5, np.full(n, 0.5), np.full(n, 0.5)], axis=1)


def _plane(n: int = 10) -> np.ndarray:
    """n × n points 1 m apart in the z = 0.5 plane, at cell centres."""
    x, y = np.meshgrid(np.arange(n) + 0.5, np.arange(n) + 0.5, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.full(n * n, 0.5)], axis=1)


def test_downsampling_halves_coverage_and_lowers_resolution_only():
    line = _line()
    kept = downsample(line, np.random.default_rng(1), fraction=0.5)
    assert len(kept) == 50 and len(np.unique(kept[:, 0])) == 50
    assert np.isin(kept[:, 0], line[:, 0]).all()
    s = _scores(line, kept)
    # the candidate's mean nearest-neighbour distance, by hand from the gaps between kept points
    gaps = np.diff(np.sort(kept[:, 0]))
    nearest = np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])
    assert s["q_r"] == pytest.approx(1.0 / nearest.mean())
    assert (s["q_a"], s["q_c"], s["q_t"]) == (1.0, 0.5, 1.0)


def test_noise_costs_accuracy_by_the_mean_displacement_only():
    # points 3 m apart at cell centres: σ = 0.1 m never leaves a cell (5σ to a face) nor finds
    # another point; Q_a = 1 − E|d| / ε with E|d| = 2σ√(2/π) (Maxwell mean)
    grid = np.stack(np.meshgrid(*(np.arange(13) * 3.0 + 0.5,) * 3, indexing="ij"), -1)
    points = grid.reshape(-1, 3)[:2000]
    noisy = add_noise(points, np.random.default_rng(2), sigma_m=0.1)
    s = _scores(points, noisy)
    assert s["q_a"] == pytest.approx(1 - 0.2 * math.sqrt(2 / math.pi), abs=0.006)
    assert (s["q_c"], s["q_t"], s["q_r"]) == (1.0, 1.0, 1.0)


@pytest.mark.parametrize("axis", [0, 1])
def test_crop_to_40_percent_keeps_40_percent_of_the_cells(axis):
    plane = _plane()
    kept = crop(plane, RNG, axis=axis, fraction=0.4)
    # extent 0.5 … 9.5: keep ≤ 0.5 + 0.4 · 9 = 4.1, i.e. 4 of the 10 rows
    assert len(kept) == 40 and kept[:, axis].max() == 3.5
    assert _scores(plane, kept) == {"q_r": 1.0, "q_a": 1.0, "q_c": 0.4, "q_t": 1.0}


def test_shift_by_half_a_cell_makes_artifacts_where_points_cross_a_face():
    # four points far apart (≥ 9.5 m); +0.5 m in x: 0.0 → 0.5 and 10.25 → 10.75 stay in their
    # cells, 20.625 → 21.125 crosses into cell 21; 30.375 → 30.875 stays
    points = np.array([[0.0, 0.0, 0.0], [10.25, 0.0, 0.0], [20.625, 0.0, 0.0], [30.375, 0.0, 0.0]])
    moved = shift(points, RNG, offset_m=(0.5, 0.0, 0.0))
    s = _scores(points, moved)
    # every moved point is 0.5 m from its original: Q_a = 1 − 4 · 0.5 / (1 m · 4)
    assert s["q_a"] == pytest.approx(0.5)
    assert (s["q_c"], s["q_t"]) == (0.75, 0.75)
    assert s["q_r"] == pytest.approx(1.0)  # the spacing is unchanged


def test_ablations_follow_table_one_and_are_seeded():
    assert [a.value for a in ABLATIONS] == list(PAPER_TABLE_I)
    diagonal = ABLATIONS[-1].degrade(np.zeros((1, 3)), RNG)[0]
    assert math.hypot(diagonal[0], diagonal[1]) == pytest.approx(0.282)
    plane = _plane()
    first = run_ablations(plane, CONFIG, np.random.default_rng(5))
    again = run_ablations(plane, CONFIG, np.random.default_rng(5))
    assert [r.scores for r in first[1]] == [r.scores for r in again[1]]
    assert first[0].scores == {"q_r": 1.0, "q_a": 1.0, "q_c": 1.0, "q_t": 1.0}
    assert len(verdicts(*first)) == len(ABLATIONS)


@pytest.mark.parametrize(
    ("fallen", "target", "verdict"),
    [
        ({"q_r": 0.13, "q_a": 0.0, "q_c": 0.07, "q_t": 0.0}, "q_r", REPRODUCED),  # Uniform 75 %
        ({"q_r": 0.09, "q_a": 0.16, "q_c": 0.08, "q_t": 0.23}, "q_a", PARTLY),  # σ = 0.01
        ({"q_r": 0.02, "q_a": 0.29, "q_c": 0.38, "q_t": 0.38}, "q_t", REPRODUCED),  # tie
        ({"q_r": 0.0, "q_a": 0.3, "q_c": 0.0, "q_t": 0.01}, "q_t", NOT_REPRODUCED),
    ],
)
def test_verdict_rule(fallen, target, verdict):
    assert classify(fallen, target) == verdict
