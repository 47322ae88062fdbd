"""The training config: strict TOML loading, overrides, the shipped example."""

from __future__ import annotations

import pytest

from nbv_gym.configs import config_file
from nbv_gym.core.errors import ConfigError
from nbv_gym.rl.config import EVAL_WORLDS, TRAIN_WORLDS, TrainConfig, load_train_config
from nbv_gym.worlds import benchmark_names

EXAMPLE = config_file("ppo-wide")


def test_example_config_is_the_default_config():
    assert load_train_config(EXAMPLE) == TrainConfig()


def test_default_config_trains_on_the_wide_pool_and_evaluates_on_its_held_out_worlds():
    assert TRAIN_WORLDS == ("random:wide",) and TrainConfig().world_pool_size >= 256
    assert EVAL_WORLDS == tuple(f"random:wide/heldout-{k}" for k in range(8))
    assert not set(EVAL_WORLDS) & set(benchmark_names())
    assert TrainConfig().task.name == "budget"


def test_the_shipped_agents_recipes_still_describe_how_they_were_trained():
    for name in ("ppo", "ppo-time"):  # as the models' stored configs say
        config = load_train_config(config_file(name, "train"))
        assert config.train_worlds == ("random:mixed",) and config.world_pool_size == 32
    wide = load_train_config(config_file("ppo-time-wide", "train"))
    assert (wide.task.name, wide.train_worlds, wide.eval_worlds) == (
        "time",
        TRAIN_WORLDS,
        EVAL_WORLDS,
    )


def test_overrides_replace_file_values(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text("total_timesteps = 1000\nn_envs = 4\n")
    config = load_train_config(path, {"total_timesteps": 64, "seed": None})
    assert (config.total_timesteps, config.n_envs, config.seed) == (64, 4, 0)


@pytest.mark.parametrize(
    "text, match",
    [
        ("total_timestep = 5\n", "Unknown key total_timestep"),
        ("[learning]\nn_step = 5\n", r"Unknown key learning\.n_step"),
        ('algorithm = "SAC"\n', "algorithm: expected one of MaskablePPO, PPO, A2C"),
        ('observation_layers = ["gain_nob"]\n', r"observation_layers: unknown layer\(s\)"),
        ("[learning]\ngamma = 1.5\n", r"learning: gamma: must be in \(0, 1\]"),
        ("n_envs = 0\n", "n_envs: must be ≥ 1"),
        ("n_envs = 1\n", r"learning\.batch_size: must be ≤ n_steps · n_envs = 128 · 1 = 128"),
        ('task = "race"\n', "task: expected one of explore, budget"),
        ('train_worlds = ["random:trees", "pp1-trees"]\n', "train_worlds: a world distribution"),
        ("features_dim = 16\n", r"features_dim: must be > 32 \(the robot state's features"),
        ("features_dim = 32\n", "features_dim: must be > 32"),  # no feature left for the map
        ("[learning]\nlearning_rate = inf\n", "learning_rate: must be a finite number > 0"),
        ("[learning]\nmax_grad_norm = nan\n", "max_grad_norm: must be a finite number"),
        ("[learning]\nvf_coef = -1.0\n", "vf_coef: must be ≥ 0"),
        ("reward_scale = inf\n", "reward_scale: must be a finite number > 0"),
        ("[imitation]\ntemperature = inf\n", "temperature: must be a finite number > 0"),
        ("[imitation]\nlearning_rate = inf\n", "learning_rate: must be a finite number > 0"),
        ("[imitation]\nvalue_coef = nan\n", "value_coef: must be a finite number ≥ 0"),
    ],
    ids=[
        "unknown-key",
        "unknown-nested-key",
        "algorithm",
        "layer",
        "gamma",
        "n_envs",
        "batch-larger-than-rollout",
        "task",
        "distribution-with-worlds",
        "features-below-the-state",
        "no-map-features",
        "learning-rate-inf",
        "grad-norm-nan",
        "vf-coef-negative",
        "reward-scale-inf",
        "imitation-temperature-inf",
        "imitation-learning-rate-inf",
        "imitation-value-coef-nan",
    ],
)
def test_bad_values_are_refused_with_their_key(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_train_config(path)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_train_config(tmp_path / "nope.toml")


def test_a_dotted_override_sets_a_key_of_a_table_so_one_env_can_train():
    """``nbv-gym train --n-envs 1`` is refused by the shipped batch size (256 > 128 · 1), and the
    refusal names the flag that lowers it; ``--batch-size`` reaches ``learning.batch_size``."""
    shipped = config_file("ppo", "train")
    with pytest.raises(ConfigError, match=r"lower it \(nbv-gym train --batch-size 128\)"):
        load_train_config(shipped, {"n_envs": 1})
    config = load_train_config(shipped, {"n_envs": 1, "learning.batch_size": 128})
    assert config.n_envs == 1 and config.learning.batch_size == 128
    assert config.learning.n_steps == 128  # the table's other keys stay the file's
    with pytest.raises(ConfigError, match="batch_sise"):
        load_train_config(shipped, {"learning.batch_sise": 128})
