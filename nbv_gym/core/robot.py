"""What one robot owns in an episode: its pose and trajectory, its clock (the path it drove and
the scans it took, charged by the effort model), and the generator of its localisation and range
noise. The world, the map, the statistics and the map quality are the team's
(:class:`nbv_gym.simulator.Exploration`); a single robot is the team of one."""

from __future__ import annotations

import numpy as np

from nbv_gym.core.pose import Pose
from nbv_gym.core.protocol import EffortModel, TimeBudget


class Robot:
    """One robot of an episode, starting at ``start`` (a ground pose).

    ``steps`` counts the scans after the first one and ``path_length_m`` sums the paths driven
    to reach them (metres); under an :class:`~nbv_gym.core.protocol.EffortModel` they give the
    robot's clock (:meth:`elapsed_s`). ``goal`` is the goal cell it stands on or drives to (−1
    before its first goal).
    """

    def __init__(self, start: Pose):
        self.start = start
        self.rng = np.random.default_rng()
        self.pose = start
        self.trajectory: list[Pose] = []
        self.steps, self.path_length_m, self.goal = 0, 0.0, -1

    def reset(self, seed: int | None) -> None:
        """Back at the start with an empty trajectory and clock; the noise generator seeded
        with ``seed``."""
        self.rng = np.random.default_rng(seed)
        self.pose = self.start
        self.trajectory = [self.start]
        self.steps, self.path_length_m, self.goal = 0, 0.0, -1

    def move(self, pose: Pose, path_length_m: float) -> None:
        """Arrive at ``pose`` after a path of ``path_length_m`` metres, for the next scan."""
        self.pose = pose
        self.trajectory.append(pose)
        self.steps += 1
        self.path_length_m += path_length_m

    def elapsed_s(self, effort: EffortModel) -> float:
        """The robot's clock, seconds since the first scan: its path and its scans after the
        first under ``effort``."""
        return effort.elapsed_s(self.path_length_m, self.steps)

    def remaining_s(self, budget: TimeBudget) -> float:
        """Seconds of ``budget`` left on the robot's clock (inf without a budget)."""
        return budget.remaining_s(self.elapsed_s(budget.effort))

    @property
    def xy(self) -> np.ndarray:
        """(2,) float64 the robot's x, y, metres."""
        return np.array([self.pose.x, self.pose.y])
