"""The registered ids as Gymnasium and SB3 expect them: int8 masks that ``sample(mask=...)``
takes, masks through wrappers, pickling (the checkers and ``max_episode_steps`` of every id:
``test_registered_ids.py``)."""

from __future__ import annotations

import pickle

import gymnasium
import numpy as np
import pytest

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.protocol import BUDGET_ID, BUDGET_SCANS, EXPLORE_ID
from nbv_gym.env import ExploreEnv
from nbv_gym.policies import load_policy

WORLD = "pp1-cuboids"


@pytest.mark.parametrize("env_id", [EXPLORE_ID, BUDGET_ID])
def test_sample_with_the_info_mask_returns_a_valid_goal(env_id):
    env = gymnasium.make(env_id, world=WORLD)
    _, info = env.reset(seed=0)
    assert info["action_mask"].dtype == np.int8 and info["action_mask"].shape == (3600,)
    env.action_space.seed(0)
    goals = [int(env.action_space.sample(mask=info["action_mask"])) for _ in range(20)]
    assert all(info["action_mask"][g] == 1 for g in goals)


def test_action_masks_reach_through_wrappers():
    env = gymnasium.make(EXPLORE_ID, world=WORLD)
    _, info = env.reset(seed=0)
    assert isinstance(env, gymnasium.Wrapper)
    masks = env.get_wrapper_attr("action_masks")()
    assert masks.dtype == np.int8
    np.testing.assert_array_equal(masks, info["action_mask"])


def test_budget_runs_the_whole_budget_and_its_return_is_the_gain_in_q():
    """random-frontier passes 70 % discovered within 11 scans on the pp worlds (the explore task
    would terminate there): the budget task runs every scan of the budget all the same."""
    env = gymnasium.make(BUDGET_ID, world=WORLD)
    policy = load_policy("random-frontier")
    observation, info = env.reset(seed=1)
    policy.reset(1)
    first_q, rewards, ends = info["q"], [], []
    while True:
        observation, reward, terminated, truncated, info = env.step(policy.act(observation, info))
        rewards.append(reward)
        ends.append((terminated, truncated))
        if terminated or truncated:
            break
    assert env.unwrapped.config.simulator.episode.discovered_target is None
    assert len(rewards) == BUDGET_SCANS
    assert info["discovered"] >= 0.70  # the explore task would have ended before the budget
    assert ends[-1] == (False, True) and not any(any(end) for end in ends[:-1])
    assert sum(rewards) == pytest.approx(info["q"] - first_q, abs=1e-12)


def test_unknown_task_is_refused():
    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match="task: expected one of explore, budget"):
        ExploreEnv(task="race", world=WORLD)


def test_the_env_pickles_and_goes_on_identically():
    env = gymnasium.make(BUDGET_ID, world=WORLD).unwrapped
    _, info = env.reset(seed=4)
    copy = pickle.loads(pickle.dumps(env))
    goal = int(np.flatnonzero(info["action_mask"])[7])
    original, copied = env.step(goal), copy.step(goal)
    assert original[1] == copied[1] and original[4]["q"] == copied[4]["q"]
    for key in original[0]:
        np.testing.assert_array_equal(original[0][key], copied[0][key])
