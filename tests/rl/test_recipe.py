"""``nbv-gym train --config RECIPE``: labels → imitation → RL as one resumable job on the tiny
world — the stages chain (the learner acts in iteration 1, RL starts from the last imitation),
a rerun of a finished recipe changes nothing, another config is refused, and the shipped actor
reads the agent's observation only."""

from __future__ import annotations

import json
import shutil
import tomllib
import zipfile

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from nbv_gym.configs import config_file
from nbv_gym.env.layers import OPTIONAL_LAYERS
from nbv_gym.env.observation import BASE_LAYERS
from nbv_gym.env.views import PRIVILEGED_KEYS
from nbv_gym.rl.config import load_train_config
from nbv_gym.rl.labelfile import EpisodeLabels
from tests.helpers import invoke

RL_STEPS = 16


@pytest.fixture(scope="module")
def recipe(world, tmp_path_factory):
    """A recipe of two DAgger iterations of two episodes (one held out) and 16 RL steps."""
    folder = tmp_path_factory.mktemp("recipe")
    path = folder / "tiny-recipe.toml"
    path.write_text(
        f"train_worlds = [{json.dumps(world)}]\neval_worlds = [{json.dumps(world)}]\n"
        'task = "time"\ntime_budget_s = 40.0\nn_envs = 1\n'
        f"total_timesteps = {RL_STEPS}\ncheckpoint_every_steps = 8\neval_every_steps = 0\n"
        'observation_layers = ["gain_sigma", "gain_unknown", "nbv_candidates"]\n'
        "[learning]\nn_steps = 8\nbatch_size = 8\nn_epochs = 1\n"
        "[imitation]\niterations = 2\nepisodes_per_iteration = 2\nvalidation_share = 0.5\n"
        "epochs = 2\nbatch_size = 4\n"
    )
    out = folder / "run"
    result = invoke("train", "--config", path, "--out", out, "--no-progress")
    assert result.code == 0, result.err
    return path, out, result


def test_the_stages_chain_into_one_folder(recipe):
    _, out, result = recipe
    for i in (0, 1):
        assert sorted(p.name for p in (out / "labels" / f"iter-{i}").iterdir()) == [
            "episode-00000.npz", "episode-00001.npz"]  # fmt: skip
        assert {"model.zip", "checkpoint.pt", "metrics.csv"} <= {
            p.name for p in (out / "imitation" / f"iter-{i}").iterdir()}  # fmt: skip
    first = EpisodeLabels.from_file(out / "labels" / "iter-0" / "episode-00000.npz")
    later = [EpisodeLabels.from_file(p) for p in (out / "labels" / "iter-1").iterdir()]
    assert first.teacher_acted.all()  # iteration 0: the teacher alone
    assert not all(label.teacher_acted.all() for label in later)  # β = 0.5: the learner too
    rl = tomllib.loads((out / "rl" / "config.toml").read_text())
    assert rl["init_model"] == str(out / "imitation" / "iter-1" / "model.zip")
    assert "imitation" not in rl
    assert f"steps              {RL_STEPS}" in result.out
    with zipfile.ZipFile(out / "rl" / "final_model.zip") as archive:
        assert json.loads(archive.read("data"))["num_timesteps"] == RL_STEPS


def test_a_finished_recipe_run_again_changes_nothing(recipe):
    path, out, _ = recipe
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    result = invoke("train", "--config", path, "--out", out, "--no-progress")
    assert result.code == 0, result.err
    changed = [p for p, t in before.items() if p.stat().st_mtime_ns != t]
    assert changed == [] and "stage labels" not in result.err


def test_a_recipe_folder_refuses_another_config_and_resume_or_force(recipe, tmp_path):
    path, out, _ = recipe
    other = tmp_path / "other.toml"
    other.write_text(path.read_text().replace("epochs = 2", "epochs = 3"))
    result = invoke("train", "--config", other, "--out", out)
    assert result.code == 2 and "imitation.epochs" in result.err and "another config" in result.err
    for flag in (["--force"], ["--resume", out / "rl" / "final_model.zip"]):
        result = invoke("train", "--config", path, "--out", out, *flag)
        assert result.code == 2 and "rerun the same command" in result.err


def test_a_recipe_folder_from_before_budget_scans_goes_on(recipe, tmp_path):
    """A recipe.toml written when a config held ``max_steps = 12`` whatever its task (the time
    task never reads it) is the same recipe: the finished run goes on, as a no-op."""
    path, out, _ = recipe
    old = tmp_path / "run"
    shutil.copytree(out, old, symlinks=True)
    stored = old / "recipe.toml"
    stored.write_text("max_steps = 12\n" + stored.read_text().replace("max_steps = ", "# "))
    result = invoke("train", "--config", path, "--out", old, "--no-progress")
    assert result.code == 0, result.err


def test_the_shipped_actor_reads_the_agent_observation_only(recipe):
    """The final model's inputs are observation layers the robot computes from its own map
    (and its state): none is a privileged key, and it runs as a normal (non-oracle) policy,
    which the harness hands the agent view of ``info``."""
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.episode import make_env, run_episode
    from nbv_gym.policies import is_oracle, load_policy

    path, out, _ = recipe
    policy = load_policy(f"sb3:{out / 'rl' / 'final_model.zip'}")
    keys = set(policy.model.observation_space.spaces)
    assert keys <= {*BASE_LAYERS, *OPTIONAL_LAYERS, "state"}
    assert not keys & set(PRIVILEGED_KEYS) and not is_oracle(policy)
    config = load_train_config(path)
    env = make_env(ExploreEnv(world=config.train_worlds[0], **config.env_kwargs()).config, policy)
    result = run_episode(env, policy, seed=3)
    assert not result.oracle and len(result.steps) >= 2
    assert np.isfinite([row["q"] for row in result.steps]).all()


def test_the_shipped_recipe_is_a_time_task_recipe_with_the_references_gain_layers():
    config = load_train_config(config_file("imitation-time", "train"))
    assert config.task.name == "time" and config.imitation is not None
    assert config.imitation.teacher == "oracle-time" and config.init_model == ""
    assert {"gain_sigma", "gain_unknown", "nbv_candidates"} <= set(config.task.observation_layers)
    ppo_time = load_train_config(config_file("ppo-time", "train"))
    assert ppo_time.imitation is None and ppo_time.task.observation_layers == ()
