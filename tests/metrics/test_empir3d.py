"""Empir3D against analytic cases, brute force, and the ablation pattern of Table I (004_…)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import cdist

from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.empir3d import Empir3DConfig, chamfer_hausdorff, empir3d


def _plane(step=0.02, size=1.0):
    axis = np.arange(0.0, size, step) + step / 2
    x, y = np.meshgrid(axis, axis, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, 0.05)], axis=1)


def test_identical_clouds_score_one_and_distance_zero():
    a = _plane()
    result = empir3d(a, a.copy(), Empir3DConfig(0.1, 0.5), distances=True)
    assert (result.q_r, result.q_a, result.q_c, result.q_t) == (1.0, 1.0, 1.0, 1.0)
    assert result.chamfer_m == 0.0 and result.hausdorff_m == 0.0


def test_offset_within_a_cell_lowers_accuracy_only():
    a = _plane()
    b = a + [0.0, 0.0, 0.03]  # every candidate point 3 cm from its reference, same ε-cells
    result = empir3d(a, b, Empir3DConfig(0.1, 0.5))
    assert result.q_a == pytest.approx(1 - 0.03 / 0.1)
    assert (result.q_r, result.q_c, result.q_t) == (1.0, 1.0, 1.0)


def test_half_density_halves_nothing_but_resolution():
    a = _plane(step=0.02)
    b = _plane(step=0.04)  # a subset-like cloud with twice the spacing
    result = empir3d(a, b, Empir3DConfig(0.1, 1.0))
    assert result.q_r == pytest.approx(0.5, rel=1e-9)


def test_chamfer_and_hausdorff_match_brute_force():
    rng = np.random.default_rng(0)
    a, b = rng.random((300, 3)), rng.random((200, 3)) + 0.1
    d = cdist(a, b)
    chamfer, hausdorff = chamfer_hausdorff(a, b)
    assert chamfer == pytest.approx(d.min(axis=1).sum() + d.min(axis=0).sum())
    assert hausdorff == pytest.approx(max(d.min(axis=1).max(), d.min(axis=0).max()))


def test_per_region_results_are_available():
    a = _plane(size=2.0)
    result = empir3d(a, a[a[:, 0] < 1.0], Empir3DConfig(0.1, 1.0))
    regions = result.regions
    assert len(regions.index) == 4
    assert sorted(regions.q_c.tolist()) == [0.0, 0.0, 1.0, 1.0]
    assert len(regions.rows()) == 4 and "q_t" in regions.rows()[0]


def test_empty_or_bad_clouds_raise():
    with pytest.raises(MetricInputError, match="candidate point cloud is empty"):
        empir3d(_plane(), np.zeros((0, 3)))
    with pytest.raises(MetricInputError, match=r"must be \(n, 3\)"):
        empir3d(np.zeros((5, 2)), _plane())


@pytest.mark.slow
def test_ablation_pattern_of_table_1():
    rng = np.random.default_rng(0)
    a = _scene(400_000, rng)
    config = Empir3DConfig(0.1, 5.0)
    down = empir3d(a, a[rng.random(len(a)) < 0.5], config)
    assert down.q_r < 0.8 and down.q_a == 1.0 and down.q_t == 1.0
    noisy = empir3d(a, a + rng.normal(0, 0.02, a.shape), config)
    assert noisy.q_a < 0.85
    low = a[:, 0].min()
    crop = empir3d(a, a[a[:, 0] < low + 0.4 * np.ptp(a[:, 0])], config)
    assert crop.q_c == pytest.approx(0.4, abs=0.05) and crop.q_t == 1.0
    shifted = empir3d(a, a + [0.15, 0.0, 0.0], config)
    assert shifted.q_t < 0.8 and down.q_t - shifted.q_t > 0.2


def _scene(count, rng):
    """Surfaces shaped like our assets on a regular layout: box shells and thin cylinders."""
    centres = np.stack(np.meshgrid(np.arange(-25, 26, 5.0), np.arange(-25, 26, 5.0)), -1).reshape(
        -1, 2
    )
    kind = rng.integers(0, 2, count)
    c = centres[rng.integers(0, len(centres), count)]
    t, h, s = rng.random((3, count))
    angle = 2 * np.pi * t
    cylinder = np.stack([c[:, 0] + 0.3 * np.cos(angle), c[:, 1] + 0.3 * np.sin(angle), 5 * h], 1)
    side = (4 * t).astype(int)
    u = 2 * s - 1
    bx = np.choose(side, [u, np.ones(count), u, -np.ones(count)])
    by = np.choose(side, [np.ones(count), u, -np.ones(count), u])
    box = np.stack([c[:, 0] + bx, c[:, 1] + by, 2 * h], 1)
    return np.where(kind[:, None] == 0, cylinder, box)
