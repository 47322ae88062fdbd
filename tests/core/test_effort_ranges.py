"""Effort values are bounded to physically meaningful ranges at every entry, from one table
(:data:`nbv_gym.core.protocol.EFFORT_RANGES`): each config that holds one refuses a value outside
it in one line naming the key and the range, and inside it every figure of the clock stays
finite (the round-4 probes T10-T25, R01, R02, E02, E04 crashed past these checks)."""

from __future__ import annotations

import math

import pytest

from nbv_gym.core.config import from_dict
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import (
    EFFORT_RANGES,
    EffortModel,
    EpisodeConfig,
    TimeBudget,
    task_episode,
)

#: Every config an effort value enters by, with how it is given there.
ENTRIES = {
    "episode": lambda key, value: from_dict(EpisodeConfig, {key: value}),
    "train": lambda key, value: _train({key: value}),
    "sweep": lambda key, value: _sweep(key, value),
    "tuning": lambda key, value: _tuning(key, value),
}


def _train(values):
    from nbv_gym.rl.config import train_config

    return train_config({"task": "time", **values})


def _sweep(key, value):
    from nbv_gym.sweep.config import sweep_config

    base = {"worlds": ["pp1-cuboids"], "policies": ["closest-frontier"], "task": "time"}
    return sweep_config({**base, key: value})


def _tuning(key, value):
    from nbv_gym.benchmark.tuning import TuningConfig

    if key != "time_budget_s":
        pytest.skip("a tuning config holds only the time budget")
    return TuningConfig(time_budget_s=value)


def _outside(key):
    low, high, _ = EFFORT_RANGES[key]
    below = [low / 2 if low > 0 else -1e-300]
    return [*below, high * 1.5, math.inf, -math.inf, math.nan, 1e308]


CASES = [
    pytest.param(entry, key, value, id=f"{entry}-{key}-{value:g}")
    for entry in ENTRIES
    for key in EFFORT_RANGES
    for value in _outside(key)
]


@pytest.mark.parametrize(("entry", "key", "value"), CASES)
def test_a_value_outside_its_range_is_refused_naming_the_key_and_the_range(entry, key, value):
    low, high, unit = EFFORT_RANGES[key]
    with pytest.raises(ConfigError) as error:
        ENTRIES[entry](key, value)
    message = str(error.value)
    assert f"{key}: must be from {low:,g} to {high:,g} {unit}, got" in message, message


@pytest.mark.parametrize("speed", [EFFORT_RANGES["speed_mps"][0], EFFORT_RANGES["speed_mps"][1]])
@pytest.mark.parametrize("scan", [0.0, 5e-324, EFFORT_RANGES["scan_time_s"][1]])
@pytest.mark.parametrize(
    "budget", [EFFORT_RANGES["time_budget_s"][0], EFFORT_RANGES["time_budget_s"][1]]
)
def test_at_the_corners_of_the_ranges_the_clock_stays_finite(speed, scan, budget):
    effort = EffortModel(speed, scan)
    cap = effort.scan_cap(budget)
    assert 1 <= cap <= budget * EFFORT_RANGES["speed_mps"][1] + 1
    assert math.isfinite(effort.elapsed_s(1000.0, cap)) and math.isfinite(
        TimeBudget(budget, effort).reach_m(budget)
    )
    episode = task_episode("time", EpisodeConfig(speed_mps=speed, scan_time_s=scan), None, budget)
    assert episode.max_steps == cap


def test_the_scan_cap_of_the_defaults_is_unchanged():
    """The time task's cap (and so every suite's content hash) is what it was: 61 at 600 s."""
    assert EffortModel().scan_cap(600.0) == 61
    assert EffortModel(0.5, 5.0).scan_cap(90.0) == 19
