"""The team environment: PettingZoo's parallel API, Gymnasium's space checks per robot, the
event clock, the goal rule and bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from gymnasium.utils.passive_env_checker import (
    check_action_space,
    check_obs,
    check_observation_space,
)
from pettingzoo.test import parallel_api_test

from nbv_gym.core.errors import ConfigError
from nbv_gym.policies import load_policy
from nbv_gym.simulator import InvalidActionError, ResetNeededError
from nbv_gym.team import EachRobot, TeamEnv, run_team_episode
from nbv_gym.team.policies import TeamPolicyError

WORLD = "pp1-cuboids"
#: A short budget keeps the episodes small (each robot takes a few scans).
BUDGET_S = 60.0


@pytest.fixture(scope="module", params=[2, 3, 4], ids=lambda n: f"{n}-robots")
def env(request) -> TeamEnv:
    return TeamEnv(world=WORLD, n_robots=request.param, time_budget_s=BUDGET_S)


def play(env: TeamEnv, seed: int, busy_action=None):
    """One episode choosing each deciding robot's lowest valid goal; every step's
    (observations, infos) as it was when the actions were chosen, and the actions."""
    observations, infos = env.reset(seed=seed)
    history = []
    while env.agents:
        actions = {}
        for agent in env.agents:
            mask = infos[agent]["action_mask"]
            busy = infos[agent]["busy"]
            chosen = int(np.flatnonzero(mask)[0])
            actions[agent] = busy_action if busy and busy_action is not None else chosen
        history.append((observations, infos, actions))
        observations, _, _, _, infos = env.step(actions)
    return history


def test_pettingzoo_parallel_api_test_passes_with_warnings_as_errors(env):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parallel_api_test(env, num_cycles=1000)


def test_each_robots_spaces_and_observations_pass_gymnasiums_checks(env):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        observations, _ = env.reset(seed=1)
        for agent in env.possible_agents:
            check_observation_space(env.observation_space(agent))
            check_action_space(env.action_space(agent))
            check_obs(observations[agent], env.observation_space(agent), "reset")
        actions = {a: env.action_space(a).sample() for a in env.agents}
        observations, *_ = env.step(actions)
        for agent in observations:
            check_obs(observations[agent], env.observation_space(agent), "step")
        assert env.state() in env.state_space


def test_one_robot_decides_per_step_and_a_busy_robots_action_is_ignored(env):
    played = play(env, seed=2)
    for _, infos, _ in played:
        deciding = [a for a, info in infos.items() if not info["busy"]]
        assert len(deciding) == 1
        for info in infos.values():
            carry_on_only = np.flatnonzero(info["action_mask"]).tolist() == [env.carry_on]
            assert carry_on_only == info["busy"]
    scans = [(s.robot, s.time_s, s.q) for s in env.sim.scans]
    play(env, seed=2, busy_action=7)  # any action of a busy robot: ignored
    assert [(s.robot, s.time_s, s.q) for s in env.sim.scans] == scans


def test_the_team_clock_charges_each_robots_own_drives_and_scans(env):
    play(env, seed=3)
    effort, n = env.sim.effort, len(env.possible_agents)
    scans = env.sim.scans
    assert [s.time_s for s in scans[:n]] == [0.0] * n  # the first scans, at the start
    times = [s.time_s for s in scans]
    assert times == sorted(times)
    for k, robot in enumerate(env.sim.robots):
        own = [s for s in scans if s.robot == k]
        path = np.cumsum([s.path_length_m for s in own])
        expected = [effort.elapsed_s(p, i) for i, p in enumerate(path)]
        assert [s.time_s for s in own] == pytest.approx(expected, rel=1e-12)
        assert robot.elapsed_s(effort) == pytest.approx(expected[-1], rel=1e-12)
        assert robot.elapsed_s(effort) <= BUDGET_S
        assert env.sim.stopped[k].startswith("time budget spent")
    latest = max(r.elapsed_s(effort) for r in env.sim.robots)
    assert env.sim.time_s == latest == times[-1]


def test_no_two_robots_aim_at_one_goal_and_a_teammates_goal_is_refused(env):
    for observations, infos, _ in play(env, seed=4):
        for agent, info in infos.items():
            goals = [info["goal"], *info["teammate_goals"]]
            assert len(set(goals)) == len(goals) == len(env.possible_agents)
            assert not info["action_mask"][info["teammate_goals"]].any()
            if not info["busy"]:
                assert not observations[agent]["valid"][info["teammate_goals"]].any()
    _, infos = env.reset(seed=4)
    assert all(info["decides_now"] for info in infos.values())  # all at once, one at a time
    deciding = next(a for a, info in infos.items() if not info["busy"])
    teammate = int(infos[deciding]["teammate_goals"][0])
    with pytest.raises(InvalidActionError, match="a teammate stands on it or drives to it"):
        env.step({deciding: teammate})


def test_teammates_rows_say_where_each_teammate_is_and_goes(env):
    observations, infos = env.reset(seed=5)
    deciding = next(a for a, info in infos.items() if not info["busy"])
    goal = int(np.flatnonzero(infos[deciding]["action_mask"][:-1])[0])
    observations, *_ = env.step({deciding: goal})
    half = env.sim.shared.goal_grid.high[:2]
    x, y = env.sim.shared.goal_centres[goal]
    other = next(a for a in observations if a != deciding)
    row = observations[other]["teammates"][env.possible_agents.index(deciding)]
    assert row[2:4] == pytest.approx([x / half[0], y / half[1]])
    assert 0 < row[4] <= 1 and row[5] == 1.0


def test_robots_start_on_distinct_free_cells_nearest_the_start(env):
    starts = [(r.start.x, r.start.y) for r in env.sim.robots]
    expected = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (-1.0, 0.0)]
    assert starts == expected[: len(starts)]


def test_a_finished_episode_and_a_step_before_reset_ask_for_a_reset():
    fresh = TeamEnv(world=WORLD, n_robots=2, time_budget_s=BUDGET_S)
    with pytest.raises(ResetNeededError, match="reset"):
        fresh.step({"robot_0": 0})
    play(fresh, seed=0)
    with pytest.raises(ResetNeededError, match="reset"):
        fresh.step({})


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_robots": 0}, "at least 1 robot, got 0"),
        ({"n_robots": 2.0}, "expected an integer"),
        ({"n_robots": 10}, "10 robots, but world pp1-cuboids has 9 free start points"),
        ({"n_robots": 2, "start_xy_m": [(0.0, 0.0)]}, r"one \(x, y\) per robot \(2\), got 1"),
        ({"n_robots": 2, "start_xy_m": [(3.2, 1.0), (3.7, 1.4)]}, "duplicate start poses"),
        ({"world": "random:mixed"}, "explores one world"),
        (
            {"n_robots": 2, "start_xy_m": [(0, 0, 0), (1, 1, 1)]},
            r"robot 0's start must be \(x, y\)",
        ),
        ({"n_robots": 2, "start_xy_m": [(0.0, 0.0), "ab"]}, "robot 1's start must be"),
        ({"n_robots": 2, "start_xy_m": [(0.0, 0.0), (True, 1.0)]}, "two numbers in metres"),
    ],
)
def test_bad_team_input_gets_one_clear_line(kwargs, message):
    with pytest.raises(ConfigError, match=message):
        TeamEnv(**{"world": WORLD, **kwargs})


def test_bad_actions_say_what_is_wrong():
    fresh = TeamEnv(world=WORLD, n_robots=2, time_budget_s=BUDGET_S)
    fresh.reset(seed=0)
    with pytest.raises(InvalidActionError, match="robot_0 decides now: actions must hold"):
        fresh.step({"robot_1": fresh.carry_on})
    with pytest.raises(InvalidActionError, match=r"carry on .* is a busy robot's action"):
        fresh.step({"robot_0": fresh.carry_on})
    with pytest.raises(InvalidActionError, match=r"actions for \['robot_7'\]"):
        fresh.step({"robot_0": 0, "robot_7": 0})
    with pytest.raises(ConfigError, match="unknown agent"):
        fresh.observation_space("robot_9")


def test_a_single_robot_policy_where_a_team_policy_is_expected_is_refused():
    fresh = TeamEnv(world=WORLD, n_robots=2, time_budget_s=BUDGET_S)
    with pytest.raises(TeamPolicyError, match=r"not a team policy .* EachRobot\.of"):
        run_team_episode(fresh, load_policy("closest-frontier"), seed=0)
    with pytest.raises(TeamPolicyError, match="oracle"):
        EachRobot.of("oracle-greedy", 2)


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_a_reset_seed_that_is_no_integer_from_0_is_refused_naming_it(seed):
    fresh = TeamEnv(world=WORLD, n_robots=2, time_budget_s=BUDGET_S)
    with pytest.raises(ConfigError, match=r"reset\(seed=...\): expected None or an integer ≥ 0"):
        fresh.reset(seed=seed)
