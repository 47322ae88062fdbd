"""Imitation of a teacher's labels on a toy label set whose teacher prefers the candidate of the
highest ``n_obs``: the loss falls and the top-1 agreement on held-out episodes rises; the target
distribution; an imitation stopped after an epoch goes on to the same weights; determinism."""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

th = pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from nbv_gym.env.observation import BASE_LAYERS, observation_space  # noqa: E402
from nbv_gym.env.task import TaskConfig  # noqa: E402
from nbv_gym.rl import imitation as imitation_module  # noqa: E402
from nbv_gym.rl.config import ImitationConfig, LearningConfig, TrainConfig  # noqa: E402
from nbv_gym.rl.imitation import (  # noqa: E402
    CHECKPOINT,
    MODEL,
    States,
    discounted_returns,
    imitate,
    teacher_targets,
)
from nbv_gym.rl.labelfile import EpisodeLabels, EpisodeRecorder, LabelFileError  # noqa: E402

N_GOALS = 3600
CANDIDATES = 12


def toy_shards(folder: Path, episodes: int, states: int, seed: int) -> list[Path]:
    """Shards of random observations whose teacher values each of 12 candidates (marked in
    ``nbv_candidates``) by its ``n_obs`` cell: the best is learnable from the layers alone."""
    space = observation_space(N_GOALS, {"gain_unknown": 5e4, "nbv_candidates": 1.0}, 30.0)
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for k in range(episodes):
        recorder = EpisodeRecorder.of_space(space)
        for _ in range(states):
            observation = {key: rng.random(N_GOALS).astype(np.float32) for key in BASE_LAYERS}
            observation["gain_unknown"] = (5e4 * rng.random(N_GOALS) ** 4).astype(np.float32)
            goals = rng.choice(N_GOALS, CANDIDATES, replace=False)
            observation["nbv_candidates"] = np.isin(np.arange(N_GOALS), goals).astype(np.float32)
            observation["state"] = rng.random(6).astype(np.float32)
            values = observation["n_obs"][goals].astype(np.float64) * 1e-4
            recorder.add(observation, np.ones(N_GOALS, bool), goals, values, int(goals[0]), True)
            recorder.rewarded(float(rng.random() * 1e-3))
        path = folder / f"episode-{k:05d}.npz"
        path.write_bytes(recorder.labels("toy", 0, k, seed).to_bytes())
        paths.append(path)
    return paths


def toy_config(epochs: int) -> TrainConfig:
    return TrainConfig(
        train_worlds=("toy",), n_envs=1,
        task=TaskConfig(name="time", observation_layers=("gain_unknown", "nbv_candidates")),
        learning=LearningConfig(n_steps=8, batch_size=8),
        imitation=ImitationConfig(epochs=epochs, batch_size=8, learning_rate=1e-2),
    )  # fmt: skip


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    folder = tmp_path_factory.mktemp("toy")
    return toy_shards(folder / "train", 6, 24, seed=1), toy_shards(folder / "held", 2, 24, seed=2)


def metrics(folder: Path) -> list[dict[str, float]]:
    import csv

    with open(folder / "metrics.csv", newline="") as file:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(file)]


def test_the_loss_falls_and_the_agreement_rises_on_a_toy_set(toy, tmp_path):
    train, held = toy
    imitate(toy_config(6), 0, train, held, tmp_path, progress=False)
    rows = metrics(tmp_path)
    assert [r["epoch"] for r in rows] == [1, 2, 3, 4, 5, 6]
    losses = [r["train_loss"] for r in rows]
    assert all(b < a for a, b in itertools.pairwise(losses)), losses
    assert rows[-1]["validation_loss"] < rows[0]["validation_loss"] - 1.0  # nats
    assert rows[-1]["top1"] >= 0.5 > 1 / CANDIDATES >= rows[0]["top1"] - 0.2
    assert rows[-1]["top1"] > rows[0]["top1"] and rows[-1]["regret"] < rows[0]["regret"]
    assert rows[-1]["outside"] <= rows[0]["outside"] and rows[-1]["validation_states"] == 48


def test_a_stopped_imitation_goes_on_to_the_same_weights(toy, tmp_path, monkeypatch):
    train, held = toy
    config = toy_config(2)
    imitate(config, 0, train, held, tmp_path / "whole", progress=False)
    written = imitation_module._checkpoint

    def stop_after_one(out, policy, optimizer, state):
        written(out, policy, optimizer, state)
        raise KeyboardInterrupt

    monkeypatch.setattr(imitation_module, "_checkpoint", stop_after_one)
    with pytest.raises(KeyboardInterrupt):
        imitate(config, 0, train, held, tmp_path / "stopped", progress=False)
    monkeypatch.setattr(imitation_module, "_checkpoint", written)
    assert (tmp_path / "stopped" / CHECKPOINT).exists() and not (
        tmp_path / "stopped" / MODEL
    ).exists()
    imitate(config, 0, train, held, tmp_path / "stopped", progress=False)
    whole, resumed = (th.load(tmp_path / f / CHECKPOINT) for f in ("whole", "stopped"))
    for key, value in whole["policy"].items():
        assert th.equal(value, resumed["policy"][key]), key
    assert metrics(tmp_path / "whole") == metrics(tmp_path / "stopped")


def test_targets_weigh_candidates_by_their_share_of_the_best_value():
    p = teacher_targets(np.array([2.0, 1.0, 2.0, 0.0]), temperature=0.1)
    assert p.sum() == pytest.approx(1) and p[0] == p[2] == p.max()
    assert p[1] / p[0] == pytest.approx(np.exp(-5))  # half the best: e^(-0.5 / 0.1)
    assert np.allclose(teacher_targets(np.zeros(4), 0.1), 0.25)
    assert teacher_targets(np.array([-1.0, -3.0]), 1.0)[0] == pytest.approx(
        1 / (1 + np.exp(-2 / 3))
    )


def test_returns_are_discounted_sums():
    assert np.allclose(discounted_returns(np.array([1.0, 2.0, 4.0]), 0.5), [3.0, 4.0, 4.0])


def test_the_imitation_config_is_checked():
    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match="temperature: must be a finite number > 0"):
        ImitationConfig(temperature=0)
    with pytest.raises(ConfigError, match="validation_share: must be in"):
        ImitationConfig(validation_share=1.0)
    with pytest.raises(ConfigError, match="imitation: imitates with the action mask"):
        replace(toy_config(1), algorithm="PPO")
    config = ImitationConfig(episodes_per_iteration=20, validation_share=0.1)
    assert [k for k in range(20) if config.is_validation(k)] == [9, 19]
    assert not ImitationConfig(validation_share=0.99).is_validation(0)  # one to train on
    assert [config.teacher_share(i) for i in range(3)] == [1.0, 0.5, 0.25]


@pytest.mark.parametrize("edit", ["drop-layer", "fewer-goals"])
def test_shards_of_another_layout_are_refused_not_mixed(tmp_path, edit):
    good, other = toy_shards(tmp_path, 2, 3, seed=4)
    labels = EpisodeLabels.from_file(other)
    if edit == "drop-layer":
        labels.keys, labels.highs, labels.layers = (
            labels.keys[:-1],
            labels.highs[:-1],
            labels.layers[:, :-1],
        )
    else:
        labels.layers = labels.layers[:, :, :100]
    other.write_bytes(labels.to_bytes())
    with pytest.raises(LabelFileError, match=r"episode-00001.npz' holds the layers .* another run"):
        States.load([good, other], toy_config(1))
    with pytest.raises(LabelFileError, match="holds the layers"):  # alone, as the validation set
        States.load([other], toy_config(1), like=good)


def test_a_damaged_checkpoint_is_refused_naming_it(toy, tmp_path):
    (tmp_path / CHECKPOINT).write_bytes(b"not a checkpoint")
    with pytest.raises(LabelFileError, match=r"checkpoint.pt' is no imitation checkpoint"):
        imitate(toy_config(1), 0, toy[0], toy[1], tmp_path, progress=False)
