"""What one robot owns: its pose, trajectory, clock and noise generator."""

from __future__ import annotations

import math

import pytest

from nbv_gym.core.pose import Pose
from nbv_gym.core.protocol import EffortModel, TimeBudget
from nbv_gym.core.robot import Robot

START = Pose(1.0, -2.0, 0.0, 0.5)


def test_the_clock_is_the_path_and_the_scans_after_the_first_under_the_effort_model():
    robot = Robot(START)
    robot.reset(3)
    effort = EffortModel(speed_mps=0.5, scan_time_s=4.0)
    assert robot.elapsed_s(effort) == 0.0 and robot.trajectory == [START]
    robot.move(Pose(2.0, -2.0, 0.0), 1.0)
    robot.move(Pose(2.0, 0.0, 0.0), 2.0)
    assert robot.elapsed_s(effort) == pytest.approx(3.0 / 0.5 + 2 * 4.0)
    assert robot.remaining_s(TimeBudget(30.0, effort)) == pytest.approx(30.0 - 14.0)
    assert robot.remaining_s(TimeBudget(None, effort)) == math.inf
    assert robot.trajectory == [START, Pose(2.0, -2.0, 0.0), Pose(2.0, 0.0, 0.0)]
    assert list(robot.xy) == [2.0, 0.0]


def test_a_reset_restarts_the_robot_and_seeds_its_generator():
    robot = Robot(START)
    robot.reset(7)
    first = robot.rng.normal(size=3)
    robot.move(Pose(0.0, 0.0, 0.0), 5.0)
    robot.goal = 12
    robot.reset(7)
    assert (robot.pose, robot.steps, robot.path_length_m, robot.goal) == (START, 0, 0.0, -1)
    assert list(robot.rng.normal(size=3)) == list(first)
