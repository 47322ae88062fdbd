"""``frontier-tour``: cluster the frontier, order the clusters by a tour over path costs from the
robot, go to the first stop.

Sources: "FUEL: Fast UAV exploration using incremental frontier structure and hierarchical
planning" (B. Zhou, Y. Zhang, X. Chen, S. Shen, IEEE Robotics and Automation Letters 2021) and
"TARE: A hierarchical framework for efficiently exploring complex 3D environments" (C. Cao,
H. Zhu, H. Choset, J. Zhang, Robotics: Science and Systems 2021): both order the exploration
targets by a travelling-salesman tour that starts at the robot and need not return (FUEL's
asymmetric TSP with a zero cost back to the start), then fly to its first target.

Here, on the goal grid (1 m cells, layers ``frontier``, ``valid`` and ``robot``):

1. clusters: the 8-connected components of the frontier goals;
2. a cluster's stop (its viewpoint): the member goal nearest its centroid (ties: the lowest index);
3. path costs: 8-connected shortest paths (1 m and √2 m steps) through the goal cells that are
   valid or hold known free space (layer ``free``) and the robot's cell, from the robot and from
   every stop; where the goal grid holds no such path (free space narrower than a goal cell),
   the straight-line distance;
4. the tour: the open path from the robot through every stop of least total length, found
   exactly (Held–Karp dynamic programming) over the :data:`MAX_EXACT` clusters whose stops are
   nearest the robot by path (FUEL's tour runs over all of them with a heuristic solver; the
   closest ones decide the first stop in practice);
5. the goal: the tour's first stop.

With no frontier goal left the goal is a uniformly random valid goal (as the paper's frontier
baselines do).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numba import njit
from scipy import ndimage

from nbv_gym.mapping.navigation import path_lengths
from nbv_gym.policies.nbv import observation_layer, uniform_choice

#: Clusters over which the tour is solved exactly (the nearest ones by path).
MAX_EXACT = 10


class FrontierTour:
    """The first stop of the shortest open tour from the robot over the frontier clusters, on
    the goal grid the agent view describes (``info["goal_grid_shape"]``, ``info["goal_cell_m"]``)."""

    observation_layers: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.shape = (0, 0)  # (nx, ny) of the goal grid, read from each decision's info
        self.cell_m = 1.0  # goal cell size, metres, likewise
        self.rng = np.random.default_rng()
        self.last_tour: list[int] = []  # goal indices of the stops of the last decision's tour

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the fallback's generator is seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)
        self.last_tour = []

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The goal index of the tour's first stop (module docstring)."""
        valid = np.asarray(info["action_mask"], bool).ravel()
        self.shape = (int(info["goal_grid_shape"][0]), int(info["goal_grid_shape"][1]))
        self.cell_m = float(info["goal_cell_m"])
        frontier = (observation_layer(observation, "frontier") > 0) & valid
        if not frontier.any():
            return uniform_choice(self.rng, np.flatnonzero(valid))
        robot = int(np.argmax(observation_layer(observation, "robot")))
        stops = cluster_stops(frontier.reshape(self.shape))
        passable = valid | (observation_layer(observation, "free") > 0)
        costs = self.path_costs(passable.reshape(self.shape), robot, stops)
        nearest = np.argsort(costs[0, 1:], kind="stable")[:MAX_EXACT]
        chosen = np.concatenate([[0], nearest + 1])
        order = shortest_open_tour(costs[np.ix_(chosen, chosen)])
        self.last_tour = [int(stops[nearest[i]]) for i in order]
        return self.last_tour[0]

    def path_costs(self, passable: np.ndarray, robot: int, stops: np.ndarray) -> np.ndarray:
        """(m + 1, m + 1) float64 path lengths (metres) between the robot (row and column 0)
        and the ``stops`` (goal indices) through the (nx, ny) bool ``passable`` goal cells; the
        straight line where they hold no path."""
        nodes = np.concatenate([[robot], stops])
        passable = passable.copy()
        passable.ravel()[robot] = True
        ny = self.shape[1]
        rows = [path_lengths(passable, (n // ny, n % ny), self.cell_m).ravel() for n in nodes]
        costs = np.array(rows)[:, nodes]
        xy = np.column_stack([nodes // ny, nodes % ny]) * self.cell_m
        straight = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
        return np.where(np.isfinite(costs), costs, straight)


def cluster_stops(frontier: np.ndarray) -> np.ndarray:
    """(m,) int64 goal indices of the stops of the 8-connected clusters of the (nx, ny) bool
    ``frontier``: per cluster (in label order), the member nearest its centroid."""
    labels, m = ndimage.label(frontier, structure=np.ones((3, 3), bool))
    flat = labels.ravel()
    members = np.flatnonzero(flat)
    ny = frontier.shape[1]
    xy = np.column_stack([members // ny, members % ny]).astype(np.float64)
    label = flat[members] - 1
    counts = np.bincount(label, minlength=m)
    centroid = np.column_stack([np.bincount(label, xy[:, a], m) for a in (0, 1)]) / counts[:, None]
    distance = np.hypot(*(xy - centroid[label]).T)
    order = np.lexsort((members, distance, label))  # by cluster, then distance, then index
    first = np.concatenate([[True], np.diff(label[order]) != 0])
    return members[order[first]].astype(np.int64)


def shortest_open_tour(costs: np.ndarray) -> list[int]:
    """The stops (1 … m, as indices 0 … m − 1) in the order of the least-cost open path from
    node 0 through every other node of the (m + 1, m + 1) float ``costs``; exact (Held–Karp),
    ties broken towards the lexicographically first order of the dynamic programme."""
    m = costs.shape[0] - 1
    if m == 1:
        return [0]
    return [int(i) for i in _held_karp(np.ascontiguousarray(costs, np.float64))]


@njit(cache=True)
def _held_karp(costs):  # noqa: C901 — a numba kernel: Held-Karp's subset DP in one loop nest
    """Order (0-based stop indices) of the least-cost open path 0 → all stops."""
    m = costs.shape[0] - 1
    full = (1 << m) - 1
    best = np.full((full + 1, m), np.inf)
    parent = np.full((full + 1, m), -1, np.int64)
    for j in range(m):
        best[1 << j, j] = costs[0, j + 1]
    for subset in range(1, full + 1):
        for j in range(m):
            if not (subset >> j) & 1 or best[subset, j] == math.inf:
                continue
            for k in range(m):
                if (subset >> k) & 1:
                    continue
                value = best[subset, j] + costs[j + 1, k + 1]
                bigger = subset | (1 << k)
                if value < best[bigger, k] - 1e-12:
                    best[bigger, k] = value
                    parent[bigger, k] = j
    last = 0
    for j in range(1, m):
        if best[full, j] < best[full, last] - 1e-12:
            last = j
    order = np.empty(m, np.int64)
    subset = full
    for position in range(m - 1, -1, -1):
        order[position] = last
        previous = parent[subset, last]
        subset ^= 1 << last
        last = previous
    return order
