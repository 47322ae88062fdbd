"""Team episodes and the team's figures: area under Q(t), time to a Q target, overlap rate,
longest path and the spread of the robots' contributions."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import EffortModel
from nbv_gym.metrics.effort import area_under
from nbv_gym.team import EachRobot, TeamEnv, load_team_policy, run_team_episode
from nbv_gym.team.episode import team_figures
from nbv_gym.team.policies import TeamPolicyError
from nbv_gym.team.simulator import Scanned


def scan(robot: int, time_s: float, delta_q: float, q: float) -> Scanned:
    return Scanned(robot, time_s, 1.0, delta_q, 0.0, q, q, 0.5)


def test_team_figures_of_a_made_up_episode():
    coverage = np.zeros((2, 10), bool)
    coverage[0, :4] = True  # cells 0–3
    coverage[1, 2:6] = True  # cells 2–5: two cells seen by both
    sim = SimpleNamespace(
        scans=[scan(0, 0.0, 0.01, 0.01), scan(1, 0.0, 0.01, 0.02), scan(0, 30.0, 0.02, 0.04)],
        coverage=coverage,
        time_budget_s=100.0,
        robots=[SimpleNamespace(elapsed_s=lambda effort: 30.0)] * 2,
        effort=EffortModel(),
        stopped=["time budget spent (1.0 s left)", "no valid goal is reachable"],
        terminated=False,
    )
    robots = [{"path_length_m": 20.0, "delta_q": 0.03}, {"path_length_m": 5.0, "delta_q": 0.01}]
    figures = team_figures(sim, robots, q_target=0.035)
    assert figures["overlap_rate"] == pytest.approx(8 / 6 - 1)
    assert figures["contribution_spread"] == pytest.approx(0.75 - 0.25)
    assert figures["longest_path_m"] == 20.0 and figures["path_length_m"] == 25.0
    assert figures["time_to_q_s"] == 30.0 and figures["q"] == 0.04
    assert figures["q_time_auc"] == pytest.approx((0.02 * 30 + 0.04 * 70) / 100)
    assert figures["steps"] == 1 and figures["end_reason"].startswith("no valid goal")
    assert team_figures(sim, robots, q_target=0.5)["time_to_q_s"] is None


@pytest.mark.parametrize("name", ["closest-frontier", "utility-frontier", "hungarian-frontier"])
def test_a_team_of_three_explores_together_and_its_figures_follow_from_its_scans(name):
    env = TeamEnv(world="pp1-cuboids", n_robots=3, time_budget_s=120.0)
    result = run_team_episode(env, load_team_policy(name, 3), seed=6)
    figures, rows = result.figures, result.scans
    times, q = [r["time_s"] for r in rows], [r["q"] for r in rows]
    assert figures["q_time_auc"] == pytest.approx(area_under(times, q, 120.0), rel=1e-12)
    assert figures["q"] == q[-1] and figures["elapsed_s"] <= 120.0
    effort = env.sim.effort  # the team's clock: the latest robot's own drives and scans
    clocks = [effort.elapsed_s(r["path_length_m"], r["steps"]) for r in result.robots]
    assert figures["elapsed_s"] == max(clocks) == max(times)
    assert {r["robot"] for r in rows} == {0, 1, 2}
    assert all(robot["steps"] >= 1 for robot in result.robots)
    first = env.sim.scans[0]
    unobserved = first.q - first.delta_q  # Q of the map before any scan
    gained = sum(robot["delta_q"] for robot in result.robots)
    assert gained == pytest.approx(figures["q"] - unobserved)
    assert figures["overlap_rate"] > 0  # three robots from one spot see some cells twice
    again = run_team_episode(env, load_team_policy(name, 3), seed=6)
    assert again.scans == rows  # same seed, same bits


@pytest.mark.parametrize("q_target", [float("nan"), -1.0, 0.0, 1.5, "0.5", True])
def test_a_q_target_outside_0_1_is_refused_before_the_episode(q_target):
    env = TeamEnv(world="pp1-cuboids", n_robots=2, time_budget_s=60.0)
    with pytest.raises(ConfigError, match="q_target: "):
        run_team_episode(env, load_team_policy("utility-frontier", 2), 0, q_target=q_target)


def test_each_robot_with_one_policy_per_robot_only():
    env = TeamEnv(world="pp1-cuboids", n_robots=3, time_budget_s=60.0)
    with pytest.raises(TeamPolicyError, match="holds 2 robot policies for a team of 3"):
        run_team_episode(env, EachRobot.of("closest-frontier", 2), 0)
