"""Team policies: what chooses the deciding robot's goal in the team environment (docs/team.md).

A team policy has ``team = True``, ``reset(seed)`` and ``act(observations, infos)`` over the
running robots' dicts, returning an action per robot (``carry_on`` for the busy ones). Two kinds
ship:

- :class:`EachRobot` — uncoordinated: each robot runs its own copy of a single-robot policy on
  its own observation (its goal mask already leaves out its teammates' goals, the goal rule).
- :class:`UtilityFrontier` — coordinated, after Burgard et al., "Coordinated multi-robot
  exploration" (IEEE T-RO 2005): the deciding robot takes the frontier goal of highest utility
  minus path cost, a frontier goal's utility (1) discounted near the goals its teammates
  announced, linearly from 1 at the teammate's goal to 0 at the sensor range.
- :class:`HungarianFrontier` — coordinated by cost assignment, after Faigl et al., "Goal
  assignment using distance cost in multi-robot exploration" (IROS 2012): the robots that decide
  at this moment get distinct frontier goals of least summed path cost (the Hungarian method,
  Kuhn 1955, as ``scipy.optimize.linear_sum_assignment``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.env.views import agent_view
from nbv_gym.policies import Policy, PolicyError, is_oracle, load_policy, policy_name
from nbv_gym.policies.registry import POLICIES, required_layers
from nbv_gym.sensor.lidar import SENSOR_RANGE_M
from nbv_gym.team.simulator import robot_seed

#: Keys the team adds to a robot's observation (dropped for a single-robot policy).
TEAM_KEYS = ("teammates", "action_mask")


class TeamPolicyError(PolicyError):
    """Something that is not a team policy was given where one is expected."""


def check_team_policy(policy: object) -> None:
    """:class:`TeamPolicyError` unless ``policy`` declares ``team = True`` (naming what to do
    with a single-robot policy)."""
    if getattr(policy, "team", False) is True:
        return
    raise TeamPolicyError(
        f"{policy_name(policy)} is not a team policy (no team = True); a single-robot policy "
        "runs on a team as EachRobot.of(name, n_robots), each robot its own copy"
    )


def deciding_robot_acts(
    infos: Mapping[str, Mapping[str, Any]], choose: Callable[[str], int]
) -> dict[str, int]:
    """An action per robot of ``infos``: ``choose(agent)`` for the one that decides now,
    carry on (the last action) for the busy ones."""
    return {
        agent: len(info["action_mask"]) - 1 if info["busy"] else choose(agent)
        for agent, info in infos.items()
    }


def robot_index(agent: str) -> int:
    """The index of agent ``robot_<k>``."""
    return int(agent.rpartition("_")[2])


class DecidingRobot:
    """A team policy that chooses the deciding robot's goal (:meth:`_goal`) and carries on for
    the others; deterministic unless :meth:`reset` says otherwise."""

    team = True

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset: the policy is deterministic."""

    def act(
        self,
        observations: Mapping[str, Mapping[str, np.ndarray]],
        infos: Mapping[str, Mapping[str, Any]],
    ) -> dict[str, int]:
        """The deciding robot's goal; carry on for the others."""
        return deciding_robot_acts(infos, lambda a: self._goal(a, observations, infos))

    def _goal(self, agent: str, observations: Mapping, infos: Mapping) -> int:
        """The goal of ``agent``, the robot that decides now."""
        raise NotImplementedError


class EachRobot(DecidingRobot):
    """Uncoordinated: robot k runs ``policies[k]``, a single-robot policy, on its own
    observation and agent view (the team's keys left out, the mask without carry-on)."""

    def __init__(self, policies: Sequence[Policy]):
        if not policies:
            raise TeamPolicyError("EachRobot: give one single-robot policy per robot, got none")
        for policy in policies:
            check_single_policy(policy)
        self.policies = list(policies)

    @classmethod
    def of(cls, name: str, n_robots: int) -> EachRobot:
        """``n_robots`` copies of the registered single-robot policy ``name``."""
        return cls([load_policy(name) for _ in range(n_robots)])

    def reset(self, seed: int | None = None) -> None:
        """Robot k's policy is reset with robot k's seed (robot 0's is ``seed``)."""
        for index, policy in enumerate(self.policies):
            policy.reset(robot_seed(seed, index))

    def _goal(self, agent: str, observations: Mapping, infos: Mapping) -> int:
        policy = self.policies[robot_index(agent)]
        single = {k: v for k, v in observations[agent].items() if k not in TEAM_KEYS}
        mask = np.asarray(infos[agent]["action_mask"])[:-1]
        view = agent_view({**infos[agent], "action_mask": mask}, policy_name(policy))
        return int(policy.act(single, view))


def check_single_policy(policy: object) -> None:
    """:class:`TeamPolicyError` for what a team cannot run per robot yet: an oracle or a policy
    that needs optional observation layers (the team env computes the base layers only)."""
    if is_oracle(policy):
        raise TeamPolicyError(f"{policy_name(policy)} is an oracle; teams run agent policies only")
    layers = required_layers(policy)
    if layers:
        raise TeamPolicyError(
            f"{policy_name(policy)} needs the observation layers {list(layers)}; the team env "
            "computes the base layers only"
        )


class UtilityFrontier(DecidingRobot):
    """Coordinated frontier exploration (module docstring): the deciding robot's frontier goal
    maximising utility − ``beta`` · cost (cost: path length / the cost range, the ``cost``
    layer), each frontier goal's utility 1 less ``1 − d / range_m`` for each teammate's goal at
    distance d < ``range_m`` metres. Without a frontier goal: the valid goal of least cost."""

    def __init__(self, beta: float = 1.0, range_m: float = SENSOR_RANGE_M):
        self.beta, self.range_m = float(beta), float(range_m)
        if not (math.isfinite(self.beta) and self.beta >= 0):
            raise ConfigError(f"UtilityFrontier: beta must be a finite number ≥ 0, got {beta!r}")
        if not (math.isfinite(self.range_m) and self.range_m > 0):
            raise ConfigError(
                f"UtilityFrontier: range_m must be a finite number > 0, got {range_m!r}"
            )

    def _goal(self, agent: str, observations: Mapping, infos: Mapping) -> int:
        observation, info = observations[agent], infos[agent]
        valid = np.asarray(info["action_mask"])[:-1].astype(bool)
        frontier = valid & (np.asarray(observation["frontier"]) > 0)
        cost = np.asarray(observation["cost"], float)
        if not frontier.any():
            return int(np.argmin(np.where(valid, cost, np.inf)))
        utility = 1.0 - self._discount(info)
        score = np.where(frontier, utility - self.beta * cost, -np.inf)
        return int(np.argmax(score))

    def _discount(self, info: Mapping[str, Any]) -> np.ndarray:
        """(n_goals,) the sum over teammates' goals of max(1 − distance / range, 0)."""
        nx, ny = info["goal_grid_shape"]
        cell = float(info["goal_cell_m"])
        i, j = np.divmod(np.arange(nx * ny), ny)
        discount = np.zeros(nx * ny)
        for goal in np.asarray(info["teammate_goals"], np.int64):
            gi, gj = divmod(int(goal), ny)
            distance = np.hypot(i - gi, j - gj) * cell
            discount += np.maximum(1.0 - distance / self.range_m, 0.0)
        return discount


class HungarianFrontier(DecidingRobot):
    """Coordinated by cost assignment (module docstring): the robots that decide now
    (``info["decides_now"]``, each with its fresh ``cost`` and ``valid`` layers) are assigned
    distinct frontier goals — those valid for the deciding robot, so the teammates' goals stay
    reserved — minimising the summed path cost; the deciding robot takes its own. A robot
    left without a frontier goal (fewer than robots, or none it reaches) takes the valid goal of
    least cost outside the assigned ones. Deterministic and stateless: the robots waiting
    their turn get the same goals when they decide (the rest of an optimal assignment is
    optimal for the rest)."""

    def _goal(self, agent: str, observations: Mapping, infos: Mapping) -> int:
        valid = np.asarray(infos[agent]["action_mask"])[:-1].astype(bool)
        cost = np.asarray(observations[agent]["cost"], float)
        columns = np.flatnonzero(valid & (np.asarray(observations[agent]["frontier"]) > 0))
        robots = [a for a, info in infos.items() if a == agent or info.get("decides_now")]
        assigned = assign_goals(
            np.array([observations[a]["cost"] for a in robots], float)[:, columns],
            np.array([observations[a]["valid"] for a in robots], bool)[:, columns],
        )
        mine = assigned[robots.index(agent)]
        if mine >= 0:
            return int(columns[mine])
        free = valid.copy()
        free[columns[assigned[assigned >= 0]]] = False
        return int(np.argmin(np.where(free if free.any() else valid, cost, np.inf)))


def assign_goals(cost: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(n_robots,) int64: the column (goal) of least summed ``cost`` assigned to each robot (a
    row), distinct, only where ``valid``; −1 for a robot left without one. ``cost``, ``valid``:
    (n_robots, n_goals) float64 and bool."""
    assigned = np.full(cost.shape[0], -1, np.int64)
    if cost.size == 0:
        return assigned
    big = float(cost[valid].sum()) + 1.0 if valid.any() else 1.0  # more than any valid total
    rows, cols = linear_sum_assignment(np.where(valid, cost, big))
    keep = valid[rows, cols]
    assigned[rows[keep]] = cols[keep]
    return assigned


#: Team policies by name; any registered single-robot policy name also runs, as
#: :meth:`EachRobot.of` (uncoordinated).
TEAM_POLICIES: dict[str, type[DecidingRobot]] = {
    "utility-frontier": UtilityFrontier,
    "hungarian-frontier": HungarianFrontier,
}


def load_team_policy(name: str, n_robots: int) -> DecidingRobot:
    """A team policy: a name of :data:`TEAM_POLICIES`, or a single-robot policy's name run
    on every robot (:class:`EachRobot`)."""
    if name in TEAM_POLICIES:
        return TEAM_POLICIES[name]()
    try:
        return EachRobot.of(name, n_robots)
    except UnknownNameError:
        raise UnknownNameError("team policy", name, [*TEAM_POLICIES, *POLICIES]) from None
