"""A sweep selects the task: the budget task runs ``budget_scans`` scans without termination, the
time task ``time_budget_s`` seconds of robot time."""

from __future__ import annotations

import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import BUDGET_SCANS
from nbv_gym.sweep.config import SweepConfig, sweep_config

BASE = {"worlds": ("pp1-cuboids",), "policies": ("closest-frontier",), "noise": (1,)}


def test_explore_is_the_default_task():
    episode = sweep_config({**BASE, "max_steps": 40}).env_config("pp1-cuboids", 1).simulator.episode
    assert (episode.max_steps, episode.discovered_target) == (40, 0.70)


def test_budget_task_runs_budget_scans_without_termination():
    config = sweep_config({**BASE, "task": "budget"})
    assert config.task.budget_scans == BUDGET_SCANS
    episode = sweep_config({**BASE, "task": "budget", "budget_scans": 7}).env_config(
        "pp1-cuboids", 1
    )
    assert episode.simulator.episode.max_steps == 7
    assert episode.simulator.episode.discovered_target is None
    assert config.results_fingerprint()["task"] == "budget"  # no resuming across tasks


def test_time_task_runs_its_time_budget_with_the_configured_effort_model():
    given = {"task": "time", "time_budget_s": 300.0, "speed_mps": 0.5, "scan_time_s": 4.0}
    config = sweep_config({**BASE, **given})
    episode = config.env_config("pp1-cuboids", 1).simulator.episode
    assert (episode.time_budget_s, episode.speed_mps, episode.scan_time_s) == (300.0, 0.5, 4.0)
    assert episode.discovered_target is None and episode.max_steps * 4.0 > 300.0  # cap never binds
    assert config.results_fingerprint()["time_budget_s"] == 300.0  # no resuming across budgets
    for key in ("time_budget_s", "speed_mps"):
        with pytest.raises(
            ConfigError,
            match=rf"env\.simulator\.episode\.{key}: set by the sweep; use the top-level key "
            f"'{key}' instead",
        ):
            SweepConfig(**BASE, env={"simulator": {"episode": {key: 9.0}}})


@pytest.mark.parametrize(
    "values, match",
    [({"task": "race"}, "task: expected one of explore, budget, time"),
     ({"budget_scans": 0}, "budget_scans: must be from 1 to 10,000"),
     ({"time_budget_s": 0.0}, "time_budget_s: must be from 1 to 86,400 s, got 0.0")],
    ids=["task", "budget_scans", "time_budget_s"],
)  # fmt: skip
def test_bad_task_settings_are_refused(values, match):
    with pytest.raises(ConfigError, match=match):
        sweep_config({**BASE, **values})
