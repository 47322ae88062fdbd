"""Navigation layer on crafted maps: projection, erosion, frontiers, path lengths, goals."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping import NavigationConfig, NavigationLayer
from nbv_gym.mapping.navigation import disc, path_lengths

R2 = math.sqrt(2.0)
# goals: x, y ∈ [-3, 3] at 1 m (6 × 6); nav cells: 0.5 m over [-3, 3] (12 × 12), cell a covers
# x ∈ [-3 + 0.5 a, -2.5 + 0.5 a).
GOALS = GridSpec.from_bounds((-3.0, -3.0, 0.2), (3.0, 3.0, 1.2), 1.0)


def layer() -> NavigationLayer:
    return NavigationLayer.from_config(NavigationConfig(), GOALS)


def known_free_west() -> tuple[np.ndarray, np.ndarray]:
    """Known and occupied nav cells: known free for x < 0 (columns 0–5), unknown elsewhere."""
    known = np.zeros((12, 12), bool)
    known[:6] = True
    return known, np.zeros((12, 12), bool)


def test_config_defaults_and_checks():
    config = NavigationConfig()
    assert (config.cell_m, config.robot_radius_m, config.cost_range_m) == (0.5, 0.5, 20.0)
    assert config.known_band_m == (-0.3, 1.0) and config.occupied_band_m == (0.2, 1.0)
    with pytest.raises(ConfigError, match="frontier_unknown_dilation_m"):
        NavigationConfig(frontier_unknown_dilation_m=0.5)


def test_disc_elements():
    assert disc(0.5, 0.5).sum() == 9  # the 3 × 3 block
    expected = np.ones((5, 5), bool)
    expected[[0, 0, 4, 4], [0, 4, 0, 4]] = False  # corners are 1.06 m away
    np.testing.assert_array_equal(disc(1.0, 0.5)[1:-1, 1:-1], expected)
    assert disc(1.0, 0.5).sum() == 21


def test_frontier_sits_where_known_free_meets_unknown():
    nav = layer()
    nav.project(*known_free_west())
    assert nav.discovered_fraction == pytest.approx(0.5)
    # eroded free: columns 1–4 of rows 1–10 (column 5 touches unknown, the border touches outside)
    expected_eroded = np.zeros((12, 12), bool)
    expected_eroded[1:5, 1:11] = True
    np.testing.assert_array_equal(nav.eroded_free, expected_eroded)
    # dilated unknown (1 m) reaches column 4; the 1 m border margin keeps rows 2–9
    expected = np.zeros((12, 12), bool)
    expected[4, 2:10] = True
    np.testing.assert_array_equal(nav.frontier_mask, expected)


def test_occupied_cells_push_the_frontier_back_by_the_margin():
    known, occupied = known_free_west()
    occupied[4, 6] = True  # an obstacle
    nav = layer()
    nav.project(known, occupied)
    # 1 m margin around (4, 6): rows 4–8 of column 4 (offset 2 rows = 0.75 m gap < 1 m)
    assert np.flatnonzero(nav.frontier_mask[4]).tolist() == [2, 3, 9]


def test_path_lengths_are_8_connected_distances_around_a_wall():
    passable = np.ones((5, 5), bool)
    passable[2, 0:4] = False  # a wall along row 2 with a gap at column 4
    d = path_lengths(passable, (0, 0), 0.5)
    # to (0, 4): 4 straight steps. To the gap (2, 4): +2 rows, +4 columns = 2 diagonal + 2
    # straight steps; from the gap to (4, 0): +2 rows, −4 columns, the same again.
    assert d[0, 4] == pytest.approx(2.0)
    assert d[4, 0] == pytest.approx(0.5 * (4 + 4 * R2))
    assert d[2, 4] == pytest.approx(0.5 * (2 + 2 * R2))
    assert np.isinf(d[2, 0])
    walled = passable.copy()
    walled[2, 4] = False
    assert np.isinf(path_lengths(walled, (0, 0), 0.5)[4, 0])


@pytest.mark.parametrize("density", [0.55, 0.8, 1.0])
def test_path_lengths_equal_scipys_dijkstra_bit_for_bit(density):
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    rng = np.random.default_rng(int(density * 100))
    passable = rng.random((40, 30)) < density
    start = (17, 11)
    n = passable.size
    rows, cols, weights = [], [], []
    index = np.arange(n).reshape(passable.shape)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            if di or dj:  # an edge into every passable neighbour (the start is always a source)
                a = index[max(0, -di) : passable.shape[0] - max(0, di),
                          max(0, -dj) : passable.shape[1] - max(0, dj)]  # fmt: skip
                b = a + di * passable.shape[1] + dj
                into = passable.ravel()[b]
                rows += a[into].tolist()
                cols += b[into].tolist()
                weights += [0.5 * (R2 if di and dj else 1.0)] * int(into.sum())
    graph = coo_matrix((weights, (rows, cols)), shape=(n, n)).tocsr()
    expected = dijkstra(graph, indices=index[start]).reshape(passable.shape)
    np.testing.assert_array_equal(path_lengths(passable, start, 0.5), expected)


def test_goals_valid_costs_and_frontier_goals():
    nav = layer()
    nav.update(*known_free_west(), robot_xy=(-1.5, -1.5))  # goal (1, 1), nav cell (3, 3)
    assert nav.robot_goal == 1 * 6 + 1
    mask = nav.goal_mask().reshape(6, 6)
    # goal (i, j) has centre (-2.5 + i, -2.5 + j) and nav cell (2i + 1, 2j + 1); eroded free
    # needs 2i + 1 ≤ 4, 1 ≤ 2j + 1 ≤ 10; the 1 m border margin drops i, j ∈ {0, 5}; the robot's own
    # goal is excluded.
    expected = np.zeros((6, 6), bool)
    expected[1, 1:5] = True
    expected[1, 1] = False
    np.testing.assert_array_equal(mask, expected)
    length = nav.goal_path_length().reshape(6, 6)
    assert length[1, 4] == pytest.approx(3.0)  # 6 straight steps along y
    cost = nav.goal_cost().reshape(6, 6)
    assert cost[1, 4] == pytest.approx(3.0 / 20.0)
    assert cost[3, 3] == 1.0  # invalid
    # frontier column 4 touches the nav cells (3, ·) of goals (1, ·), rows 2–9 → goal rows 1–4
    np.testing.assert_array_equal(nav.frontier_goal_mask().reshape(6, 6), expected)


def test_excluded_goals_are_invalid_everywhere_until_cleared():
    nav = layer()
    nav.update(*known_free_west(), robot_xy=(-1.5, -1.5))
    before = nav.goal_mask().copy()
    teammates = np.array([1 * 6 + 2, 1 * 6 + 4])  # two valid frontier goals
    assert before[teammates].all()
    nav.exclude_goals(teammates)
    after = nav.goal_mask()
    assert not after[teammates].any() and not nav.frontier_goal_mask()[teammates].any()
    np.testing.assert_array_equal(after | np.isin(np.arange(36), teammates), before)
    assert (nav.goal_cost()[teammates] == 1.0).all()
    assert not nav.goal_mask(limited=False)[teammates].any()
    nav.plan(np.array([-1.5, -1.5]))  # a new plan keeps them out
    assert not nav.goal_mask()[teammates].any()
    nav.clear()
    nav.update(*known_free_west(), robot_xy=(-1.5, -1.5))
    np.testing.assert_array_equal(nav.goal_mask(), before)


def test_bad_inputs_are_rejected():
    with pytest.raises(ConfigError, match="divide"):
        NavigationLayer.from_config(NavigationConfig(cell_m=0.3), GOALS)
    with pytest.raises(NbvGymError, match="shape"):
        layer().project(np.zeros((6, 6), bool), np.zeros((6, 6), bool))


@pytest.mark.parametrize(("escape_m", "reachable"), [(0.5, False), (2.0, True)])
def test_a_robot_hemmed_in_by_obstacles_escapes_through_free_cells(escape_m, reachable):
    # all known and free but for two walls at nav rows 6 and 8 (y cells 2–8); the robot stands
    # between them in cell (7, 5), where erosion leaves no free cell. Within 2 m it can walk along
    # row 7 and round the walls' end at column 9, never through a wall.
    known = np.ones((12, 12), bool)
    occupied = np.zeros((12, 12), bool)
    occupied[6, 2:9] = True
    occupied[8, 2:9] = True
    nav = NavigationLayer.from_config(NavigationConfig(escape_radius_m=escape_m), GOALS)
    nav.update(known, occupied, robot_xy=(0.75, -0.25))  # nav cell (7, 5)
    assert not nav.eroded_free[7, 5]
    assert nav.goal_mask().any() == reachable
    if reachable:
        # goal (1, 4): nav cell (3, 9). Path (7, 5) → (7, 8): 3 steps; → (6, 9) diagonal; →
        # (5, 9) (free, 1.9 m from the robot's cell: in the zone), (4, 9) (eroded free), (3, 9).
        expected = (3 + 3) * 0.5 + R2 * 0.5
        assert nav.goal_path_length()[1 * 6 + 4] == pytest.approx(expected)


def test_reprojecting_around_changed_cells_equals_a_full_projection():
    """Patches of random known/occupied changes, each reprojected only around the changed cells
    (the exploration state's per-scan path), give the layers a full projection gives, exactly."""
    rng = np.random.default_rng(4)
    grid = GridSpec((-20.0, -20.0, 0.2), 1.0, (40, 40, 6))
    nav, full = (NavigationLayer.from_config(NavigationConfig(), grid) for _ in range(2))
    for step in range(30):
        i0, j0 = rng.integers(0, 80, 2)
        size = rng.integers(1, 12, 2)
        i, j = np.meshgrid(np.arange(i0, min(i0 + size[0], 80)),
                           np.arange(j0, min(j0 + size[1], 80)), indexing="ij")  # fmt: skip
        i, j = i.ravel(), j.ravel()
        nav.known[i, j] = rng.random(len(i)) < 0.9
        nav.occupied[i, j] = nav.known[i, j] & (rng.random(len(i)) < 0.1 * (step % 3))
        nav.reproject((i, j))
        nav.plan(np.array([0.3, -0.2]))
        full.update(nav.known.copy(), nav.occupied.copy(), np.array([0.3, -0.2]))
        np.testing.assert_array_equal(nav.eroded_free, full.eroded_free)
        np.testing.assert_array_equal(nav.frontier_mask, full.frontier_mask)
        np.testing.assert_array_equal(nav.goal_fractions, full.goal_fractions)
        np.testing.assert_array_equal(nav.frontier_goal_mask(), full.frontier_goal_mask())
        np.testing.assert_array_equal(nav.goal_cost(), full.goal_cost())
    assert full.frontier_mask.any() and full.eroded_free.any() and full.goal_fractions[2].any()
