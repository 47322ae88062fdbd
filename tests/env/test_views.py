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
from tests.helpers import few_steps

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
        {"config": {"simulator": {"episode": {"discovered_target": 0.3}}}},  # at its first step
    ),
}


def info_keys(env_id: str, kwargs: dict) -> set[str]:
    """The keys of every info of a two-step episode (reset, steps, the final one)."""
    env = gymnasium.make(env_id, world=WORLD, noise=1, **few_steps(env_id, 2), **kwargs)
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


def team_info_keys() -> set[str]:
    """The keys of every robot's info of a short team episode."""
    from nbv_gym.team import TeamEnv

    env = TeamEnv(world=WORLD, n_robots=2, time_budget_s=30.0)
    _, infos = env.reset(seed=0)
    keys = set().union(*map(set, infos.values()))
    while env.agents:
        actions = {a: int(np.flatnonzero(infos[a]["action_mask"])[0]) for a in env.agents}
        infos = env.step(actions)[4]
        keys |= set().union(*map(set, infos.values()))
    return keys


@pytest.fixture(scope="module")
def produced() -> set[str]:
    singles = (info_keys(env_id, kwargs) for env_id, kwargs in SETTINGS.values())
    return set().union(*singles, team_info_keys())


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


# -- the view holds agent values only (third round of probes) ---------------------------------------


def _full_info() -> dict:
    return {
        "action_mask": np.array([0, 1, 1], np.int8),
        "estimated_pose": np.array([1.0, 2.0, 3.0]),
        "predicted_gain": {"gain_nobs": np.array([1.5, 2.5])},
        "steps": 3,
        "q": 0.123456789,
        "world": "secret-world",
        "true_pose": np.array([9.0, 9.0, 9.0]),
    }


def _reachable(root, depth: int = 4) -> list:
    """Every object reachable from ``root`` through attributes, slots, mappings and sequences
    (what a policy reaches without gc or frame inspection)."""
    seen, found, frontier = set(), [], [root]
    for _ in range(depth):
        following = []
        for item in frontier:
            if id(item) in seen or isinstance(item, (str, bytes, int, float, type)):
                found.append(item)
                continue
            seen.add(id(item))
            found.append(item)
            slots = [s for c in type(item).__mro__ for s in getattr(c, "__slots__", ())]
            following += [getattr(item, s) for s in slots if hasattr(item, s)]
            following += list(getattr(item, "__dict__", {}).values())
            if hasattr(item, "items"):
                try:
                    following += [v for pair in item.items() for v in pair]
                except (TypeError, PrivilegedInfoError):
                    pass
            if isinstance(item, (list, tuple, set, frozenset)):
                following += list(item)
        frontier = following
    return found


@pytest.mark.parametrize(
    "route",
    [
        lambda view: view,
        lambda view: __import__("copy").copy(view),
        lambda view: __import__("copy").deepcopy(view),
        lambda view: __import__("pickle").loads(__import__("pickle").dumps(view)),
    ],
    ids=["attributes", "copy", "deepcopy", "pickle"],
)
def test_no_privileged_value_is_reachable_from_the_view(route):
    info = _full_info()
    reached = _reachable(route(agent_view(info)))
    assert not any(item is info for item in reached)
    assert "secret-world" not in [x for x in reached if isinstance(x, str)]
    assert 0.123456789 not in [x for x in reached if isinstance(x, float)]
    assert not any(
        isinstance(x, np.ndarray) and np.array_equal(x, info["true_pose"]) for x in reached
    )


def test_arrays_of_the_view_cannot_rewrite_the_environments():
    info = _full_info()
    view = agent_view(info)
    for array in (view["action_mask"], view["estimated_pose"], view["predicted_gain"]["gain_nobs"]):
        assert not array.flags.writeable
        assert not np.shares_memory(array, info["action_mask"])
        try:
            array.flags.writeable = True  # allowed on a copy; harmless there
        except ValueError:
            pass
        else:
            array[...] = 7
    assert info["action_mask"].tolist() == [0, 1, 1]
    assert info["estimated_pose"].tolist() == [1.0, 2.0, 3.0]
    assert info["predicted_gain"]["gain_nobs"].tolist() == [1.5, 2.5]


FLIPPER = """
import numpy as np


class Flipper:
    '''Not an oracle at reset; declares privileged = True during the episode and reads q.'''

    observation_layers = ()
    privileged = False

    def reset(self, seed=None):
        type(self).privileged = False
        self.read = []

    def act(self, observation, info):
        type(self).privileged = True  # too late: the harness read the flag at the reset
        try:
            self.read.append(info["q"])
        except Exception as error:
            self.read.append(type(error).__name__)
        return int(np.flatnonzero(info["action_mask"])[0])


class Unflipper(Flipper):
    '''An oracle at reset that drops its flag during the episode: still an oracle, recorded so.'''

    def reset(self, seed=None):
        type(self).privileged = True
        self.read = []

    def act(self, observation, info):
        type(self).privileged = False
        self.read.append(info["q"])
        return int(np.flatnonzero(info["action_mask"])[0])
"""


@pytest.fixture
def flippers(tmp_path, monkeypatch):
    (tmp_path / "flippers.py").write_text(FLIPPER)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_a_flag_flipped_mid_episode_gets_and_records_what_the_reset_read(flippers):
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env, run_episode
    from nbv_gym.policies import load_policy
    from nbv_gym.simulator import EpisodeConfig, SimulatorConfig

    config = EnvConfig(SimulatorConfig(world=WORLD, noise=0, episode=EpisodeConfig(max_steps=3)))
    flipper = load_policy("flippers:Flipper")
    result = run_episode(make_env(config, flipper), flipper, seed=0)
    assert result.oracle is False and set(flipper.read) == {"PrivilegedInfoError"}
    unflipper = load_policy("flippers:Unflipper")
    result = run_episode(make_env(config, unflipper), unflipper, seed=0)
    assert result.oracle is True and all(isinstance(q, float) for q in unflipper.read)


def test_run_records_the_oracle_flag_the_episode_used(flippers):
    import json

    from tests.helpers import run_cli

    done = run_cli("run", "--world", WORLD, "--policy", "flippers:Unflipper", "--noise", "0",
                   "--max-steps", "2", "--no-animation", "--out", "r", cwd=flippers)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads((flippers / "r" / "summary.json").read_text())["oracle"] is True
    done = run_cli("run", "--world", WORLD, "--policy", "flippers:Flipper", "--noise", "0",
                   "--max-steps", "2", "--no-animation", "--out", "f", cwd=flippers)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert json.loads((flippers / "f" / "summary.json").read_text())["oracle"] is False
