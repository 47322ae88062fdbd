"""The agent view of info: every key the environment gives is classified, and a privileged read
raises an error naming the key and the rule."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.errors import NbvGymError
from nbv_gym.env.layers import OPTIONAL_LAYERS
from nbv_gym.env.views import AGENT_KEYS, PRIVILEGED_KEYS, PrivilegedInfoError, agent_view

WORLD = "pp1-cuboids"
# Every way the env's info can differ: the ids, with and without the optional layers,
# snapping, and an episode that terminates (a tiny discovered target) or is truncated.
SETTINGS = {
    "explore": ("nbv_gym/Explore-v0", {}),
    "budget-snap": ("nbv_gym/ExploreBudget-v0", {"invalid_action": "snap"}),
    "time": ("nbv_gym/ExploreTime-v0", {}),
    "explore-layers": ("nbv_gym/Explore-v0", {"observation_layers": tuple(OPTIONAL_LAYERS)}),
    "terminates": (
        "nbv_gym/Explore-v0",
        {"config": {"simulator": {"episode": {"discovered_target": 0.02}}}},
    ),
}


def info_keys(env_id: str, kwargs: dict) -> set[str]:
    """The keys of every info of a two-step episode (reset, steps, the final one)."""
    env = gymnasium.make(env_id, world=WORLD, noise=1, max_steps=2, **kwargs)
    try:
        _, info = env.reset(seed=0)
        keys, done = set(info), False
        while not done:
            goal = int(np.flatnonzero(info["action_mask"])[0])
            if kwargs.get("invalid_action") == "snap":
                goal = int(np.flatnonzero(info["action_mask"] == 0)[0])  # snapped to a valid one
            _observation, _reward, terminated, truncated, info = env.step(goal)
            keys |= set(info)
            done = terminated or truncated
    finally:
        env.close()
    return keys


@pytest.fixture(scope="module")
def produced() -> set[str]:
    return set().union(*(info_keys(env_id, kwargs) for env_id, kwargs in SETTINGS.values()))


def test_every_info_key_is_classified_once(produced):
    assert not set(AGENT_KEYS) & set(PRIVILEGED_KEYS)
    unclassified = produced - set(AGENT_KEYS) - set(PRIVILEGED_KEYS)
    assert not unclassified, f"classify {sorted(unclassified)} in nbv_gym/env/views.py"
    stale = (set(AGENT_KEYS) | set(PRIVILEGED_KEYS)) - produced
    assert not stale, f"{sorted(stale)} are classified but the environment gives no such key"
    assert all(AGENT_KEYS.values()) and all(PRIVILEGED_KEYS.values())  # each says why


def test_ground_truth_pose_and_world_are_privileged():
    assert {"q", "q_paper", "q_observed", "cov", "l1", "delta_q"} <= set(PRIVILEGED_KEYS)
    assert {"world", "true_pose"} <= set(PRIVILEGED_KEYS)
    assert {"action_mask", "estimated_pose", "discovered", "path_length_m"} <= set(AGENT_KEYS)


INFO = {
    "action_mask": np.array([0, 1, 1], np.int8),
    "q": 0.25,
    "world": "pp1-cuboids",
    "true_pose": np.zeros(4),
    "steps": 3,
    "predicted_gain": {"gain_nobs": 1.5},
    "something_new": 1,
}


@pytest.mark.parametrize("key", ["q", "world", "true_pose"])
def test_reading_a_privileged_key_names_it_and_the_rule(key):
    view = agent_view(INFO, "my_module:Peek")
    message = (
        rf"Policy my_module:Peek read info\['{key}'\], which is privileged \(.+\): policies see "
        r"the agent view; declare privileged = True to be an oracle\."
    )
    with pytest.raises(PrivilegedInfoError, match=message):
        view[key]
    with pytest.raises(PrivilegedInfoError, match=message):
        view.get(key, 0.0)  # no silent default either
    assert issubclass(PrivilegedInfoError, NbvGymError)


def test_the_view_shows_agent_keys_only_and_read_only():
    view = agent_view(INFO)
    assert sorted(view) == ["action_mask", "predicted_gain", "steps"] == sorted(view.keys())
    assert len(view) == 3 and dict(view).keys() == {"action_mask", "predicted_gain", "steps"}
    assert "q" not in view and "action_mask" in view and "goal" not in view
    assert view["steps"] == 3 and view.get("goal", -1) == -1  # an agent key info lacks
    with pytest.raises(KeyError):
        view["no_such_key"]
    with pytest.raises(PrivilegedInfoError, match=r"info\['something_new'\] is privileged \(it "):
        view["something_new"]  # a key nobody classified stays hidden
    with pytest.raises(ValueError, match="read-only"):
        view["action_mask"][0] = 1
    with pytest.raises(TypeError):
        view["predicted_gain"]["gain_nobs"] = 0.0
    with pytest.raises(TypeError):
        view["steps"] = 4  # type: ignore[index]
    assert INFO["action_mask"][0] == 0 and INFO["predicted_gain"]["gain_nobs"] == 1.5


def test_the_user_docs_list_every_key():
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "agent-view.md").read_text()
    missing = [key for key in (*AGENT_KEYS, *PRIVILEGED_KEYS) if f"`{key}`" not in text]
    assert not missing, f"docs/agent-view.md does not list {missing}"
