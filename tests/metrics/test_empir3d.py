"""Empir3D against analytic cases, brute force, and the ablation pattern of Table I of *Empir3D: A Framework for Multi-Dimensional Point Cloud Assessment*."""

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
    assert chamfer == pytest.approx((d.min(axis=1).mean() + d.min(axis=0).mean()) / 2)
    assert hausdorff == pytest.approx(max(d.min(axis=1).max(), d.min(axis=0).max()))


def test_chamfer_of_a_shifted_copy_is_the_shift():
    a = _plane()
    chamfer, hausdorff = chamfer_hausdorff(a, a + [0.0, 0.0, 0.004])
    assert chamfer == pytest.approx(0.004) and hausdorff == pytest.approx(0.004)


def _voxel_layer(origin, corners=False):
    """A 10 × 10 layer of 0.1 m voxel centres (or low corners) above ``origin``, and a candidate:
    its first five rows plus five points one voxel higher (hand-computed scores below)."""
    offset = 0.0 if corners else 0.05
    i, j = np.meshgrid(np.arange(10), np.arange(10), indexing="ij")
    cells = np.stack([i.ravel(), j.ravel(), np.zeros(100, int)], 1)
    raised = np.stack([np.full(5, 5), np.arange(5), np.ones(5, int)], 1)
    cand = np.concatenate([cells[cells[:, 0] < 5], raised])
    to_m = lambda c: np.asarray(origin) + 0.1 * c + offset  # noqa: E731
    return to_m(cells), to_m(cand)


#: Q_c = 50 shared cells / 100; Q_t = 50 / 55; q_a: the 5 raised points are exactly ε from the
#: reference (s = ε each) → 1 − 5 ε / (55 ε); q_r: both clouds have nearest neighbours at 0.1 m.
LAYER_SCORES = (1.0, 1 - 5 / 55, 0.5, 50 / 55)


@pytest.mark.parametrize("corners", [False, True], ids=["voxel-centres", "voxel-corners"])
@pytest.mark.parametrize("origin", [(0.0, 0.0, 0.0), (-30.0, -30.0, 1.0)], ids=["at-0", "far"])
def test_structured_clouds_are_stable_under_tiny_shifts_and_float32(origin, corners):
    a, b = _voxel_layer(origin, corners)
    config = Empir3DConfig(0.1, 1.0)
    variants = {
        "float64": (a, b),
        "float32 candidate": (a, b.astype(np.float32)),
        "float32 both": (a.astype(np.float32), b.astype(np.float32)),
        "+1e-9": (a + 1e-9, b + 1e-9),
        "-1e-9": (a - 1e-9, b - 1e-9),
        "candidate -7.6e-7": (a, b - 7.6e-7),
        "reference +2e-6": (a + 2e-6, b),
    }
    for name, (ref, cand) in variants.items():
        result = empir3d(ref, cand, config)
        scores = (result.q_r, result.q_a, result.q_c, result.q_t)
        assert scores == pytest.approx(LAYER_SCORES, abs=1e-9), name


def test_cells_are_anchored_at_the_frame_origin_not_at_the_smallest_point():
    a, b = _voxel_layer((0.0, 0.0, 0.0))
    lone = np.array([[-0.049, 0.05, 0.05]])  # in cell (-1, 0, 0) whatever the other points
    result = empir3d(np.concatenate([a, lone]), b, Empir3DConfig(0.1, 1.0))
    assert result.q_c == pytest.approx(50 / 101)
    assert result.regions.index.min(axis=0).tolist() == [-1, 0, 0]
    assert result.regions.low_m.min(axis=0).tolist() == [-1.0, 0.0, 0.0]


def test_region_scores_match_a_brute_force_search():
    rng = np.random.default_rng(3)
    a = rng.random((400, 3)) * [2.0, 2.0, 0.5]
    b = np.concatenate([a[:250] + rng.normal(0, 0.03, (250, 3)), rng.random((60, 3))])
    result = empir3d(a, b, Empir3DConfig(0.1, 1.0))
    region_a, region_b = np.floor(a / 1.0), np.floor(b / 1.0)
    for r, index in enumerate(result.regions.index):
        ra, rb = a[(region_a == index).all(1)], b[(region_b == index).all(1)]
        if len(ra) < 2 or len(rb) < 2:
            assert np.isnan(result.regions.q_r[r]) and np.isnan(result.regions.q_a[r])
            continue
        spacing = [np.sort(cdist(c, c), axis=1)[:, 1].mean() for c in (ra, rb)]
        s = cdist(rb, ra).min(axis=1)
        q_a = 1 - s[s <= 0.1].sum() / (0.1 * len(rb))
        assert result.regions.q_r[r] == pytest.approx(min(spacing[0] / spacing[1], 1), rel=1e-3)
        assert result.regions.q_a[r] == pytest.approx(q_a, abs=1e-3)


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


def test_perf_chamfer_is_the_same_definition():
    from nbv_gym.perf.metrics import plain_chamfer

    rng = np.random.default_rng(1)
    a, b = rng.random((200, 3)), rng.random((150, 3))
    assert plain_chamfer(a, b) == pytest.approx(chamfer_hausdorff(a, b)[0])
