"""Run a team policy for one episode and compute the team's figures (docs/team.md#figures).

Team figures, each over the team's shared time budget T:

- ``q_time_auc``: the area under the team's Q(t) over [0, T], divided by T (Q a step function
  of the team's clock, the first scans at 0: :mod:`nbv_gym.metrics.effort`); ``q`` at the end
  (the budget); ``time_to_q_s``: the team's clock when Q first reached ``q_target`` (None if
  never).
- per robot: scans, path, clock, why it stopped, and its contribution (the ΔQ of its own
  scans); ``longest_path_m``: the longest robot path; ``contribution_spread``: the largest
  minus the smallest robot's share of the summed ΔQ (0: an even split).
- ``overlap_rate`` (Explore-Bench, Xu et al. 2022): the robots' single coverages summed over
  the team's coverage, minus 1 (0: no cell seen by two robots). A robot's coverage is the x, y
  cells of G where its scans changed the map.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nbv_gym.core.errors import ConfigError
from nbv_gym.env.views import agent_view
from nbv_gym.metrics.effort import area_under
from nbv_gym.policies import PolicyError, policy_name
from nbv_gym.simulator import InvalidActionError
from nbv_gym.team.env import TeamEnv
from nbv_gym.team.policies import TeamPolicyError, check_team_policy
from nbv_gym.team.simulator import TeamSimulator

#: Default Q target of ``time_to_q_s``: chosen, a little below the median Q one closest-frontier
#: robot holds after 600 s on the standard suite's time-test split (0.047).
Q_TARGET = 0.04


@dataclass
class TeamEpisodeResult:
    """One team episode: a row per scan (the first scans included: ``robot``, ``time_s``,
    ``path_length_m`` the team's summed path after it, ``q``, ``q_paper``, ``discovered``), a
    row per robot, the team's figures (module docstring) and the wall time (s)."""

    scans: list[dict[str, float]] = field(default_factory=list)
    robots: list[dict[str, Any]] = field(default_factory=list)
    figures: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0


def run_team_episode(
    env: TeamEnv,
    policy: Any,
    seed: int,
    q_target: float = Q_TARGET,
    on_step: Callable[[TeamEnv], None] | None = None,
) -> TeamEpisodeResult:
    """Run ``policy`` (a team policy: :func:`~nbv_gym.team.policies.check_team_policy`) in
    ``env`` from ``reset(seed=seed)`` until every robot has stopped; ``on_step(env)`` after the
    reset and after each step. Each robot's info is its agent view
    (:func:`~nbv_gym.env.views.agent_view`)."""
    check_team_policy(policy)
    check_q_target(q_target)
    robots = getattr(policy, "policies", None)  # EachRobot: one single-robot policy per robot
    if robots is not None and len(robots) != len(env.possible_agents):
        raise TeamPolicyError(
            f"{policy_name(policy)} holds {len(robots)} robot policies for a team of "
            f"{len(env.possible_agents)}; give one per robot (EachRobot.of(name, n_robots))"
        )
    start = time.perf_counter()
    observations, infos = env.reset(seed=seed)
    policy.reset(seed)
    if on_step:
        on_step(env)
    while env.agents:
        views = {agent: agent_view(info) for agent, info in infos.items() if agent in env.agents}
        actions = policy.act({a: observations[a] for a in views}, views)
        try:
            observations, _, _, _, infos = env.step(actions)
        except InvalidActionError as error:
            raise PolicyError(f"Team policy at scan {len(env.sim.scans)}: {error}") from None
        if on_step:
            on_step(env)
    return team_result(env.sim, q_target, time.perf_counter() - start)


def check_q_target(q_target: object) -> None:
    """ConfigError unless ``q_target`` is a number in (0, 1] (a Q to reach)."""
    if isinstance(q_target, bool) or not isinstance(q_target, int | float | np.floating):
        raise ConfigError(f"q_target: expected a number in (0, 1], got {q_target!r}")
    if not 0 < q_target <= 1:
        raise ConfigError(f"q_target: a Q to reach must be in (0, 1], got {q_target}")


def team_result(sim: TeamSimulator, q_target: float, wall_time_s: float) -> TeamEpisodeResult:
    """The result of ``sim``'s finished episode (module docstring)."""
    rows, path = [], 0.0
    for scan in sim.scans:
        path += scan.path_length_m
        rows.append({"robot": scan.robot, "time_s": scan.time_s, "path_length_m": path,
                     "q": scan.q, "q_paper": scan.q_paper, "discovered": scan.discovered})  # fmt: skip
    robots = [_robot_row(sim, k) for k in range(len(sim.robots))]
    return TeamEpisodeResult(rows, robots, team_figures(sim, robots, q_target), wall_time_s)


def _robot_row(sim: TeamSimulator, index: int) -> dict[str, Any]:
    robot = sim.robots[index]
    return {
        "robot": index,
        "steps": robot.steps,
        "path_length_m": robot.path_length_m,
        "elapsed_s": robot.elapsed_s(sim.effort),
        "end_reason": sim.stopped[index],
        "delta_q": float(sum(s.delta_q for s in sim.scans if s.robot == index)),
        "coverage_cells": int(sim.coverage[index].sum()),
    }


def team_figures(sim: TeamSimulator, robots: list[dict], q_target: float) -> dict[str, Any]:
    """The team's figures of a finished episode (module docstring)."""
    scans = sim.scans
    times = np.array([s.time_s for s in scans])
    q = np.array([s.q for s in scans])
    budget = sim.time_budget_s or float(times[-1]) or 1.0
    reached = np.flatnonzero(q >= q_target)
    contributions = np.array([r["delta_q"] for r in robots])
    total = contributions.sum()
    shares = contributions / total if total > 0 else np.zeros_like(contributions)
    covered = int(sim.coverage.any(axis=0).sum())
    return {
        "n_robots": len(robots),
        "steps": len(scans) - len(robots),
        "end_reason": _end_reason(sim),
        "q": float(q[-1]),
        "q_paper": scans[-1].q_paper,
        "discovered": scans[-1].discovered,
        "elapsed_s": float(times.max()),
        "path_length_m": float(sum(r["path_length_m"] for r in robots)),
        "q_time_auc": area_under(times, q, budget),
        "q_target": q_target,
        "time_to_q_s": float(times[reached[0]]) if len(reached) else None,
        "longest_path_m": float(max(r["path_length_m"] for r in robots)),
        "contribution_spread": float(shares.max() - shares.min()),
        "overlap_rate": float(sim.coverage.sum() / covered - 1.0) if covered else 0.0,
    }


def _end_reason(sim: TeamSimulator) -> str:
    """Why the episode ended: the last robot's reason to stop (all robots' when the team
    terminated)."""
    if sim.terminated:
        return sim.stopped[0]
    last = max(range(len(sim.robots)), key=lambda k: (sim.robots[k].elapsed_s(sim.effort), k))
    return sim.stopped[last]
