"""frontier-tour: its first stop is that of the optimal open tour a brute-force search finds."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from nbv_gym.policies.frontier_tour import FrontierTour, cluster_stops

SHAPE = (20, 20)


def octile(a: int, b: int) -> float:
    """8-connected path length between goals a and b of an open 20 × 20 field (1 m cells)."""
    dx, dy = abs(a // 20 - b // 20), abs(a % 20 - b % 20)
    return max(dx, dy) - min(dx, dy) + math.sqrt(2.0) * min(dx, dy)


def brute_force_first_stop(robot: int, stops: list[int]) -> tuple[int, float]:
    """The first stop of the least-cost open tour and the margin to the best tour starting
    elsewhere."""
    best: dict[int, float] = {}
    for order in itertools.permutations(stops):
        length = octile(robot, order[0]) + sum(map(octile, order[:-1], order[1:]))
        best[order[0]] = min(best.get(order[0], math.inf), length)
    ranked = sorted(best.items(), key=lambda item: item[1])
    margin = ranked[1][1] - ranked[0][1] if len(ranked) > 1 else math.inf
    return ranked[0][0], margin


def field(robot: int, clusters: list[list[int]]):
    """The observation and info of an open field (every goal valid but the robot's cell)."""
    n = SHAPE[0] * SHAPE[1]
    frontier, robot_layer = np.zeros(n, np.float32), np.zeros(n, np.float32)
    for cells in clusters:
        frontier[cells] = 1.0
    robot_layer[robot] = 1.0
    mask = np.ones(n, np.int8)
    mask[robot] = 0
    observation = {"frontier": frontier, "robot": robot_layer, "free": np.zeros(n, np.float32)}
    return observation, {"action_mask": mask, "goal_grid_shape": SHAPE, "goal_cell_m": 1.0}


@pytest.mark.parametrize("seed", range(12))
def test_first_stop_is_the_optimal_tours(seed):
    rng = np.random.default_rng(seed)
    n_clusters = int(rng.integers(2, 8))  # 2 … 7
    # single-cell or plus-shaped clusters (their stop is the centre), apart from each other
    centres = []
    while len(centres) < n_clusters:
        c = (int(rng.integers(2, 18)), int(rng.integers(2, 18)))
        if all(max(abs(c[0] - d[0]), abs(c[1] - d[1])) >= 4 for d in centres):
            centres.append(c)
    robot_cell = (int(rng.integers(0, 20)), int(rng.integers(0, 20)))
    if robot_cell in centres:
        pytest.skip("robot on a cluster")
    clusters = [[i * 20 + j] if k % 2 else [i * 20 + j, (i - 1) * 20 + j, (i + 1) * 20 + j,
                                             i * 20 + j - 1, i * 20 + j + 1]
                for k, (i, j) in enumerate(centres)]  # fmt: skip
    robot = robot_cell[0] * 20 + robot_cell[1]
    stops = [i * 20 + j for i, j in centres]
    expected, margin = brute_force_first_stop(robot, stops)
    if margin < 1e-6:
        pytest.skip("two optimal tours start at different stops")
    policy = FrontierTour()
    policy.reset(seed)
    observation, info = field(robot, clusters)
    assert policy.act(observation, info) == expected
    assert sorted(policy.last_tour) == sorted(stops)


def test_a_clusters_stop_is_the_member_nearest_its_centroid():
    frontier = np.zeros(SHAPE, bool)
    frontier[5, 2:9] = True  # a bar: centroid (5, 5)
    frontier[15, 15] = True
    assert sorted(cluster_stops(frontier).tolist()) == [5 * 20 + 5, 15 * 20 + 15]


def test_without_frontier_a_valid_goal():
    observation, info = field(0, [])
    info["action_mask"][:] = 0
    info["action_mask"][7] = 1
    assert FrontierTour().act(observation, info) == 7
