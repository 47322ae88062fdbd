"""The policy interface, the registry and the three frontier baselines."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import UnknownNameError
from nbv_gym.policies import POLICIES, Policy, PolicyError, load_policy
from nbv_gym.policies.frontier import ClosestFrontier, RandomFree, RandomFrontier


def crafted(frontier_goals: list[int], valid_goals: list[int], robot_xy=(0.0, 0.0)):
    """An observation and info with the given frontier and valid goals on the 60 × 60 grid."""
    centres = -29.5 + np.indices((60, 60)).reshape(2, -1).T.astype(float)
    distance = np.hypot(*(centres - robot_xy).T) / np.hypot(60, 60)
    frontier = np.zeros(3600, np.float32)
    frontier[frontier_goals] = 1
    mask = np.zeros(3600, bool)
    mask[valid_goals] = True
    observation = {"frontier": frontier.reshape(60, 60), "distance": distance.reshape(60, 60)}
    return observation, {"action_mask": mask}


def goal(x: float, y: float) -> int:
    return int((x + 30) // 1 * 60 + (y + 30) // 1)


def test_closest_frontier_picks_the_nearest_frontier_goal():
    near, far, nearer_but_invalid = goal(3.5, -4.5), goal(10.5, 0.5), goal(1.5, 1.5)
    observation, info = crafted([far, near, nearer_but_invalid], [far, near, goal(0.5, 2.5)])
    policy = ClosestFrontier()
    policy.reset(0)
    assert policy.act(observation, info) == near  # √(3.5² + 4.5²) = 5.7 m < 10.5 m


def test_frontier_policies_fall_back_to_random_free_without_frontiers():
    valid = [goal(5.5, 5.5), goal(-7.5, 2.5)]
    observation, info = crafted([], valid)
    for policy in (ClosestFrontier(), RandomFrontier()):
        policy.reset(3)
        assert {policy.act(observation, info) for _ in range(20)} <= set(valid)


def test_random_frontier_is_uniform_over_frontier_goals_and_seeded():
    frontier = [goal(3.5, 3.5), goal(-3.5, 3.5), goal(0.5, -9.5)]
    observation, info = crafted(frontier, frontier + [goal(12.5, 12.5)])
    policy = RandomFrontier()
    policy.reset(11)
    picks = [policy.act(observation, info) for _ in range(3000)]
    counts = np.array([picks.count(g) for g in frontier])
    assert counts.sum() == 3000 and np.all(np.abs(counts - 1000) < 4 * np.sqrt(1000 * 2 / 3))
    policy.reset(11)
    assert [policy.act(observation, info) for _ in range(3000)] == picks


def test_random_free_picks_only_valid_goals():
    valid = list(range(100, 3600, 37))
    observation, info = crafted([], valid)
    policy = RandomFree()
    policy.reset(0)
    assert {policy.act(observation, info) for _ in range(500)} <= set(valid)


@pytest.mark.parametrize("name", ["random-frontier", "closest-frontier", "random-free"])
def test_registered_baselines_satisfy_the_protocol(name):
    policy = load_policy(name)
    assert isinstance(policy, Policy)
    assert name in POLICIES


def test_unknown_policy_lists_the_valid_ones():
    with pytest.raises(UnknownNameError, match=r"Did you mean 'closest-frontier'.*random-free"):
        load_policy("closest-fronteer")


def test_user_policy_errors_say_what_is_wrong(tmp_path, monkeypatch):
    (tmp_path / "my_policies.py").write_text(
        "class NoAct:\n    def reset(self, seed=None):\n        pass\n"
        "class Good:\n    observation_layers = ()\n    def reset(self, seed=None):\n        pass\n"
        "    def act(self, observation, info):\n        return 7\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    assert load_policy("my_policies:Good").act({}, {}) == 7
    with pytest.raises(PolicyError, match=r"lacks act\(\)"):
        load_policy("my_policies:NoAct")
    with pytest.raises(PolicyError, match="has no attribute 'Missing'"):
        load_policy("my_policies:Missing")
    with pytest.raises(PolicyError, match="cannot import module 'not_a_module_xyz'"):
        load_policy("not_a_module_xyz:Policy")


def test_an_nbv_name_may_fix_its_visibility_model():
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env

    policy = load_policy("nbv-sigma@fov")
    assert policy.statistic == "sigma" and policy.visibility == "fov"
    assert load_policy("nbv-sigma").visibility is None
    with pytest.raises(PolicyError, match="visibility"):
        load_policy("nbv-sigma@sky")
    env = make_env(EnvConfig(), policy)
    assert env.config.nbv.visibility == "fov" and "gain_sigma" in env.config.observation_layers


def test_a_shipped_model_name_is_its_sb3_file(monkeypatch):
    pytest.importorskip("sb3_contrib")  # the rl extra
    from nbv_gym.policies import MODELS, model_path

    assert model_path("ppo-budget").parts[-4:] == (
        "nbv_gym",
        "policies",
        "models",
        "ppo-budget.zip",
    )
    monkeypatch.setitem(MODELS, "missing-model", "missing-model.zip")
    with pytest.raises(
        PolicyError, match=r"No SB3 model at .*nbv_gym/policies/models/missing-model\.zip"
    ):
        load_policy("missing-model")


def test_an_old_baselines_path_names_the_new_one():
    with pytest.raises(PolicyError, match=r"name it nbv_gym\.policies\.frontier:ClosestFrontier"):
        load_policy("baselines.frontier:ClosestFrontier")
