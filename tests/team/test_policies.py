"""Team policies: each robot its own single-robot policy, the coordinated utility frontier and the
assignment of frontier goals of least summed cost."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.team.policies import (
    EachRobot,
    HungarianFrontier,
    TeamPolicyError,
    UtilityFrontier,
    assign_goals,
    load_team_policy,
)
from nbv_gym.team.simulator import robot_seed

N_GOALS = 10 * 10


def info(busy: bool, teammate_goals=(), mask=None) -> dict:
    mask = np.ones(N_GOALS + 1, np.int8) if mask is None else mask
    mask[-1] = 0
    if busy:
        mask = np.zeros(N_GOALS + 1, np.int8)
        mask[-1] = 1
    return {"busy": busy, "action_mask": mask, "teammate_goals": np.array(teammate_goals),
            "goal_grid_shape": (10, 10), "goal_cell_m": 1.0}  # fmt: skip


def observation(frontier: list[int], cost: float = 0.1) -> dict:
    layer = np.zeros(N_GOALS, np.float32)
    layer[frontier] = 1.0
    return {"frontier": layer, "cost": np.full(N_GOALS, cost, np.float32)}


def test_utility_frontier_avoids_frontier_goals_near_a_teammates_goal():
    policy = UtilityFrontier(range_m=5.0)
    near, far = 22, 88  # cells (2, 2) and (8, 8); the teammate heads for (2, 3)
    observations = {"robot_0": observation([near, far]), "robot_1": observation([])}
    infos = {"robot_0": info(False, teammate_goals=[23]), "robot_1": info(True)}
    assert policy.act(observations, infos) == {"robot_0": far, "robot_1": N_GOALS}
    infos["robot_0"] = info(False)  # no teammate goal: the lower index of equal scores
    assert policy.act(observations, infos)["robot_0"] == near


def test_utility_frontier_without_frontier_takes_the_cheapest_valid_goal():
    cost = np.linspace(1.0, 0.0, N_GOALS).astype(np.float32)
    mask = np.zeros(N_GOALS + 1, np.int8)
    mask[[3, 40]] = 1
    observations = {"robot_0": {"frontier": np.zeros(N_GOALS, np.float32), "cost": cost}}
    assert UtilityFrontier().act(observations, {"robot_0": info(False, mask=mask)}) == {
        "robot_0": 40
    }


def test_each_robot_runs_its_own_copy_seeded_per_robot():
    team = load_team_policy("random-free", 3)
    assert isinstance(team, EachRobot) and len({id(p) for p in team.policies}) == 3
    team.reset(11)
    draws = [p.rng.integers(1 << 30) for p in team.policies]
    expected = [np.random.default_rng(robot_seed(11, k)).integers(1 << 30) for k in range(3)]
    assert draws == expected and robot_seed(11, 0) == 11 and len(set(draws)) == 3
    observations = {"robot_0": observation([5]), "robot_1": observation([])}
    mask = np.zeros(N_GOALS + 1, np.int8)
    mask[5] = 1
    actions = team.act(observations, {"robot_0": info(False, mask=mask), "robot_1": info(True)})
    assert actions == {"robot_0": 5, "robot_1": N_GOALS}


def hungarian_case(seed: int, n_robots: int = 3, n_frontier: int = 5):
    """Robots that all decide now, random path costs to ``n_frontier`` frontier goals (one goal
    unreachable for robot 1), as the team env gives them."""
    rng = np.random.default_rng(seed)
    goals = rng.choice(N_GOALS, n_frontier, replace=False)
    agents = [f"robot_{k}" for k in range(n_robots)]
    observations, infos = {}, {}
    for k, agent in enumerate(agents):
        cost = np.full(N_GOALS, 5.0, np.float32)
        cost[goals] = rng.uniform(0.1, 2.0, n_frontier)
        valid = np.ones(N_GOALS, np.int8)
        if k == 1:
            valid[goals[0]] = 0
        frontier = np.zeros(N_GOALS, np.float32)
        frontier[goals] = 1.0
        observations[agent] = {"cost": cost, "valid": valid, "frontier": frontier}
        infos[agent] = {**info(k > 0, mask=np.append(valid, 0)), "decides_now": True}
    return agents, goals, observations, infos


def brute_force(agents, goals, observations) -> tuple[int, ...]:
    """The assignment of least summed cost over every ordered choice of distinct goals."""
    best, best_cost = (), np.inf
    for chosen in itertools.permutations(goals, len(agents)):
        if not all(observations[a]["valid"][g] for a, g in zip(agents, chosen, strict=True)):
            continue
        total = sum(float(observations[a]["cost"][g]) for a, g in zip(agents, chosen, strict=True))
        if total < best_cost:
            best, best_cost = tuple(int(g) for g in chosen), total
    return best


@pytest.mark.parametrize("seed", range(6))
def test_hungarian_frontier_picks_the_cost_minimal_assignment_one_robot_at_a_time(seed):
    agents, goals, observations, infos = hungarian_case(seed)
    expected = brute_force(agents, goals, observations)
    policy, chosen = load_team_policy("hungarian-frontier", 3), []
    for k, agent in enumerate(agents):  # each decides in turn, its teammates' goals reserved
        for other in agents[k:]:
            mask = np.append(observations[other]["valid"], 0)
            mask[chosen] = 0
            infos[other] = {**info(other != agent, mask=mask), "decides_now": True}
        actions = policy.act({a: observations[a] for a in agents[k:]},
                             {a: infos[a] for a in agents[k:]})  # fmt: skip
        assert [a for a, g in actions.items() if g != N_GOALS] == [agent]
        chosen.append(actions[agent])
    assert tuple(chosen) == expected and len(set(chosen)) == 3


def test_hungarian_frontier_beats_each_robot_taking_its_nearest():
    cost = {"robot_0": {22: 0.1, 88: 0.3}, "robot_1": {22: 0.2, 88: 1.5}}  # greedy: 0.1 + 1.5
    observations, infos = {}, {}
    for k, agent in enumerate(cost):
        layer = np.full(N_GOALS, 5.0, np.float32)
        layer[list(cost[agent])] = list(cost[agent].values())
        frontier = np.zeros(N_GOALS, np.float32)
        frontier[[22, 88]] = 1.0
        observations[agent] = {"cost": layer, "valid": np.ones(N_GOALS, np.int8),
                               "frontier": frontier}  # fmt: skip
        infos[agent] = {**info(k > 0), "decides_now": True}
    assert HungarianFrontier().act(observations, infos)["robot_0"] == 88  # 0.3 + 0.2
    infos["robot_1"]["decides_now"] = False  # robot 1 drives: robot 0 alone takes its nearest
    assert HungarianFrontier().act(observations, infos)["robot_0"] == 22


def test_hungarian_frontier_leaves_no_robot_two_goals_with_fewer_goals_than_robots():
    cost = np.array([[1.0, 2.0], [0.5, 0.1], [0.2, 0.3]])
    assigned = assign_goals(cost, np.ones_like(cost, bool))
    assert sorted(assigned[assigned >= 0].tolist()) == [0, 1] and (assigned == -1).sum() == 1
    assert assigned.tolist() == [-1, 1, 0]  # 0.1 + 0.2, the least of the six
    valid = np.array([[True, False], [False, False], [True, False]])
    assert assign_goals(cost, valid).tolist() == [-1, -1, 0]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"beta": float("nan")}, "beta must be a finite number ≥ 0"),
        ({"beta": -1.0}, "beta must be"),
        ({"range_m": 0.0}, "range_m must be a finite number > 0"),
        ({"range_m": float("inf")}, "range_m must be"),
    ],
)
def test_utility_frontier_refuses_weights_that_rank_nothing(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        UtilityFrontier(**kwargs)


def test_each_robot_without_policies_is_refused():
    with pytest.raises(TeamPolicyError, match="one single-robot policy per robot, got none"):
        EachRobot([])
