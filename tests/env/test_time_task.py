"""The time task, ``nbv_gym/ExploreTime-v0``: the robot's clock follows the effort model, goals
that would overrun the remaining time are masked, the episode ends when the budget is spent, and
the ``cost`` layer gives the true path cost of every valid goal, however far (checkers:
``test_registered_ids.py``)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import SCAN_TIME_S, SPEED_MPS, TIME_BUDGET_S, TIME_ID
from nbv_gym.env import ExploreEnv
from nbv_gym.mapping.navigation import NavigationConfig

WORLD = "pp1-cuboids"
#: Not the defaults, so that a formula that ignores a parameter fails.
SPEED, SCAN, BUDGET = 0.8, 7.5, 400.0
#: The range that scales the ``cost`` layer (the navigation's search range), metres.
RANGE_M = NavigationConfig().cost_range_m


def random_episode(seed: int = 3, **kwargs):
    """(observation, info, reward, (terminated, truncated), env) after reset (reward None) and
    after every step of a random masked episode on the time task with :data:`SPEED`,
    :data:`SCAN` and :data:`BUDGET`."""
    env = gymnasium.make(
        TIME_ID, world=WORLD, time_budget_s=BUDGET, speed_mps=SPEED, scan_time_s=SCAN, **kwargs
    )
    rng = np.random.default_rng(seed)
    observation, info = env.reset(seed=seed)
    yield observation, info, None, (False, False), env.unwrapped
    while True:
        goal = int(rng.choice(np.flatnonzero(info["action_mask"])))
        observation, reward, terminated, truncated, info = env.step(goal)
        yield observation, info, reward, (terminated, truncated), env.unwrapped
        if terminated or truncated:
            return


def goal_time_s(env: ExploreEnv) -> np.ndarray:
    """(n_goals,) seconds to drive to each goal and scan there (inf if unreachable)."""
    return env.sim.navigation.goal_path_length() / SPEED + SCAN


@pytest.fixture(scope="module")
def episode() -> list[dict]:
    """Per reset and step: the observation, info, (terminated, truncated), and read from the
    navigation layer: each goal's drive + scan time (s), the goals valid without the time
    limit, the cells the path search may cross, the robot's nav cell and the goals' nav cells."""
    steps = []
    for obs, info, reward, end, env in random_episode():
        nav = env.sim.navigation
        i, j = nav.grid.index([[*nav.robot_xy, nav.grid.origin[2]]])[0, :2]
        steps.append({
            "obs": obs, "info": info, "reward": reward, "end": end, "cost_s": goal_time_s(env),
            "reachable": nav.goal_mask(limited=False).copy(),
            "passable": nav._passable((int(i), int(j))), "robot": (int(i), int(j)),
            "goal_cells": nav._goal_cells, "space": env.observation_space,
        })  # fmt: skip
    return steps


def test_elapsed_time_is_path_over_speed_plus_scans_times_scan_time(episode):
    assert len(episode) > 5
    for step in episode:
        info = step["info"]
        expected = info["path_length_m"] / SPEED + info["steps"] * SCAN
        assert abs(info["elapsed_s"] - expected) <= 1e-9
        assert abs(info["remaining_s"] - (BUDGET - expected)) <= 1e-9
    assert episode[0]["info"]["elapsed_s"] == 0.0  # the first scan starts the clock


def test_the_rewards_sum_to_the_area_under_q_over_the_budget(episode):
    q = np.array([step["info"]["q"] for step in episode])
    ends = [step["info"]["elapsed_s"] for step in episode]
    held_s = np.diff([*ends, BUDGET])  # each scan's Q is held until the next scan ends
    area = float(q @ held_s) / BUDGET
    assert q[0] + sum(step["reward"] for step in episode[1:]) == pytest.approx(area, abs=1e-12)
    assert all(s["reward"] < s["info"]["delta_q"] for s in episode[1:] if s["info"]["delta_q"] > 0)


def test_the_valid_goals_are_the_reachable_goals_that_fit_in_the_remaining_time(episode):
    for step in episode:
        mask, cost_s, remaining = (
            step["info"]["action_mask"].astype(bool),
            step["cost_s"],
            step["info"]["remaining_s"],
        )
        assert np.all(cost_s[mask] <= remaining + 1e-9)  # no valid goal overruns the time left
        np.testing.assert_array_equal(mask, step["reachable"] & (cost_s <= remaining + 1e-9))
    assert any(np.any(s["reachable"] & (s["cost_s"] > s["info"]["remaining_s"])) for s in episode)


def test_the_episode_ends_when_the_budget_is_spent(episode):
    *running, last = episode
    info = last["info"]
    assert last["end"] == (False, True)
    assert info["end_reason"].startswith("time budget spent")
    assert 0 <= info["remaining_s"] < np.min(last["cost_s"][last["reachable"]])
    assert all(
        step["info"]["end_reason"] == "" and step["end"] == (False, False) for step in running
    )


def test_the_cost_layer_is_the_shortest_path_cost_of_goals_beyond_the_sensor_range(episode):
    far_goals = 0
    for step in episode:
        lengths = grid_path_lengths(step["passable"], step["robot"], 0.5)
        goal_lengths = lengths.ravel()[step["goal_cells"]]
        valid = step["info"]["action_mask"].astype(bool)
        far = valid & (goal_lengths > 20.0)
        far_goals += int(far.sum())
        cost = step["obs"]["cost"].astype(float)
        np.testing.assert_allclose(cost[far] * RANGE_M, goal_lengths[far], rtol=1e-6)
        assert np.all(cost[~valid] == 1.0)
        assert step["obs"] in step["space"]
    assert far_goals > 100


def test_the_state_progress_is_the_share_of_the_budget_spent(episode):
    for step in episode:
        expected = step["info"]["elapsed_s"] / BUDGET
        assert step["obs"]["state"][5] == pytest.approx(expected, rel=1e-6, abs=1e-7)


def test_defaults_and_refusals():
    env = ExploreEnv(task="time", world=WORLD)
    episode = env.config.simulator.episode
    assert (episode.time_budget_s, episode.speed_mps, episode.scan_time_s) == (
        TIME_BUDGET_S, SPEED_MPS, SCAN_TIME_S)  # fmt: skip
    assert episode.discovered_target is None
    assert episode.max_steps == 61 and 61 * SCAN_TIME_S > TIME_BUDGET_S  # a cap that never binds
    with pytest.raises(ConfigError, match="time_budget_s is the time task's budget"):
        ExploreEnv(task="budget", world=WORLD, time_budget_s=100.0)
    with pytest.raises(ConfigError, match=r"speed_mps: must be from 0\.01 to 100 m/s, got 0\.0"):
        ExploreEnv(task="time", world=WORLD, speed_mps=0.0)
    _, info = ExploreEnv(world=WORLD).reset(seed=0)
    assert "elapsed_s" not in info  # the other tasks' info stays as pinned (test_digest.py)


def grid_path_lengths(passable: np.ndarray, start: tuple[int, int], step_m: float) -> np.ndarray:
    """(nx, ny) 8-connected shortest path lengths over ``passable`` from ``start`` with scipy's
    Dijkstra (an independent implementation)."""
    nx, ny = passable.shape
    ids = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, weights = [], [], []
    for di, dj in [(di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if (di, dj) != (0, 0)]:
        a = ids[max(0, -di) : nx - max(0, di), max(0, -dj) : ny - max(0, dj)]
        b = ids[max(0, di) : nx + min(0, di), max(0, dj) : ny + min(0, dj)]
        ok = passable.ravel()[b.ravel()]
        rows.append(a.ravel()[ok])
        cols.append(b.ravel()[ok])
        weights.append(np.full(ok.sum(), step_m * (np.sqrt(2) if di and dj else 1.0)))
    graph = coo_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), (nx * ny,) * 2
    ).tocsr()
    return dijkstra(graph, indices=start[0] * ny + start[1]).reshape(nx, ny)


@pytest.mark.parametrize("budget", [5.0, 10.5], ids=["shorter-than-a-scan", "no-goal-near-enough"])
def test_a_budget_that_leaves_no_goal_ends_the_episode_at_its_first_scan_naming_it(budget):
    """The round-4 probes E09 and E20: the episode is over at reset, ``info`` says why with the
    budget and what the nearest goal takes, and a step is refused saying the same, whatever goal
    ``sample()`` or Gymnasium's checker picks."""
    from gymnasium.utils.env_checker import check_env

    from nbv_gym.simulator import ResetNeededError

    env = gymnasium.make(TIME_ID, world=WORLD, time_budget_s=budget)
    _, info = env.reset(seed=0)
    assert not info["action_mask"].any()
    reason = info["end_reason"]
    assert reason.startswith(
        f"time budget spent at the first scan: time_budget_s = {budget:g} s leaves no goal "
        "(the nearest takes "
    ), reason
    nearest_s = float(reason.split("the nearest takes ")[1].split(" s")[0])
    assert budget < nearest_s  # what it says is why
    with pytest.raises(ResetNeededError, match=r"ended at its first scan, before any step \(time"):
        env.step(env.action_space.sample())
    with pytest.raises(ResetNeededError, match=f"time_budget_s = {budget:g} s leaves no goal"):
        check_env(env.unwrapped)


def test_once_the_budget_is_spent_sample_draws_a_goal_valid_at_the_start():
    """The round-4 probe E20: once no goal fitted, ``sample()`` drew any cell, which Gymnasium's
    checker then stepped after a new reset ("within 1.0 m of the window border")."""
    env = gymnasium.make(TIME_ID, world=WORLD, time_budget_s=12.0)  # one scan 1-2 m away fits
    _, info = env.reset(seed=0)
    start = info["action_mask"].astype(bool)
    _, _, _, truncated, info = env.step(int(np.flatnonzero(start)[0]))
    assert truncated and not info["action_mask"].any()
    assert all(start[env.action_space.sample()] for _ in range(20))


def test_no_registered_step_limit_cuts_a_time_episode_short():
    """E22: with a scan time of 0.5 s the env's own scan cap is 1201, the registered TimeLimit
    was 61: an episode was truncated with 506.8 of 600 s left and no end reason. The id now
    sets no step limit: scans are free here and the nearest goals a metre or two away, so an
    episode runs past 61 steps until its budget is spent, and says so."""
    env = gymnasium.make(TIME_ID, world=WORLD, scan_time_s=0.0, time_budget_s=80.0)
    assert env.spec.max_episode_steps is None
    assert env.unwrapped.config.simulator.episode.max_steps == 81  # 80 s / 1 s a goal + 1
    observation, info = env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        goal = int(np.argmin(np.where(info["action_mask"], observation["cost"], np.inf)))
        observation, _, terminated, truncated, info = env.step(goal)
        steps += 1
        assert not terminated
    assert info["end_reason"] == f"time budget spent ({info['remaining_s']:.1f} s left)"
    assert 61 < steps < 81 and not info["action_mask"].any()


def test_the_time_id_refuses_another_task():
    """E12: make(ExploreTime-v0, task="budget") built the budget task under the time id."""
    with pytest.raises(ConfigError, match="task"):
        gymnasium.make(TIME_ID, world=WORLD, task="budget")
