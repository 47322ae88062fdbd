"""Tuning the references for the time task: every tunable policy is scored on the same episodes
at each value of a grid of the same size, on a training pool, and keeps the best value."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.benchmark import tuning
from nbv_gym.benchmark.tuning import GRID_SIZE, TUNABLE, Tuning, TuningConfig, tune
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.policies import load_policy


def test_every_tunable_policy_gets_the_same_budget_and_its_keyword_exists():
    for name, (keyword, grid) in TUNABLE.items():
        assert len(grid) == GRID_SIZE
        policy = load_policy(name, **{keyword: grid[0]})  # the constructor takes the keyword
        value = getattr(policy if hasattr(policy, keyword) else policy.ranking, keyword)
        assert value == grid[0]


def test_the_best_value_has_the_highest_mean_score():
    t = Tuning("ig-unknown", "lam", TuningConfig(episodes=2))
    t.scores = {0.1: [0.02, 0.04], 0.5: [0.05, 0.02], 0.02: [0.03, 0.03]}
    assert t.best == 0.5  # mean 0.035 against 0.03 and 0.03
    assert [r["chosen"] for r in t.table()] == [False, False, True]


def test_tuning_runs_on_a_training_pool_only_and_names_a_bad_policy():
    with pytest.raises(ConfigError, match="random: pool"):
        TuningConfig(pool="pp1-trees")
    with pytest.raises(UnknownNameError, match="Valid tunable policies: ig-entropy"):
        tune("closest-frontier")  # no parameter: nothing to tune


@pytest.mark.slow
def test_a_tuning_scores_every_value_on_the_same_episodes(monkeypatch):
    monkeypatch.setitem(TUNABLE, "ig-unknown", ("lam", (0.05, 5.0)))
    config = TuningConfig(episodes=1, time_budget_s=40.0)
    first = tune("ig-unknown", config, say=lambda _: None)
    again = tuning.episode_score("ig-unknown", {"lam": 0.05}, config, 0)
    assert first.scores[0.05] == [again]  # the same seed, the same world and episode
    assert all(0 < s[0] < 1 and np.isfinite(s[0]) for s in first.scores.values())
