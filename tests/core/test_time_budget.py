"""The time budget: what is left of it, whether a drive and a scan fit, and how far the robot
reaches, with and without a budget."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import EffortModel, EpisodeConfig, TimeBudget

#: Not the defaults, so that a formula that ignores a parameter fails.
EFFORT = EffortModel(speed_mps=0.5, scan_time_s=4.0)


def test_what_is_left_and_what_fits_follow_the_effort_model():
    budget = TimeBudget(30.0, EFFORT)
    assert budget.limited and budget.remaining_s(14.0) == 16.0
    # 16 s left: a scan of 4 s and 12 s of driving at 0.5 m/s, 6 m
    assert budget.reach_m(16.0) == 6.0
    assert budget.fits(6.0, 16.0) and not budget.fits(6.01, 16.0)
    assert budget.reach_m(3.0) < 0 and not budget.fits(0.0, 3.0)  # not even a scan fits
    assert budget.bound_m() == 15.0  # the whole budget driven
    assert budget.held(15.0) == 0.5 and budget.share(45.0) == 1.0 and budget.share(3.0) == 0.1


def test_without_a_budget_nothing_runs_out():
    budget = TimeBudget(None, EFFORT)
    assert not budget.limited and budget.remaining_s(1e9) == math.inf
    assert budget.reach_m(budget.remaining_s(0.0)) == math.inf and budget.fits(1e9, math.inf)
    assert budget.bound_m() == math.inf and budget.held(math.inf) == 1.0


def test_arrays_of_clocks_give_arrays_of_what_is_left_and_held():
    budget = TimeBudget(20.0, EFFORT)
    held = budget.held(budget.remaining_s(np.array([0.0, 5.0, 20.0])))
    assert held.tolist() == [1.0, 0.75, 0.0]


def test_the_episode_builds_its_budget_and_checks_it():
    episode = EpisodeConfig(time_budget_s=90.0, speed_mps=0.5, scan_time_s=4.0)
    assert episode.budget == TimeBudget(90.0, EFFORT)
    assert EpisodeConfig().budget == TimeBudget(None, EffortModel())
    with pytest.raises(ConfigError, match="time_budget_s: must be from 1 to 86,400 s"):
        TimeBudget(0.5)
