"""DAgger label collection on the tiny world: what a shard holds (the teacher's own values on the
very states the episode visited, the observation within half a quantisation level), who acts
(the teacher, the learner, or a mixture), and a collection killed mid-way that, run again, ends
with the shards of an uninterrupted one."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.env.observation import BASE_LAYERS
from nbv_gym.env.task import TaskConfig
from nbv_gym.policies.teacher import OracleTime
from nbv_gym.rl.config import ImitationConfig, LearningConfig, TrainConfig
from nbv_gym.rl.labelfile import (
    LEVELS,
    EpisodeLabels,
    LabelFileError,
    decoding_table,
    encode_layers,
)
from nbv_gym.rl.labels import collect, episode_seed

LAYERS = ("gain_sigma", "gain_unknown", "nbv_candidates")
#: A short time budget: a few decisions per episode.
BUDGET_S = 50.0


def tiny_config(world: str, **imitation) -> TrainConfig:
    """A recipe on the tiny world: three episodes an iteration, a short time budget."""
    return TrainConfig(
        train_worlds=(world,), eval_worlds=(world,), n_envs=1,
        task=TaskConfig(name="time", time_budget_s=BUDGET_S, observation_layers=LAYERS), learning=LearningConfig(n_steps=8, batch_size=8),
        imitation=ImitationConfig(**{"episodes_per_iteration": 3, "validation_share": 0.34,
                                     **imitation}),
    )  # fmt: skip


@pytest.fixture(scope="module")
def collected(world, tmp_path_factory) -> tuple[TrainConfig, list[Path]]:
    config = tiny_config(world)
    return config, collect(config, tmp_path_factory.mktemp("labels"), 0, None, progress=False)


def test_stored_values_are_the_teachers_on_the_visited_states(collected):
    """Replaying an episode's stored actions from its seed, the teacher's values at every state
    are the stored ones, bit for bit, and so are the state, the mask and the rewards."""
    config, paths = collected
    labels = EpisodeLabels.from_file(paths[1])
    assert labels.seed == episode_seed(config.seed, 0, 1) and labels.world == "tiny-cuboids"
    teacher = OracleTime()
    env = ExploreEnv(world=config.train_worlds[0], **config.env_kwargs())
    observation, info = env.reset(seed=labels.seed)
    teacher.reset(labels.seed)
    teacher.attach(env)
    table = decoding_table(labels.highs)
    for t, goal in enumerate(labels.action):
        values = teacher.values(observation, info)
        goals, stored = labels.teacher_values(t)
        assert np.array_equal(goals, teacher.last_evaluation["goals"])
        assert np.array_equal(stored, values[goals])
        assert np.array_equal(labels.masks()[t], info["action_mask"].astype(bool))
        assert np.array_equal(labels.state[t], observation["state"])
        for c, key in enumerate(labels.keys):
            decoded = table[c][labels.layers[t, c]]
            assert np.allclose(_unit(decoded, labels.highs[c]),
                               _unit(observation[key], labels.highs[c]), atol=0.5 / LEVELS)  # fmt: skip
        assert goal == goals[np.argmax(stored)]  # iteration 0: the teacher acts
        observation, reward, *_, info = env.step(int(goal))
        assert reward == labels.reward[t]
    assert labels.teacher_acted.all() and len(labels) == len(labels.action) >= 2


def _unit(x, high: float) -> np.ndarray:
    """A layer on the network's input scale, computed independently of the encoder."""
    x = np.asarray(x, np.float64)
    return np.log1p(x) / np.log1p(high) if high > 1 else x


def test_a_shard_holds_the_agent_observation_layers_only(collected):
    labels = EpisodeLabels.from_file(collected[1][0])
    assert set(labels.keys) == {*BASE_LAYERS, *LAYERS}
    assert labels.layers.dtype == np.uint8 and labels.layers.shape[1:] == (len(labels.keys), 3600)


def test_layers_are_quantised_to_half_a_level_of_the_networks_scale():
    rng = np.random.default_rng(0)
    highs = np.array([1.0, 30.0, 5e4])
    layers = np.stack([rng.random(500), 30 * rng.random(500), 5e4 * rng.random(500) ** 4])
    decoded = np.stack(
        [decoding_table(highs)[c][q] for c, q in enumerate(encode_layers(layers, highs))]
    )
    for c, high in enumerate(highs):
        assert np.abs(_unit(decoded[c], high) - _unit(layers[c], high)).max() <= 0.5 / LEVELS + 1e-6
    assert (encode_layers(np.zeros((3, 4)), highs) == 0).all()
    assert (encode_layers(np.array([[1.0], [30.0], [5e4]]), highs) == LEVELS).all()


def test_the_learner_acts_where_the_teacher_does_not(world, tmp_path):
    """Iteration 1 with a teacher share of 0: every step is the learner's (a fresh model,
    acting from the agent's view), and the teacher still labels every state."""
    from nbv_gym.rl.imitation import new_model
    from nbv_gym.rl.labelfile import labels_space

    config = tiny_config(world, teacher_share_decay=0.0, episodes_per_iteration=1)
    first = collect(config, tmp_path / "iter-0", 0, None, progress=False)
    labels = EpisodeLabels.from_file(first[0])
    model = new_model(config, labels_space(labels), labels.n_goals)
    model.save(tmp_path / "learner.zip")
    second = EpisodeLabels.from_file(
        collect(config, tmp_path / "iter-1", 1, tmp_path / "learner.zip", progress=False)[0]
    )
    assert labels.teacher_acted.all() and not second.teacher_acted.any()
    assert (np.diff(second.offsets) > 0).all()  # labelled all the same
    assert second.seed == episode_seed(config.seed, 1, 0) != labels.seed


def test_a_collection_killed_midway_goes_on_to_the_uninterrupted_shards(world, tmp_path):
    config = tiny_config(world)
    reference = collect(config, tmp_path / "reference", 0, None, progress=False)
    folder = tmp_path / "killed"
    script = (
        "import json, sys; from pathlib import Path; "
        "from nbv_gym.core.config import from_dict; from nbv_gym.rl.config import TrainConfig; "
        "from nbv_gym.rl.labels import collect; "
        "collect(from_dict(TrainConfig, json.loads(sys.argv[1])), Path(sys.argv[2]), 0, None, "
        "progress=False)"
    )
    from nbv_gym.core.config import to_dict

    process = subprocess.Popen([sys.executable, "-c", script, json.dumps(to_dict(config)),
                                str(folder)], env={**os.environ})  # fmt: skip
    try:
        deadline = time.monotonic() + 300
        while not list(folder.glob("episode-*.npz")) and time.monotonic() < deadline:
            assert process.poll() is None, "the collection ended before it was killed"
            time.sleep(0.05)
        os.kill(process.pid, signal.SIGKILL)
    finally:
        process.wait()
    done = sorted(p.name for p in folder.glob("episode-*.npz"))
    assert 1 <= len(done) < 3, done
    resumed = collect(config, folder, 0, None, progress=False)
    assert not list(folder.glob("*.tmp*"))
    for ours, theirs in zip(resumed, reference, strict=True):
        a, b = EpisodeLabels.from_file(ours), EpisodeLabels.from_file(theirs)
        for name in ("layers", "state", "mask", "offsets", "candidates", "values", "action",
                     "teacher_acted", "reward", "highs"):  # fmt: skip
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
        assert (a.keys, a.world, a.seed) == (b.keys, b.world, b.seed)


def test_an_iteration_with_a_learner_share_needs_a_learner(world, tmp_path):
    config = tiny_config(world)
    config = replace(config, imitation=replace(config.imitation, episodes_per_iteration=1))
    with pytest.raises(ValueError, match="needs a learner"):
        collect(config, tmp_path, 1, None, progress=False)


@pytest.mark.slow  # worker processes, then a LocalCluster started: about a minute on 2 cores
@pytest.mark.parametrize("where", [{"n_envs": 2}, {"n_envs": 2, "scheduler": "local"}],
                         ids=["processes", "dask"])  # fmt: skip
def test_workers_and_a_dask_cluster_collect_the_shards_of_one_process(collected, tmp_path, where):
    config, reference = collected
    paths = collect(replace(config, **where), tmp_path, 0, None, progress=False)
    for ours, theirs in zip(paths, reference, strict=True):
        a, b = EpisodeLabels.from_file(ours), EpisodeLabels.from_file(theirs)
        assert np.array_equal(a.layers, b.layers) and np.array_equal(a.values, b.values)
        assert np.array_equal(a.action, b.action) and a.seed == b.seed


def test_a_shard_of_another_episode_or_run_is_refused_naming_it(collected, tmp_path):
    config, paths = collected
    folder = tmp_path / "iter-0"
    folder.mkdir()
    (folder / paths[0].name).write_bytes(paths[1].read_bytes())  # episode 1's labels as 0's
    with pytest.raises(LabelFileError, match=r"holds iteration 0, episode 1 .* a shard of another"):
        collect(config, folder, 0, None, progress=False)
    other = replace(config, seed=config.seed + 1)  # the same files under another recipe seed
    with pytest.raises(LabelFileError, match="not this recipe's iteration 0, episode 0"):
        collect(other, paths[0].parent, 0, None, progress=False)
