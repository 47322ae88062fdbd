"""The ``invalid_action`` option: "raise" refuses an invalid goal, "snap" runs the nearest valid
one and says so in ``info``; the nearest-valid-goal rule on hand-made masks."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import TASK_IDS
from nbv_gym.env.actions import nearest_valid_goal, resolve_goal
from nbv_gym.simulator import InvalidActionError
from tests.helpers import few_steps

WORLD = "pp1-cuboids"
BORDER_GOAL = 0  # the corner cell: within 1 m of the window border, never valid


@pytest.mark.parametrize(
    "goal, valid, expected",
    [(5, [5, 100], 5), (0, [61, 3599], 61), (3599, [0, 3540], 3540), (65, [5, 125], 5)],
    ids=["valid", "diagonal-neighbour", "same-column", "tie-to-lower-index"],
)
def test_nearest_valid_goal(goal, valid, expected):
    mask = np.zeros(3600, np.int8)
    mask[valid] = 1
    assert nearest_valid_goal(goal, mask) == expected


def test_resolve_goal_snaps_only_invalid_in_range_goals():
    mask = np.zeros(3600, bool)
    mask[[61, 62]] = True
    assert resolve_goal(0, mask, "snap") == (61, True)
    assert resolve_goal(62, mask, "snap") == (62, False)
    assert resolve_goal(0, mask, "raise") == (0, False)
    assert resolve_goal(3600, mask, "snap") == (3600, False)  # not a goal: left to raise


@pytest.mark.parametrize("env_id", list(TASK_IDS.values()))
def test_snap_runs_the_nearest_valid_goal_and_reports_it(env_id):
    env = gymnasium.make(env_id, world=WORLD, invalid_action="snap", **few_steps(env_id, 4))
    _, info = env.reset(seed=0)
    assert info["goal"] == -1 and info["snapped"] is False
    rng = np.random.default_rng(0)
    for _ in range(4):
        mask = info["action_mask"]
        invalid = int(rng.choice(np.flatnonzero(mask == 0)))
        expected = nearest_valid_goal(invalid, mask)
        _observation, _reward, terminated, truncated, info = env.step(invalid)
        assert mask[info["goal"]] == 1 and info["goal"] == expected and info["snapped"] is True
        if terminated or truncated:
            break
    env.close()


def test_snap_leaves_a_valid_goal_alone():
    env = gymnasium.make("nbv_gym/Explore-v0", world=WORLD, max_steps=2, invalid_action="snap")
    _, info = env.reset(seed=0)
    goal = int(np.flatnonzero(info["action_mask"])[0])
    _, _, _, _, info = env.step(goal)
    assert (info["goal"], info["snapped"]) == (goal, False)


def test_snapped_step_equals_the_step_of_the_goal_it_ran():
    snapping = gymnasium.make("nbv_gym/Explore-v0", world=WORLD, invalid_action="snap").unwrapped
    plain = gymnasium.make("nbv_gym/Explore-v0", world=WORLD).unwrapped
    snapping.reset(seed=3), plain.reset(seed=3)
    snapped = snapping.step(BORDER_GOAL)
    direct = plain.step(snapped[4]["goal"])
    assert snapped[1] == direct[1]
    for key in direct[0]:
        np.testing.assert_array_equal(snapped[0][key], direct[0][key])


@pytest.mark.parametrize("kwargs", [{}, {"invalid_action": "raise"}], ids=["default", "raise"])
def test_raise_is_the_default_and_unchanged(kwargs):
    env = gymnasium.make("nbv_gym/Explore-v0", world=WORLD, **kwargs)
    _, info = env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"within 1.0 m of the window border"):
        env.step(BORDER_GOAL)
    goal = int(np.flatnonzero(info["action_mask"])[0])
    assert env.step(goal)[4]["snapped"] is False


def test_an_index_outside_the_action_space_raises_even_when_snapping():
    env = gymnasium.make("nbv_gym/Explore-v0", world=WORLD, invalid_action="snap")
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=r"integer index in \[0, 3600\)"):
        env.step(3600)


def test_unknown_invalid_action_is_refused_with_the_choices():
    with pytest.raises(ConfigError, match="invalid_action: expected one of raise, snap"):
        gymnasium.make("nbv_gym/Explore-v0", world=WORLD, invalid_action="ignore")
