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
from nbv_gym.episode import run_episode  # noqa: E402
from nbv_gym.policies import PolicyError, load_policy  # noqa: E402
from nbv_gym.policies.registry import model_path  # noqa: E402
from nbv_gym.rl.config import LearningConfig, TrainConfig  # noqa: E402
from nbv_gym.rl.hub import find_source  # noqa: E402
from nbv_gym.rl.train import train  # noqa: E402

BUDGET = 4
EPISODES = 2


@pytest.fixture(scope="module")
def packaged(world, tmp_path_factory):
    run = tmp_path_factory.mktemp("runs") / "tiny"
    config = TrainConfig(
        total_timesteps=32, n_envs=1, train_worlds=(world,), eval_worlds=(world,),
        max_steps=BUDGET, learning=LearningConfig(n_steps=16, batch_size=16, n_epochs=1),
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


def test_the_folder_holds_the_hub_files(packaged):
    names = {p.name for p in packaged.out.iterdir()}
    assert names == {"README.md", "config.toml", "results.json", "replay.gif",
                     "learning_curve.png", "maskableppo-ExploreBudget-v0.zip"}  # fmt: skip


def test_the_model_card_has_the_sb3_hub_metadata_with_the_masked_evaluation(packaged):
    meta, results = packaged.meta, packaged.results
    assert meta["library_name"] == "stable-baselines3"
    assert {BUDGET_ID, "stable-baselines3", "reinforcement-learning"} <= set(meta["tags"])
    (entry,) = meta["model-index"]
    (result,) = entry["results"]
    assert entry["name"] == "MaskablePPO" and result["dataset"]["type"] == BUDGET_ID
    assert "(masked)" in result["dataset"]["name"] and results["masked"] is True
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
        env = ExploreEnv(task="budget", world=world, max_steps=BUDGET)
        first_q = env.reset(seed=episode["seed"])[1]["q"]
        assert episode["return"] == pytest.approx(100.0 * (episode["q"] - first_q), abs=1e-9)
    returns = [e["return"] for e in episodes]
    assert packaged.results["mean_reward"] == pytest.approx(sum(returns) / len(returns))


def test_the_folder_loads_back_as_a_policy_and_runs_an_episode(packaged, world):
    policy = load_policy(f"sb3:{packaged.out}")
    result = run_episode(ExploreEnv(task="budget", world=world, max_steps=BUDGET), policy, 7)
    assert len(result.steps) == BUDGET + 1 and result.final["q"] > 0  # the first scan, BUDGET steps


def test_a_folder_with_two_models_is_refused(packaged, tmp_path):
    shutil.copytree(packaged.out, tmp_path / "two")
    shutil.copyfile(
        tmp_path / "two" / "maskableppo-ExploreBudget-v0.zip", tmp_path / "two" / "b.zip"
    )
    with pytest.raises(PolicyError, match=r"expected one model \.zip in it .* found b\.zip, mask"):
        load_policy(f"sb3:{tmp_path / 'two'}")


def test_the_shipped_model_is_found_with_its_config_and_curve():
    source = find_source("ppo-budget")
    assert source.model == model_path("ppo-budget")
    assert source.config.name == "ppo-budget.toml" and source.curve.name == "ppo-budget.png"


def test_a_run_folder_without_its_config_is_refused(tmp_path):
    (tmp_path / "final_model.zip").write_bytes(b"")
    with pytest.raises(PolicyError, match=r"training config .*config\.toml' is missing"):
        find_source(tmp_path)
