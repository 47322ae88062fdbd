"""``QualityTracker.from_voxels``: the tracker of a sparse occupied-voxel list is the tracker of
the dense grid, bit for bit; lists it cannot trust are refused."""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.cuboids import occupied_cuboids
from nbv_gym.metrics.tracker import QualityTracker


def test_a_voxel_list_gives_the_dense_grids_tracker_exactly():
    rng = np.random.default_rng(5)
    gt = rng.random((40, 30, 20)) < 0.02
    gt[:10] = False
    sparse = QualityTracker.from_voxels(np.argwhere(gt).astype(np.int32), gt.shape)
    np.testing.assert_array_equal(sparse.u_occ, occupied_cuboids(gt, 10))
    prob = rng.choice(np.float32([0.12, 0.3, 0.5, 0.75, 0.97]), gt.shape)
    expected = astuple(QualityTracker(gt).update(prob))
    np.testing.assert_equal(astuple(sparse.update(prob)), expected)  # NaN == NaN


@pytest.mark.parametrize(
    ("voxels", "match"),
    [
        ([[1, 0, 0], [0, 0, 0]], "unique and in C order"),
        ([[0, 0, 0], [0, 0, 0]], "unique and in C order"),
        ([[0, 0, 10]], "lie in the grid of shape"),
        ([[0.0, 0.0, 0.0]], "integer indices"),
    ],
    ids=["unsorted", "duplicate", "outside", "float"],
)
def test_voxel_lists_that_do_not_fit_the_grid_are_refused(voxels, match):
    with pytest.raises(MetricInputError, match=match):
        QualityTracker.from_voxels(np.array(voxels), (10, 10, 10))
