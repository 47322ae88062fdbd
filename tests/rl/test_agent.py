"""Training, saving, loading as a policy and resuming, on a tiny world (a few hundred steps)."""

from __future__ import annotations

import csv
import sys
from dataclasses import replace
from types import SimpleNamespace

import gymnasium
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from gymnasium import spaces

from nbv_gym.core.errors import MissingExtraError
from nbv_gym.core.protocol import EpisodeConfig
from nbv_gym.env.explore import EnvConfig
from nbv_gym.env.task import TaskConfig
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import PolicyError, load_policy, required_layers
from nbv_gym.rl.agent import SB3Policy, check_spaces
from nbv_gym.rl.config import LearningConfig, TrainConfig
from nbv_gym.rl.train import require_rl, train
from nbv_gym.simulator import SimulatorConfig


@pytest.fixture(scope="module")
def config(world):
    return TrainConfig(
        total_timesteps=128,
        n_envs=2,
        train_worlds=(world,),
        eval_worlds=(world,),
        task=TaskConfig(name="budget", budget_scans=8),
        learning=LearningConfig(n_steps=32, batch_size=32, n_epochs=2),
        checkpoint_every_steps=64,
        eval_every_steps=64,
        eval_episodes=1,
    )


@pytest.fixture(scope="module")
def run(tmp_path_factory, config):
    out = tmp_path_factory.mktemp("runs") / "tiny"
    model = train(config, out, progress_bar=False)
    return SimpleNamespace(out=out, model=model)


def env_config(world: str, max_steps: int = 6) -> EnvConfig:
    return EnvConfig(SimulatorConfig(world=world, episode=EpisodeConfig(max_steps=max_steps)))


@pytest.mark.slow
def test_training_leaves_a_self_describing_run_folder(run):
    names = {p.name for p in run.out.iterdir()}
    assert {"config.toml", "system_info.txt", "final_model.zip", "best_model.zip"} <= names
    assert {p.name for p in (run.out / "checkpoints").iterdir()} == {
        "model_64_steps.zip",
        "model_128_steps.zip",
    }
    logs = run.out / "logs" / "run-1"
    assert any(p.name.startswith("events.out.tfevents") for p in logs.iterdir())
    rows = list(csv.DictReader(open(logs / "progress.csv")))
    assert sorted({int(r["time/total_timesteps"]) for r in rows}) == [64, 128]
    assert run.model.num_timesteps == 128


@pytest.mark.slow
def test_trained_model_runs_as_a_policy_on_valid_goals_only(run, world):
    policy = load_policy(f"sb3:{run.out / 'final_model.zip'}")
    assert required_layers(policy) == ()
    env = make_env(env_config(world), policy)
    observation, info = env.reset(seed=3)
    for _ in range(5):
        goal = policy.act(observation, info)
        assert info["action_mask"][goal]
        observation, _, terminated, truncated, info = env.step(goal)
        if terminated or truncated:
            break
    result = run_episode(env, policy, seed=4)
    assert len(result.steps) >= 2 and result.final["q"] > 0


@pytest.mark.slow
def test_save_load_round_trip_gives_identical_actions(run, world, tmp_path):
    path = tmp_path / "copy.zip"
    run.model.save(path)
    original, copy = SB3Policy(run.out / "final_model.zip"), SB3Policy(path)
    env = make_env(env_config(world), original)
    observation, info = env.reset(seed=5)
    for _ in range(4):
        expected, _ = run.model.predict(
            observation, action_masks=info["action_mask"], deterministic=True
        )
        actions = {original.act(observation, info), copy.act(observation, info), int(expected)}
        assert len(actions) == 1
        observation, _, terminated, truncated, info = env.step(actions.pop())
        if terminated or truncated:
            break


@pytest.mark.slow
def test_resume_continues_the_step_count(run, config):
    checkpoint = run.out / "checkpoints" / "model_128_steps.zip"
    model = train(replace(config, total_timesteps=192), run.out, resume=checkpoint,
                  progress_bar=False)  # fmt: skip
    assert model.num_timesteps == 192
    rows = list(csv.DictReader(open(run.out / "logs" / "run-2" / "progress.csv")))
    assert sorted({int(r["time/total_timesteps"]) for r in rows}) == [192]


def test_model_for_another_action_space_is_refused(tmp_path):
    from stable_baselines3 import PPO

    path = tmp_path / "cartpole.zip"
    PPO("MlpPolicy", gymnasium.make("CartPole-v1"), n_steps=8, batch_size=8).save(path)
    with pytest.raises(PolicyError, match=r"action space Discrete\(2\).*needs Discrete\(3600\)"):
        load_policy(f"sb3:{path}")


class _OtherLayersEnv(gymnasium.Env):
    """Discrete(3600) like Explore-v0, but observing other layers."""

    observation_space = spaces.Dict(
        {
            "known": spaces.Box(0, 1, (3600,), np.float32),
            "elevation": spaces.Box(0, 1, (3600,), np.float32),
            "state": spaces.Box(-2, 2, (6,), np.float32),
        }
    )
    action_space = spaces.Discrete(3600)


def test_model_for_other_observation_layers_is_refused(tmp_path):
    from sb3_contrib import MaskablePPO

    path = tmp_path / "other.zip"
    MaskablePPO("MultiInputPolicy", _OtherLayersEnv(), n_steps=8, batch_size=8).save(path)
    with pytest.raises(PolicyError, match=r"other observation layers.*unknown \['elevation'\]"):
        load_policy(f"sb3:{path}")


def test_optional_layers_of_a_model_are_declared():
    from nbv_gym.env.observation import BASE_LAYERS

    box = spaces.Box(0, 1, (3600,), np.float32)
    entries = {k: box for k in (*BASE_LAYERS, "gain_sigma", "gain_nobs")}
    space = spaces.Dict({**entries, "state": spaces.Box(-2, 2, (6,), np.float32)})
    model = SimpleNamespace(action_space=spaces.Discrete(3600), observation_space=space)
    assert check_spaces(model, "m.zip") == ("gain_nobs", "gain_sigma")


def test_missing_model_file_is_refused(tmp_path):
    with pytest.raises(PolicyError, match="No SB3 model at"):
        load_policy(f"sb3:{tmp_path / 'nope.zip'}")


def test_missing_rl_extra_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "sb3_contrib", None)
    with pytest.raises(MissingExtraError, match=r"nbv-gym\[rl\]") as raised:
        require_rl()
    # the CPU build first: a plain install of the extra pulls the multi-GB CUDA build
    assert "--index-url https://download.pytorch.org/whl/cpu, then pip install" in str(raised.value)


@pytest.mark.slow
@pytest.mark.parametrize("algorithm, network", [("PPO", "goal-map"), ("A2C", "dense")])
def test_unmasked_algorithms_train_and_act_on_valid_goals(
    config, world, tmp_path, algorithm, network
):
    small = replace(config, algorithm=algorithm, network=network, n_envs=1, total_timesteps=32,
                    checkpoint_every_steps=0, eval_every_steps=0)  # fmt: skip
    train(small, tmp_path, progress_bar=False)
    policy = load_policy(f"sb3:{tmp_path / 'final_model.zip'}")
    assert not policy.masked
    result = run_episode(make_env(env_config(world, max_steps=4), policy), policy, seed=1)
    assert len(result.steps) >= 2


@pytest.mark.parametrize("member", ["policy.pth", "pytorch_variables.pth", "policy.optimizer.pth"])
def test_a_model_zip_broken_past_its_data_json_is_one_line(tmp_path, member):
    import zipfile

    from nbv_gym.policies import model_path

    broken = tmp_path / "broken.zip"
    with zipfile.ZipFile(model_path("ppo-budget")) as source, zipfile.ZipFile(broken, "w") as out:
        for info in source.infolist():
            data = source.read(info)
            out.writestr(info, data[: len(data) // 3] if info.filename == member else data)
    if member not in zipfile.ZipFile(broken).namelist():
        pytest.skip(f"the shipped model has no {member}")
    with pytest.raises(PolicyError, match="is not a loadable model") as error:
        SB3Policy(broken).reset(0)
    assert "\n" not in str(error.value)
