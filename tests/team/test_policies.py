"""Team policies: each robot its own single-robot policy, and the coordinated utility frontier."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.team.policies import EachRobot, TeamPolicyError, UtilityFrontier, load_team_policy
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
