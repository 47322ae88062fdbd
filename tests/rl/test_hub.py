"""``nbv-gym package-model``: a tiny trained run packaged into a hub folder (model, config, model
card with the hub's metadata block, evaluation, replay, curve) that loads back as ``sb3:DIR``."""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import pytest

pytest.importorskip("sb3_contrib")
yaml = pytest.importorskip("yaml")

from typer.testing import CliRunner  # noqa: E402

from nbv_gym.cli.main import app  # noqa: E402
from nbv_gym.core.protocol import BUDGET_ID  # noqa: E402
from nbv_gym.env.explore import ExploreEnv  # noqa: E402
from nbv_gym.env.task import TaskConfig  # noqa: E402
from nbv_gym.episode import run_episode  # noqa: E402
from nbv_gym.policies import PolicyError, load_policy  # noqa: E402
from nbv_gym.policies.registry import model_path  # noqa: E402
from nbv_gym.rl.config import LearningConfig, TrainConfig  # noqa: E402
from nbv_gym.rl.hub import find_source, summarise  # noqa: E402
from nbv_gym.rl.train import train  # noqa: E402

BUDGET = 4
EPISODES = 2


@pytest.fixture(scope="module")
def packaged(world, tmp_path_factory):
    run = tmp_path_factory.mktemp("runs") / "tiny"
    config = TrainConfig(
        total_timesteps=32, n_envs=1, train_worlds=(world,), eval_worlds=(world,),
        task=TaskConfig(name="budget", budget_scans=BUDGET), learning=LearningConfig(n_steps=16, batch_size=16, n_epochs=1),
        checkpoint_every_steps=0, eval_every_steps=0,
    )  # fmt: skip
    train(config, run, progress_bar=False)
    out = tmp_path_factory.mktemp("hub") / "tiny-agent"
    command = ["package-model", str(run), "--out", str(out), "--episodes", str(EPISODES)]
    result = CliRunner().invoke(app, command)
    assert result.exit_code == 0, result.output
    card = (out / "README.md").read_text()
    _, front, body = card.split("---\n", 2)
    results = json.loads((out / "results.json").read_text())
    return SimpleNamespace(out=out, meta=yaml.safe_load(front), body=body, results=results)


MODEL_ZIP = "ppo_mask-nbv_gym-ExploreBudget-v0.zip"  # rl-zoo3's <algo>-<env id, / as ->.zip


def test_the_folder_holds_the_hub_files(packaged):
    names = {p.name for p in packaged.out.iterdir()}
    assert names == {"README.md", "config.toml", "results.json", "replay.gif",
                     "learning_curve.png", MODEL_ZIP, "config.yml", "env_kwargs.yml", "args.yml",
                     "train_eval_metrics.zip"}  # fmt: skip


def test_rl_zoo3_downloads_the_folder_as_a_run_that_loads_and_plays(
    packaged, tmp_path, monkeypatch
):
    """rl-zoo3's own hub tooling: ``download_from_hub`` (its Hub download pointed at the folder)
    finds every file it needs and lays them out as an rl-zoo3 run; rl-zoo3 reads the saved
    hyper-parameters, and the model of that run plays the environment its ``env_kwargs.yml``
    describes. (rl-zoo3's ``enjoy`` has no MaskablePPO; the run plays through ``sb3:``.)"""
    import gymnasium

    rl_zoo3_hub = pytest.importorskip("rl_zoo3.load_from_hub")
    from rl_zoo3.utils import get_saved_hyperparams

    def load_from_hub(repo_id: str, filename: str) -> str:  # the Hub's download, from the folder
        if not (packaged.out / filename).is_file():
            raise rl_zoo3_hub.HTTPError(f"404: {filename}")
        return str(packaged.out / filename)

    monkeypatch.setattr(rl_zoo3_hub, "load_from_hub", load_from_hub)
    env_name = rl_zoo3_hub.EnvironmentName(BUDGET_ID)
    rl_zoo3_hub.download_from_hub("ppo_mask", env_name, 1, str(tmp_path / "logs"), "someone")
    run = tmp_path / "logs" / "ppo_mask" / f"{env_name}_1"
    hyperparameters, _ = get_saved_hyperparams(str(run / env_name))
    assert hyperparameters["normalize"] is False and hyperparameters["n_steps"] == 16
    assert hyperparameters["policy"] == "nbv_gym.rl.extractor.MaskableGoalMapPolicy"
    assert (run / "results.json").is_file()  # the metrics archive, unpacked
    env_kwargs = yaml.safe_load((run / env_name / "env_kwargs.yml").read_text())
    assert env_kwargs["budget_scans"] == BUDGET and env_kwargs["invalid_action"] == "snap"
    env = gymnasium.make(BUDGET_ID, **env_kwargs)
    result = run_episode(env.unwrapped, load_policy(f"sb3:{run / f'{env_name}.zip'}"), 3)
    assert len(result.steps) == BUDGET + 1


def test_the_model_card_has_the_sb3_hub_metadata_with_the_masked_evaluation(packaged):
    meta, results = packaged.meta, packaged.results
    assert meta["library_name"] == "stable-baselines3"
    assert {BUDGET_ID, "stable-baselines3", "reinforcement-learning"} <= set(meta["tags"])
    (entry,) = meta["model-index"]
    (result,) = entry["results"]
    assert entry["name"] == "MaskablePPO"
    assert result["dataset"]["name"] == result["dataset"]["type"] == BUDGET_ID
    assert "(masked)" in result["dataset"]["split"] and results["masked"] is True
    metrics = {m["type"]: m for m in result["metrics"]}
    mean, std = results["mean_reward"], results["std_reward"]
    assert metrics["mean_reward"]["value"] == f"{mean:.2f} +/- {std:.2f}"
    q = results["overall"]["q"]
    assert q["low"] <= q["mean"] <= q["high"] and metrics["q"]["value"] == round(q["mean"], 4)
    assert "| **all** |" in packaged.body and "![replay" in packaged.body


def test_each_return_is_the_scaled_gain_in_q_of_its_episode(packaged):
    """No path penalty: the return is reward_scale · (final Q − Q after the first scan); the
    evaluation ran EPISODES episodes of BUDGET scans on the held-out world, seeds 0, 1."""
    episodes = packaged.results["episodes"]
    assert [e["seed"] for e in episodes] == list(range(EPISODES))
    world = episodes[0]["world"]
    for episode in episodes:
        env = ExploreEnv(task="budget", world=world, budget_scans=BUDGET)
        first_q = env.reset(seed=episode["seed"])[1]["q"]
        assert episode["return"] == pytest.approx(100.0 * (episode["q"] - first_q), abs=1e-9)
    returns = [e["return"] for e in episodes]
    assert packaged.results["mean_reward"] == pytest.approx(sum(returns) / len(returns))


def test_the_folder_loads_back_as_a_policy_and_runs_an_episode(packaged, world):
    policy = load_policy(f"sb3:{packaged.out}")
    result = run_episode(ExploreEnv(task="budget", world=world, budget_scans=BUDGET), policy, 7)
    assert len(result.steps) == BUDGET + 1 and result.final["q"] > 0  # the first scan, BUDGET steps


def test_a_folder_with_two_models_is_refused(packaged, tmp_path):
    shutil.copytree(packaged.out, tmp_path / "two")
    shutil.copyfile(tmp_path / "two" / MODEL_ZIP, tmp_path / "two" / "b.zip")
    with pytest.raises(
        PolicyError, match=r"expected one model \.zip in it .* found b\.zip, ppo_mask"
    ):
        load_policy(f"sb3:{tmp_path / 'two'}")


def test_the_shipped_model_is_found_with_its_config_and_curve():
    source = find_source("ppo-budget")
    assert source.model == model_path("ppo-budget")
    assert source.config.name == "ppo-budget.toml" and source.curve.name == "ppo-budget.png"


def test_a_run_folder_without_its_config_is_refused(tmp_path):
    (tmp_path / "final_model.zip").write_bytes(b"")
    with pytest.raises(PolicyError, match=r"training config .*config\.toml' is missing"):
        find_source(tmp_path)


def test_one_episode_per_world_gets_a_real_interval_and_a_single_episode_none():
    """Resampled within each world, one episode per world gives the point [m, m]; the episodes
    are then resampled across the worlds (the interval of a plain bootstrap of the mean). A
    world of one episode has no interval."""
    config = TrainConfig(eval_worlds=("a", "b", "c", "d"))
    returns = {"a": 1.0, "b": 2.0, "c": 4.0, "d": 8.0}
    rows = [{"world": w, "seed": 0, "return": r, "q": r / 100, "discovered": 0.5,
             "path_length_m": 10.0 * r} for w, r in returns.items()]  # fmt: skip
    results = summarise(rows, config, masked=True, seed=0)
    q = results["overall"]["q"]
    assert q["mean"] == pytest.approx(0.0375)
    # every resample is 4 draws from {0.01, 0.02, 0.04, 0.08}: the extremes bound the interval
    assert 0.01 <= q["low"] < q["mean"] < q["high"] <= 0.08
    assert "across the worlds" in results["interval"]
    assert results["per_world"]["a"]["q"] == {"mean": 0.01, "low": None, "high": None}


def test_the_hub_environment_is_the_one_of_training_lidar_and_effort_included():
    import gymnasium

    from nbv_gym.core.protocol import TIME_ID
    from nbv_gym.rl.hub import zoo_env_kwargs
    from nbv_gym.sensor.presets import lidar_preset

    task = TaskConfig(name="time", lidar="vlp-16", time_budget_s=90.0, speed_mps=0.5)
    config = TrainConfig(task=task, eval_worlds=("pp1-cuboids",))
    kwargs = zoo_env_kwargs(config)
    env = gymnasium.make(TIME_ID, **kwargs).unwrapped
    episode = env.sim.config.episode
    assert (episode.time_budget_s, episode.speed_mps, episode.scan_time_s) == (90.0, 0.5, 10.0)
    assert env.sim.config.lidar == lidar_preset("vlp-16").config != lidar_preset("os1-16").config
    assert kwargs["invalid_action"] == "snap"
