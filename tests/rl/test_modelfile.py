"""Model zips are checked from their data JSON before SB3 unpickles anything in them."""

from __future__ import annotations

import base64
import json
import pickle
import zipfile

import gymnasium
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from gymnasium import spaces

from nbv_gym.core.errors import ConfigError
from nbv_gym.env.observation import BASE_LAYERS, STATE_SIZE
from nbv_gym.policies import PolicyError, load_policy
from nbv_gym.rl import modelfile
from nbv_gym.rl.config import TrainConfig
from nbv_gym.rl.modelfile import describe_model
from nbv_gym.rl.train import check_resume


class _ExploreSpacesEnv(gymnasium.Env):
    """Explore-v0's spaces (the base layers, 'state' and one optional layer), nothing else."""

    observation_space = spaces.Dict(
        {
            **{k: spaces.Box(0, 1, (3600,), np.float32) for k in (*BASE_LAYERS, "gain_sigma")},
            "state": spaces.Box(-2, 2, (STATE_SIZE,), np.float32),
        }
    )
    action_space = spaces.Discrete(3600)


def _save(algorithm: str, path):
    from sb3_contrib import MaskablePPO
    from stable_baselines3 import A2C, PPO

    cls = {"MaskablePPO": MaskablePPO, "PPO": PPO, "A2C": A2C}[algorithm]
    kwargs = {"n_steps": 8, "policy_kwargs": {"net_arch": [8]}}
    kwargs |= {"batch_size": 8} if algorithm != "A2C" else {}
    cls("MultiInputPolicy", _ExploreSpacesEnv(), **kwargs).save(path)
    return path


@pytest.fixture(scope="module")
def masked_model(tmp_path_factory):
    return _save("MaskablePPO", tmp_path_factory.mktemp("models") / "masked.zip")


def _rewrite_data(source, target, change) -> None:
    """Copy the zip ``source`` to ``target`` with ``change(data)`` applied to its data JSON."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            content = old.read(item)
            if item.filename == "data":
                data = json.loads(content)
                change(data)
                content = json.dumps(data).encode()
            new.writestr(item, content)


@pytest.mark.parametrize("algorithm", ["MaskablePPO", "PPO", "A2C"])
def test_the_algorithm_and_spaces_are_read_from_the_json(tmp_path, algorithm):
    description = describe_model(_save(algorithm, tmp_path / "model.zip"))
    assert description.algorithm == algorithm
    assert description.action_space == spaces.Discrete(3600)
    saved = description.observation_space.spaces
    assert sorted(saved) == sorted([*BASE_LAYERS, "gain_sigma", "state"])
    assert {k: s.shape for k, s in saved.items()} == {
        k: (STATE_SIZE,) if k == "state" else (3600,) for k in saved
    }


def test_a_checked_model_loads_as_a_policy_with_its_layers(masked_model):
    policy = load_policy(f"sb3:{masked_model}")
    assert policy.masked and policy.observation_layers == ("gain_sigma",)


def test_a_policy_class_from_elsewhere_is_refused_before_its_pickle_runs(tmp_path, masked_model):
    marker = tmp_path / "the pickle ran"

    class Payload:
        def __reduce__(self):
            return open, (str(marker), "w")

    def poison(data):
        data["policy_class"]["__module__"] = "someone.elses.module"
        data["policy_class"][":serialized:"] = base64.b64encode(pickle.dumps(Payload())).decode()

    poisoned = tmp_path / "poisoned.zip"
    _rewrite_data(masked_model, poisoned, poison)
    with pytest.raises(PolicyError, match=r"policy class comes from 'someone\.elses\.module'"):
        load_policy(f"sb3:{poisoned}")
    assert not marker.exists()

    from stable_baselines3.common.save_util import load_from_zip_file

    load_from_zip_file(poisoned)
    assert marker.exists()  # SB3 alone runs it


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d["action_space"].update(n="2"), r"action space Discrete\(2\)"),
        (lambda d: d["observation_space"].update({":type:": "<class 'x.Box'>"}), "observes"),
        (lambda d: d.pop("observation_space"), "has no saved observation_space"),
        (lambda d: d.pop("policy_class"), "has no saved policy_class"),
    ],
    ids=["action-space", "observation-type", "no-observation-space", "no-policy-class"],
)
def test_wrong_saved_spaces_are_refused_naming_the_file(tmp_path, masked_model, change, message):
    path = tmp_path / "changed.zip"
    _rewrite_data(masked_model, path, change)
    with pytest.raises(PolicyError, match=rf"changed\.zip.*{message}"):
        load_policy(f"sb3:{path}")


def test_zips_that_are_not_models_are_refused(tmp_path, monkeypatch, masked_model):
    cases = {"empty.zip": {}, "text.zip": {"data": b"not json"}, "list.zip": {"data": b"[1]"}}
    for name, members in cases.items():
        with zipfile.ZipFile(tmp_path / name, "w") as archive:
            for member, content in members.items():
                archive.writestr(member, content)
        with pytest.raises(PolicyError, match=rf"{name}' is not a stable-baselines3 model zip"):
            load_policy(f"sb3:{tmp_path / name}")
    monkeypatch.setattr(modelfile, "MAX_DATA_BYTES", 100)
    with pytest.raises(PolicyError, match=r"its data member has \d+ bytes"):
        describe_model(masked_model)


def test_resuming_from_another_algorithm_is_refused_before_loading(tmp_path):
    path = _save("PPO", tmp_path / "ppo.zip")
    with pytest.raises(ConfigError, match=r"Cannot resume MaskablePPO from .*ppo\.zip': PPO saved"):
        check_resume(TrainConfig(algorithm="MaskablePPO"), path)
