"""Probes of the fifth round, as a hostile user tried them (ids as in the round's table): the team
task's inputs (T), the imitation recipe's config and label shards (R), the pool world names
(W) and the locale (N05). Each is one line naming the problem. The classes' own tests live beside
their code (tests/team, tests/rl/test_config.py, test_labels.py, test_imitation.py,
tests/worlds/test_distribution.py, tests/core/test_text_encoding.py); these keep the user's view
of each, cheaply (no world is built).
"""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.rl.config import load_train_config
from nbv_gym.team.policies import EachRobot, TeamPolicyError, UtilityFrontier
from nbv_gym.team.simulator import check_team_size
from nbv_gym.worlds import load_spec


@pytest.mark.parametrize(
    ("starts", "message"),
    [
        ([(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)], r"robot 0's start must be \(x, y\)"),  # T13
        ([(0.0, 0.0), "ab"], "robot 1's start must be"),  # T14
        ([(0.0, 0.0), np.array([1.0, np.nan, 2.0])], "robot 1's start must be"),
    ],
)
def test_a_team_start_that_is_no_xy_pair_is_one_line(starts, message):
    with pytest.raises(ConfigError, match=message):
        check_team_size(2, starts)


def test_team_policy_weights_and_sizes_are_checked_t_policies():
    with pytest.raises(ConfigError, match="beta must be a finite number"):
        UtilityFrontier(beta=float("nan"))
    with pytest.raises(ConfigError, match="range_m must be a finite number > 0"):
        UtilityFrontier(range_m=0.0)
    with pytest.raises(TeamPolicyError, match="got none"):
        EachRobot([])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("features_dim = 16\n", "features_dim: must be > 32"),  # R23, R24
        ("[imitation]\ntemperature = inf\n", "temperature: must be a finite number > 0"),  # R12
        ("[imitation]\nlearning_rate = inf\n", "learning_rate: must be a finite number > 0"),  # R13
    ],
)
def test_a_recipe_config_out_of_range_is_refused_before_any_label(tmp_path, text, message):
    path = tmp_path / "recipe.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match=message):
        load_train_config(path)


@pytest.mark.parametrize(
    "name", ["random:wide/-1", "random:wide/heldout-", "random:wide/1e3", "random:wide/0/1"]
)
def test_a_pool_world_name_past_its_form_names_the_form_w08_w15(name):
    with pytest.raises(ConfigError, match=r"a pool's world is random:<kind>/<k> or"):
        load_spec(name)


@pytest.mark.parametrize("name", ["random:wide/100000", "random:wide/heldout-100000"])
def test_a_pool_world_past_its_bound_is_refused_and_the_last_is_not_w04_w07(name):
    with pytest.raises(ConfigError, match="the index must be below 100000"):
        load_spec(name)
    assert load_spec(name.replace("100000", "99999")).name.endswith("99999")


def test_a_distribution_where_one_world_is_needed_names_its_worlds_w21():
    with pytest.raises(ConfigError, match="is a distribution, not one world"):
        load_spec("random:wide")
