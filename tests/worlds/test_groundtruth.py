"""Ground truth is exactly the voxels a surface passes through."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.grid import GridSpec
from nbv_gym.worlds import shapes, surface_voxels
from nbv_gym.worlds.groundtruth import GroundTruth
from tests.helpers import box_mesh, box_surface_voxels


def shell(low, high):
    """Lattice voxels on the boundary layer of the index box [low, high] (inclusive)."""
    ranges = [range(a, b + 1) for a, b in zip(low, high, strict=True)]
    return {
        v for v in itertools.product(*ranges) if any(v[a] in (low[a], high[a]) for a in range(3))
    }


def test_known_box_is_exactly_its_surface_voxels():
    # box x ∈ [-0.95, 1.05], y ∈ [-0.95, 1.05], z ∈ [0.05, 2.05]: faces inside voxel layers
    vertices, faces = shapes.cuboid()
    truth = surface_voxels(vertices + [0.05, 0.05, 0.05], faces, 0.1)
    assert set(map(tuple, truth.voxels)) == shell((-10, -10, 0), (10, 10, 20))


def test_a_face_on_a_voxel_boundary_occupies_the_voxels_on_its_upper_side():
    # the box stands on z = 0 exactly (its base in the ground plane marks nothing) and its lid
    # at z = 2.0 lies on the boundary between layers 19 and 20: it occupies layer 20
    vertices, faces = shapes.cuboid()
    truth = surface_voxels(vertices + [0.05, 0.05, 0.0], faces, 0.1)
    base = {(i, j, 0) for i in range(-9, 10) for j in range(-9, 10)}
    assert set(map(tuple, truth.voxels)) == shell((-10, -10, 0), (10, 10, 20)) - base


@pytest.mark.parametrize(
    "box",  # (x0, x1, y0, y1, z1) in 5 cm units, on z = 0
    [
        (-150, -90, -30, 30, 80),  # every face on the lattice (the half metre)
        (-120, -60, 40, 100, 40),  # on whole metres
        (21, 61, -59, -19, 41),  # every face midway between boundaries
        (10, 50, 11, 51, 30),  # x and the lid on the lattice, y not
        (6, 26, 14, 42, 34),  # on the lattice, none of them exact in binary (0.3, 0.7, …)
    ],
    ids=["half-metre", "metre", "midway", "mixed", "tenths"],
)
def test_a_box_gives_the_voxels_worked_out_alone(box):
    truth = surface_voxels(*box_mesh(box), 0.1, snap_m=1e-3)
    assert set(map(tuple, truth.voxels.tolist())) == box_surface_voxels(box)


def test_a_box_on_the_lattice_gives_its_counted_voxels():
    # a × b × h voxels: (a + 1)(b + 1)(h + 1) voxels meet the closed box, (a − 1)(b − 1) h
    # of them hold no wall nor lid (the base marks nothing)
    for (a, b, h), box in [((30, 30, 40), (-150, -90, -30, 30, 80)),
                           ((20, 20, 20), (-20, 20, 140, 180, 40))]:  # fmt: skip
        count = (a + 1) * (b + 1) * (h + 1) - (a - 1) * (b - 1) * h
        assert len(surface_voxels(*box_mesh(box), 0.1, snap_m=1e-3).voxels) == count


def test_the_voxels_do_not_depend_on_float_precision_or_whole_voxel_shifts():
    """The same boxes from float32 coordinates, and moved by whole voxels far from the origin,
    occupy the same voxels, moved by the same whole voxels."""
    boxes = [(-150, -90, -30, 30, 80), (6, 26, 14, 42, 34)]
    vertices, faces = shapes.concatenate([box_mesh(box) for box in boxes])
    plain = surface_voxels(vertices, faces, 0.1, snap_m=1e-3).voxels
    rounded = vertices.astype(np.float32).astype(np.float64)  # 0.7 → 0.69999998807907…
    assert not np.array_equal(surface_voxels(rounded, faces, 0.1).voxels, plain)
    assert np.array_equal(surface_voxels(rounded, faces, 0.1, snap_m=1e-3).voxels, plain)
    far = vertices + [500_000.0, 5_000_000.0, 0.0]
    moved = surface_voxels(far, faces, 0.1, snap_m=1e-3).voxels
    assert np.array_equal(moved - [5_000_000, 50_000_000, 0], plain)


def test_a_diagonal_triangle_marks_the_voxels_it_crosses():
    # the plane x + y = 0.25 between z ∈ [0, 0.1) crosses voxels with i + j ∈ {0, 1, 2}...
    triangle = np.array([[0.25, 0.0, 0.01], [0.0, 0.25, 0.01], [0.25, 0.0, 0.09]])
    truth = surface_voxels(triangle, np.array([[0, 1, 2]]), 0.1)
    # the segment from (0.25, 0) to (0, 0.25) passes through voxels (2,0),(1,0),(1,1),(0,1),(0,2)
    assert set(map(tuple, truth.voxels[:, :2])) == {(2, 0), (1, 0), (1, 1), (0, 1), (0, 2)}


def test_occupancy_grid_of_a_box():
    vertices, faces = shapes.cuboid()
    truth = surface_voxels(vertices + [0.05, 0.05, 0.05], faces, 0.1)
    grid = GridSpec.from_bounds((-1.0, -1.0, 0.0), (0.0, 1.0, 1.0), 0.1)
    occupied = truth.occupancy(grid)
    assert occupied.shape == (10, 20, 10)
    expected = {
        (i + 10, j + 10, k)
        for i, j, k in map(tuple, truth.voxels)
        if -10 <= i < 0 and -10 <= j < 10 and 0 <= k < 10
    }
    assert set(map(tuple, np.argwhere(occupied))) == expected


def test_occupancy_refuses_a_grid_off_the_lattice():
    truth = surface_voxels(*shapes.cuboid(), 0.1)
    with pytest.raises(ConfigError, match="lattice"):
        truth.occupancy(GridSpec((0.05, 0.0, 0.0), 0.1, (4, 4, 4)))
    with pytest.raises(ConfigError, match="lattice"):
        truth.occupancy(GridSpec((0.0, 0.0, 0.0), 0.2, (4, 4, 4)))


def test_grid_voxels_are_the_occupied_cells_of_the_grid_in_c_order():
    truth = GroundTruth(np.array([[-1, 0, 0], [0, 0, 0], [0, 3, 1], [2, -5, 0], [4, 1, 2]]), 0.1)
    np.testing.assert_array_equal(  # (-1, 0, 0), (2, -5, 0) and (4, 1, 2) lie outside
        truth.grid_voxels(GridSpec((0.0, 0.0, 0.0), 0.1, (4, 4, 4))), [[0, 0, 0], [0, 3, 1]]
    )
    np.testing.assert_array_equal(  # one voxel lower in x: (-1, 0, 0) is in, (4, 1, 2) too
        truth.grid_voxels(GridSpec((-0.1, 0.0, 0.0), 0.1, (6, 4, 4))),
        [[0, 0, 0], [1, 0, 0], [1, 3, 1], [5, 1, 2]],
    )
    with pytest.raises(ConfigError, match="lattice"):
        truth.grid_voxels(GridSpec((0.05, 0.0, 0.0), 0.1, (4, 4, 4)))


def test_surface_voxels_marked_in_slabs_equal_one_mask(monkeypatch):
    from nbv_gym.worlds import groundtruth, shapes

    poses = (((0.3, 0.2), 0.4), ((4.1, -1.7), 2.0))
    mesh = shapes.concatenate([shapes.place(shapes.helicoid(), *pose, 1.1, 0.9) for pose in poses])
    whole = groundtruth.surface_voxels(*mesh, 0.1)
    monkeypatch.setattr(groundtruth, "SLAB_VOXELS", 1)  # one x layer per slab
    np.testing.assert_array_equal(groundtruth.surface_voxels(*mesh, 0.1).voxels, whole.voxels)
    monkeypatch.setattr(groundtruth, "SLAB_VOXELS", 7 * 60 * 80)
    np.testing.assert_array_equal(groundtruth.surface_voxels(*mesh, 0.1).voxels, whole.voxels)
