"""Sight lines and visibility against hand-drawn cases and an exact segment–box brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nbv_gym.core.grid import GridSpec
from nbv_gym.nbv.visibility import SightModel, credited_cells, crossed_cells, sight_lines

# A one-layer grid with the sensor at the layer's mid-height: every sight line is horizontal, so
# the cases below are drawn on squared paper.
FLAT = GridSpec((0.0, 0.0, 0.0), 1.0, (7, 7, 1))


def flat_visible(occluders, column=(3, 3), min_range=0.5, max_range=10.0):
    occluding = np.zeros(FLAT.shape, bool)
    for cell in occluders:
        occluding[cell] = True
    return credited_cells(occluding, column, FLAT, SightModel("sphere", 0.5, min_range, max_range))


@pytest.mark.parametrize(
    ("target", "zs", "expected"),
    [
        ((3, 0, 0), 0.22, [(1, 0, 0), (2, 0, 0)]),  # straight along x
        ((2, 2, 0), 0.22, [(1, 1, 0)]),  # the diagonal passes corners: no side cells
        ((3, 1, 0), 0.22, [(1, 0, 0), (2, 1, 0)]),  # y = 0.5 + (x − 0.5)/3 hits the corner (2, 1)
        ((0, 0, 4), 0.22, [(0, 0, 1), (0, 0, 2), (0, 0, 3)]),  # straight up
        ((1, 1, 3), 0.22, [(0, 0, 1), (1, 1, 1), (1, 1, 2)]),  # up, then the xy corner at t = 1/2
        ((-2, 1, 0), 0.5, [(-1, 0, 0), (-1, 1, 0)]),  # x = 0 at y = 0.75; y = 1 at x = −0.5
    ],
)
def test_crossed_cells_drawn_by_hand(target, zs, expected):
    assert crossed_cells(*target, zs).tolist() == [list(c) for c in expected]


def test_nothing_occludes_in_an_empty_grid():
    visible = flat_visible([])
    expected = np.ones(FLAT.shape, bool)
    expected[3, 3, 0] = False  # the sensor's own cell is closer than the minimum range
    assert np.array_equal(visible, expected)


def test_a_cell_behind_an_occluding_cell_is_hidden():
    # Sensor at (3.5, 3.5), occluder [4, 5] × [3, 4]. Sight lines through its interior (drawn by
    # hand): to (5, 3), (6, 3) straight; (5, 4) and (5, 2) cross it for x ∈ (4, 4.5); (6, 4), (6, 2)
    # for x ∈ (4, 5); (6, 5), (6, 1) for x ∈ (4, 4.25). The diagonals to (5, 5), (6, 6), (4, 4),
    # (5, 1), (6, 0) only touch its corners.
    visible = flat_visible([(4, 3, 0)])
    hidden = {(5, 3), (6, 3), (5, 4), (5, 2), (6, 4), (6, 2), (6, 5), (6, 1)}
    for i, j in itertools.product(range(7), range(7)):
        expected = (i, j) != (3, 3) and (i, j) not in hidden
        assert visible[i, j, 0] == expected, (i, j)
    assert visible[4, 3, 0]  # the occluding cell itself is visible: it is the surface


def test_the_sensor_cell_and_the_target_cell_do_not_occlude():
    visible = flat_visible([(3, 3, 0), (6, 3, 0)])
    assert visible[6, 3, 0] and visible[5, 3, 0] and visible[0, 0, 0]


def test_range_window():
    visible = flat_visible([], min_range=1.5, max_range=3.0)
    assert not visible[4, 3, 0]  # 1 m: too close
    assert not visible[4, 4, 0]  # √2 m < 1.5 m
    assert visible[5, 3, 0] and visible[5, 5, 0]  # 2 m and 2.83 m
    assert not visible[6, 3, 0]  # 3 m: the window is [min, max)


def segment_crosses_open_box(p, q, lo, hi, eps=1e-9):
    """Whether the segment p → q passes through the interior of the box [lo, hi] (slab method)."""
    t0, t1 = 0.0, 1.0
    for a in range(3):
        d = q[a] - p[a]
        if d == 0.0:
            if not lo[a] < p[a] < hi[a]:
                return False
            continue
        ta, tb = sorted(((lo[a] - p[a]) / d, (hi[a] - p[a]) / d))
        t0, t1 = max(t0, ta), min(t1, tb)
    return t1 - t0 > eps


def brute_force_visible(grid, occluding, column, height, min_range, max_range):
    sensor = np.array([*(grid.low[:2] + (np.asarray(column) + 0.5) * grid.res), height])
    sensor_cell = tuple(grid.index(sensor[None])[0])
    occluders = [tuple(c) for c in np.argwhere(occluding)]
    out = np.zeros(grid.shape, bool)
    for cell in itertools.product(*(range(s) for s in grid.shape)):
        centre = grid.centres(np.array([cell]))[0]
        if not min_range <= np.linalg.norm(centre - sensor) < max_range:
            continue
        out[cell] = not any(
            segment_crosses_open_box(
                sensor,
                centre,
                grid.low + np.array(o) * grid.res,
                grid.low + (np.array(o) + 1) * grid.res,
            )
            for o in occluders
            if o != cell and o != sensor_cell
        )
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_visibility_equals_an_exact_brute_force(seed):
    grid = GridSpec((-4.0, -3.0, 0.2), 1.0, (9, 8, 4))
    rng = np.random.default_rng(seed)
    occluding = rng.random(grid.shape) < 0.08
    column = (int(rng.integers(9)), int(rng.integers(8)))
    got = credited_cells(occluding, column, grid, SightModel("sphere", 0.42, np.sqrt(3), 7.0))
    want = brute_force_visible(grid, occluding, column, 0.42, np.sqrt(3), 7.0)
    assert np.array_equal(got, want)
    assert 0 < got.sum() < want.size  # the case is not trivial


def brute_force_physical(grid, occluding, column, model):
    """The ``physical`` model by brute force: every occluding cell in the range window and the
    field of view whose centre line crosses no other occluding cell (but the sensor's), and every
    cell in the range window that a segment from the sensor to that cell's centre or to a point a
    quarter cell from it along a diagonal passes through (the sensor's cell excepted)."""
    sensor = np.array([*(grid.low[:2] + (np.asarray(column) + 0.5) * grid.res), 0.42])
    sensor_cell = tuple(grid.index(sensor[None])[0])
    clear = brute_force_visible(grid, occluding, column, 0.42, model.min_range_m, 9e9)
    corners = [0.5 + 0.25 * np.array(d) for d in itertools.product((-1, 1), repeat=3)]
    out = np.zeros(grid.shape, bool)
    for surface in map(tuple, np.argwhere(occluding & clear)):
        centre = grid.centres(np.array([surface]))[0]
        offset = centre - sensor
        elevation = np.arcsin(offset[2] / np.linalg.norm(offset))
        in_range = model.min_range_m <= np.linalg.norm(offset) < model.max_range_m
        if not in_range or not model.elevation_min_rad <= elevation <= model.elevation_max_rad:
            continue
        out[surface] = True
        for end in [np.full(3, 0.5), *corners]:
            point = grid.low + (np.array(surface) + end) * grid.res
            for cell in itertools.product(*(range(s) for s in grid.shape)):
                distance = np.linalg.norm(grid.centres(np.array([cell]))[0] - sensor)
                if cell in (surface, sensor_cell) or not (
                    model.min_range_m <= distance < model.max_range_m
                ):
                    continue
                low = grid.low + np.array(cell) * grid.res
                if segment_crosses_open_box(sensor, point, low, low + grid.res):
                    out[cell] = True
    return out


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_physical_visibility_equals_an_exact_brute_force(seed):
    # Surfaces hide one another: a line ending on a surface behind another credits nothing.
    grid = GridSpec((-4.0, -3.0, 0.2), 1.0, (9, 8, 4))
    rng = np.random.default_rng(seed)
    occluding = rng.random(grid.shape) < 0.12
    column = (int(rng.integers(9)), int(rng.integers(8)))
    model = SightModel("physical", 0.42, np.sqrt(3), 7.0, -0.6, 0.6)
    got = credited_cells(occluding, column, grid, model)
    want = brute_force_physical(grid, occluding, column, model)
    assert np.array_equal(got, want)
    hidden = occluding & ~brute_force_visible(grid, occluding, column, 0.42, np.sqrt(3), 7.0)
    assert got.sum() > 0 and hidden.any()  # the case is not trivial


def test_sight_lines_are_sorted_by_dx_and_in_range():
    grid = GridSpec((-30.0, -30.0, 0.2), 1.0, (60, 60, 6))
    lines = sight_lines(grid, SightModel("sphere", 0.42, np.sqrt(3), 20.0))
    assert np.all(np.diff(lines.dx) >= 0)
    assert lines.range_m.min() >= np.sqrt(3) and lines.range_m.max() < 20.0
    for dx in (-20, 0, 7):
        rays = slice(lines.dx_start[dx + lines.reach], lines.dx_start[dx + lines.reach + 1])
        assert np.all(lines.dx[rays] == dx)
