"""nbv-gym record: a Minari dataset loaded back by minari itself and replayed to the same rewards."""

from __future__ import annotations

import numpy as np
import pytest

minari = pytest.importorskip("minari")

from nbv_gym.env.task import TaskConfig  # noqa: E402
from nbv_gym.rl.dataset import RecordError, record_dataset  # noqa: E402

DATASET = "nbv-gym/pp1-cuboids/closest-frontier-v0"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("datasets")
    record_dataset(
        "closest-frontier", "pp1-cuboids", out, TaskConfig(max_steps=3), episodes=2, seed=5
    )
    return out


def test_dataset_loads_with_minari_and_replays_to_the_same_rewards(recorded, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(recorded))
    dataset = minari.load_dataset(DATASET)
    assert dataset.total_episodes == 2 and dataset.total_steps == 6
    env = dataset.recover_environment()
    metadata = list(dataset.storage.get_episode_metadata(dataset.episode_indices))
    for episode, meta in zip(dataset.iterate_episodes(), metadata, strict=True):
        observation, info = env.reset(seed=int(meta["seed"]))
        np.testing.assert_array_equal(observation["known"], episode.observations["known"][0])
        masks = episode.infos["action_mask"]
        np.testing.assert_array_equal(info["action_mask"], masks[0])
        rewards = []
        for t, action in enumerate(episode.actions):
            assert masks[t][action] == 1  # every recorded action was valid when taken
            observation, reward, terminated, truncated, info = env.step(int(action))
            rewards.append(reward)
            np.testing.assert_array_equal(info["action_mask"], masks[t + 1])
        np.testing.assert_array_equal(rewards, episode.rewards)
        np.testing.assert_array_equal(episode.infos["q"][1:] - episode.infos["q"][:-1], rewards)
        assert terminated == episode.terminations[-1] and truncated == episode.truncations[-1]
    assert [int(m["seed"]) for m in metadata] == [5, 6]


def test_recording_into_an_existing_dataset_is_refused(recorded):
    with pytest.raises(RecordError, match="exists; choose another --out or id"):
        record_dataset("closest-frontier", "pp1-cuboids", recorded, TaskConfig(max_steps=1))


def test_the_dataset_names_its_code_and_requirements(recorded, monkeypatch):
    from importlib.metadata import version

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(recorded))
    dataset = minari.load_dataset(DATASET)
    metadata = dataset.storage.metadata
    assert metadata["requirements"] == [f"nbv-gym=={version('nbv-gym')}"]
    assert metadata["code_permalink"].startswith("https://github.com/nbv-gym/nbv-gym/tree/")


def test_a_budget_recording_runs_the_budget_without_termination(tmp_path):
    dataset = record_dataset(
        "random-frontier", "pp1-cuboids", tmp_path, TaskConfig(name="budget", budget_scans=4)
    )
    assert dataset.total_steps == 4 and dataset.env_spec.id == "nbv_gym/ExploreBudget-v0"


def test_a_time_recording_runs_until_its_time_budget_is_spent(tmp_path):
    dataset = record_dataset(
        "closest-frontier", "pp1-cuboids", tmp_path, TaskConfig(name="time", time_budget_s=45.0)
    )
    assert dataset.env_spec.id == "nbv_gym/ExploreTime-v0"
    (episode,) = dataset.iterate_episodes()
    assert episode.truncations[-1] and 1 <= dataset.total_steps < 45 / 10  # ≥ 10 s a scan
