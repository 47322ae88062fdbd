"""A team of robots exploring one world, event by event, free of PettingZoo (docs/team.md).

The robots share one :class:`~nbv_gym.simulator.Exploration` — one world, one map, one set of
viewpoint statistics, one map quality — and one clock; each owns a
:class:`~nbv_gym.core.robot.Robot` (pose, path, scans, noise generator) and pays the effort
model for its own drives and scans. A robot that chooses a goal at team time t scans there at
t + path / speed + scan time; until then it is busy and its scan is not in the map. The team's
clock runs from one such moment to the next (:meth:`TeamSimulator.act`): the robots that finish
then scan (in index order) and decide one at a time (in index order, each seeing the goals its
teammates chose before it).

Goal rule: no two robots aim at one goal cell. A robot's valid goals exclude every teammate's
goal — the cell a busy teammate drives to, the cell an idle or stopped teammate stands on — so
no two robots ever stand on or head for the same cell. Paths ignore teammates (robots teleport).

A robot stops when it has no valid goal at its decision (no goal fits in the time left, or none
is reachable) or reaches ``max_steps``; it never waits, so its clock is always its own drives and
scans under the effort model, and the team's elapsed time is the latest robot's clock. The
episode ends when every robot has stopped, or for all at once when the discovered target (the
explore task's) is reached.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from nbv_gym.core import libm
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.pose import Pose
from nbv_gym.core.protocol import TimeBudget
from nbv_gym.core.robot import Robot
from nbv_gym.simulator import (
    Exploration,
    InvalidActionError,
    ResetNeededError,
    SimulatorConfig,
    goal_index,
)
from nbv_gym.worlds import World


@dataclass(frozen=True)
class Scanned:
    """One scan of the team: which robot took it, at which team time (s), the path it drove to
    it (m), the change of Q and its reward (ΔQ weighted by the share of the budget left), and
    the team's Q, Q_paper and discovered fraction after it."""

    robot: int
    time_s: float
    path_length_m: float
    delta_q: float
    reward: float
    q: float
    q_paper: float
    discovered: float


class TeamSimulator:
    """``n_robots`` robots exploring one world with one map and one clock (module docstring).

    Args:
        config: the simulator config (world, noise, sensor, mapping, quality, episode).
        n_robots: how many robots (≥ 1).
        start_xy_m: each robot's start (x, y), metres; None: robot 0 at the episode's start and
            the others at the nearest free start points (:func:`start_points`).
        world: a built world to explore instead of ``config.world``'s.
    """

    def __init__(
        self,
        config: SimulatorConfig | None = None,
        n_robots: int = 2,
        start_xy_m: Sequence[tuple[float, float]] | None = None,
        world: World | None = None,
    ):
        check_team_size(n_robots, start_xy_m)
        self.shared = Exploration(config, world)
        yaw = self.shared.config.episode.start_yaw_rad
        starts = start_xy_m or start_points(self.shared, n_robots)
        self.robots = [Robot(Pose(float(x), float(y), 0.0, yaw)) for x, y in starts]
        self._check_starts()
        n = len(self.robots)
        #: the pose each busy robot drives to and its path there (None: not busy)
        self.pending: list[tuple[Pose, float] | None] = [None] * n
        self.ready_s = np.zeros(n)  # when each busy robot's scan is done, team seconds
        self.stopped = [""] * n  # why each robot stopped ("" while it runs)
        self.terminated = False  # the discovered target was reached
        self.time_s = 0.0  # the team's clock
        self.deciding = -1  # the robot that decides now (−1: none, the episode is over)
        self.scans: list[Scanned] = []
        #: (n, n_goals) bool: the x, y cells of G where each robot's scans changed the map
        self.coverage = np.zeros((n, self.n_goals), bool)
        self._planned = -1  # the robot the navigation layer is planned for (after the last scan)

    @property
    def n_goals(self) -> int:
        """The goals (x, y cells of G); the team's actions add "carry on" (:data:`n_goals`)."""
        return self.shared.n_goals

    @property
    def effort(self):
        """The episode's effort model."""
        return self.shared.config.episode.effort

    @property
    def time_budget_s(self) -> float | None:
        """The team's time budget, s (None: none)."""
        return self.budget.seconds

    @property
    def budget(self) -> TimeBudget:
        """The team's time budget (every robot's clock runs against it)."""
        return self.shared.config.episode.budget

    @property
    def ended(self) -> bool:
        """Whether the episode is over (no robot decides)."""
        return self.deciding < 0

    def busy(self, robot: int) -> bool:
        """Whether ``robot`` does not decide now (it drives and scans, waits for its turn this
        moment, or has stopped)."""
        return robot != self.deciding

    def deciding_now(self) -> list[int]:
        """The robots that decide at the current time, in index order: the deciding robot and
        the idle ones waiting their turn at this moment ([] once the episode is over)."""
        return [] if self.ended else self._idle()

    def remaining_s(self, robot: int) -> float:
        """Seconds of the budget left on ``robot``'s clock (inf without a budget)."""
        return self.robots[robot].remaining_s(self.budget)

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the map cleared, every robot at its start with its generator
        seeded (:func:`robot_seed`), the first scans taken (in index order, at time 0), and
        robot 0 (or the first that can) to decide."""
        self.shared.clear()
        for index, robot in enumerate(self.robots):
            robot.reset(robot_seed(seed, index))
            robot.goal = self.goal_at(robot.pose)
        n = len(self.robots)
        self.pending, self.ready_s, self.stopped = [None] * n, np.zeros(n), [""] * n
        self.terminated, self.time_s, self.scans = False, 0.0, []
        self.coverage[...] = False
        for index in range(n):
            self._scan(index, 0.0)
        self._next_decision()

    def goal_mask(self, robot: int | None = None) -> np.ndarray:
        """(n_goals,) bool: the deciding robot's valid goals (all False for another
        ``robot``)."""
        if robot is not None and robot != self.deciding:
            return np.zeros(self.n_goals, bool)
        self._live()
        return self.shared.navigation.goal_mask()

    def act(self, goal: int) -> None:
        """The deciding robot heads for ``goal``; the clock then runs on to the next decision.
        :class:`InvalidActionError` for a goal that is not valid now (saying why)."""
        self._live()
        if self.ended:
            raise ResetNeededError("The team's episode has ended; call reset() first.")
        index = self.deciding
        goal = goal_index(goal, self.n_goals)
        self.shared.check_goal(goal, self.remaining_s(index))
        robot = self.robots[index]
        path_m = float(self.shared.navigation.goal_path_length()[goal])
        self.pending[index] = (self.shared.pose_at(goal, robot.pose), path_m)
        self.ready_s[index] = self.effort.elapsed_s(robot.path_length_m + path_m, robot.steps + 1)
        robot.goal = goal
        self._next_decision()

    def plan_for(self, index: int) -> None:
        """Plan the navigation layer for robot ``index``: from its pose, with the time left on
        its clock and its teammates' goals excluded (a new path search unless it is planned
        for since the last scan)."""
        excluded = self.teammates_goals(index)
        if self._planned == index:
            self.shared.navigation.exclude_goals(excluded)
            return
        self.shared.plan(self.robots[index], self.remaining_s(index), excluded)
        self._planned = index

    def goal_at(self, pose: Pose) -> int:
        """The goal cell holding ``pose`` (−1 outside G)."""
        grid = self.shared.goal_grid
        i, j = np.floor((np.array([pose.x, pose.y]) - grid.low[:2]) / grid.res).astype(int)
        nx, ny = grid.shape[:2]
        return int(i * ny + j) if 0 <= i < nx and 0 <= j < ny else -1

    def teammates_goals(self, robot: int) -> np.ndarray:
        """(n − 1,) int64 the goal cells of ``robot``'s teammates (the goal rule)."""
        goals = [r.goal for k, r in enumerate(self.robots) if k != robot and r.goal >= 0]
        return np.array(goals, np.int64)

    # ------------------------------------------------------------------ the clock

    def _next_decision(self) -> None:
        """Run the clock on until a robot must decide (:attr:`deciding`), or the episode ends."""
        while not self.terminated:
            finishing = self._finishing()
            if finishing:
                self.time_s = float(self.ready_s[finishing[0]])
                for index in finishing:
                    self._arrive(index)
                continue
            for index in self._idle():
                if self._can_decide(index):
                    self.deciding = index
                    return
            if not any(p is not None for p in self.pending):
                break
            self._advance()
        self.deciding = -1

    def _finishing(self) -> list[int]:
        """The busy robots whose scan is due at the current time, in index order."""
        return [
            k
            for k, p in enumerate(self.pending)
            if p is not None and self.ready_s[k] <= self.time_s
        ]

    def _idle(self) -> list[int]:
        """The robots that neither drive nor have stopped, in index order."""
        return [k for k, p in enumerate(self.pending) if p is None and not self.stopped[k]]

    def _advance(self) -> None:
        """Run the clock on to the next moment a busy robot's scan is due."""
        due = [self.ready_s[k] for k, p in enumerate(self.pending) if p is not None]
        self.time_s = float(min(due))

    def _arrive(self, index: int) -> None:
        """Robot ``index`` reaches its goal and scans."""
        pose, path_m = self.pending[index] or (self.robots[index].pose, 0.0)
        self.pending[index] = None
        self.robots[index].move(pose, path_m)
        self._scan(index, path_m)

    def _scan(self, index: int, path_m: float) -> None:
        remaining = self.remaining_s(index)
        _, touched, delta_q = self.shared.sense(self.robots[index], remaining)
        self._planned = index
        self.coverage[index] |= touched.any(axis=2).ravel()
        reward = self.shared.reward(delta_q, path_m, remaining)
        summary, discovered = self.shared.summary, self.shared.navigation.discovered_fraction
        scan = Scanned(index, self.time_s, path_m, delta_q, reward, summary.q, summary.q_paper,
                       discovered)  # fmt: skip
        self.scans.append(scan)

    def _can_decide(self, index: int) -> bool:
        """Plan for robot ``index`` (idle, at the current time); False, recording why, when it
        stops here (or the whole team terminates)."""
        self.plan_for(index)
        terminated, _, reason = self.shared.ending(self.robots[index], self.remaining_s(index))
        if terminated:
            self.terminated = True
            self.stopped = [reason] * len(self.robots)
        elif reason:
            self.stopped[index] = reason
        return not reason

    def _live(self) -> None:
        if self.shared.state is None:
            raise ResetNeededError("Call reset() first.")

    def _check_starts(self) -> None:
        """ConfigError for a start outside G or two robots starting in one goal cell."""
        cells: dict[int, int] = {}
        for index, robot in enumerate(self.robots):
            cell = self.goal_at(robot.pose)
            where = f"({robot.pose.x:g}, {robot.pose.y:g}) m"
            if cell < 0:
                raise ConfigError(f"start_xy_m: robot {index}'s start {where} lies outside G")
            if cell in cells:
                raise ConfigError(
                    f"start_xy_m: robots {cells[cell]} and {index} both start in the goal cell "
                    f"of {where} (duplicate start poses); give each robot its own cell"
                )
            cells[cell] = index


def robot_seed(seed: int | None, index: int) -> int | None:
    """Robot ``index``'s seed in an episode of ``seed``: ``seed`` itself for robot 0 (a team of
    one is the single-robot task, bit for bit), a seed drawn from ``seed`` and ``index`` for
    the others (None stays None: fresh randomness)."""
    if seed is None or index == 0:
        return seed
    return int(np.random.SeedSequence([seed, index]).generate_state(1, np.uint64)[0] >> 1)


def check_team_size(n_robots: object, start_xy_m: Sequence | None) -> None:
    """ConfigError unless ``n_robots`` is an integer ≥ 1 and ``start_xy_m`` (if given) holds
    one (x, y) per robot."""
    if isinstance(n_robots, bool) or not isinstance(n_robots, (int, np.integer)):
        raise ConfigError(f"n_robots: expected an integer ≥ 1, got {n_robots!r}")
    if n_robots < 1:
        raise ConfigError(f"n_robots: a team needs at least 1 robot, got {n_robots}")
    if start_xy_m is not None and len(start_xy_m) != n_robots:
        raise ConfigError(
            f"start_xy_m: expected one (x, y) per robot ({n_robots}), got {len(start_xy_m)}"
        )
    for index, start in enumerate(start_xy_m or ()):
        if not _is_xy(start):
            raise ConfigError(
                f"start_xy_m: robot {index}'s start must be (x, y), two numbers in metres, "
                f"got {start!r}"
            )


def _is_xy(start: object) -> bool:
    """Whether ``start`` is a pair of real numbers (not bools, not strings)."""
    if isinstance(start, (str, bytes)) or not isinstance(start, Sequence | np.ndarray):
        return False
    return len(start) == 2 and all(
        isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        for v in start
    )


def start_points(shared: Exploration, n_robots: int) -> list[tuple[float, float]]:
    """Where ``n_robots`` robots start by default: the episode's start, then the free start
    points nearest to it (ties counter-clockwise from +x). A free start point lies on the
    lattice of goal cells through the start (one robot per goal cell) with the robot's disc
    (the navigation's robot radius) inside the world's clear disc around the origin, which no
    asset enters. ConfigError when the world has fewer free start points than robots."""
    start = shared.config.episode.start_xy_m
    cell = shared.goal_grid.res
    radius = shared.config.mapping.navigation.robot_radius_m
    room = shared.world.clear_radius_m - radius
    k = max(0, math.floor(2 * max(room, 0.0) / cell) + 1)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1)))
    x, y = start[0] + i * cell, start[1] + j * cell
    inside = (np.hypot(x, y) <= room + 1e-9) & ((i != 0) | (j != 0))
    angle = np.mod(libm.arctan2(j, i), 2 * np.pi)
    order = np.lexsort((angle[inside], np.hypot(i, j)[inside]))
    points = [(float(start[0]), float(start[1]))]
    points += [
        (float(a), float(b)) for a, b in zip(x[inside][order], y[inside][order], strict=True)
    ]
    if n_robots > len(points):
        raise ConfigError(
            f"n_robots: {n_robots} robots, but world {shared.world.name} has {len(points)} free "
            f"start points (one per {cell:g} m goal cell, the robot's {radius:g} m disc inside "
            f"the {shared.world.clear_radius_m:g} m clear disc around the start); give at most "
            f"{len(points)} robots, or each robot's start (start_xy_m)"
        )
    return points[:n_robots]


__all__ = [
    "InvalidActionError",
    "Scanned",
    "TeamSimulator",
    "check_team_size",
    "robot_seed",
    "start_points",
]
