"""Every environment id that ``import nbv_gym`` registers, checked the same way (as Minigrid's
``tests/test_envs.py`` does): Gymnasium's and stable-baselines3's environment checkers pass
without a warning, no id sets ``max_episode_steps`` (the environment's own limit is the one
truncation) and a user's ``max_episode_steps`` works as Gymnasium documents."""

from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.wrappers import TimeLimit

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import (
    BUDGET_SCANS,
    EXPLORE_MAX_STEPS,
    TASK_IDS,
)
from tests.helpers import few_steps

WORLD = "pp1-cuboids"
#: Every id of the package, read from Gymnasium's registry rather than from our own constants.
ALL_IDS = sorted(env_id for env_id in gymnasium.registry if env_id.startswith("nbv_gym/"))
#: A lidar without range noise: Gymnasium's checker samples an action before a seeded reset
#: and steps it after, which holds only when the start's valid goals do not depend on the seed.
NOISE_FREE = {"simulator": {"world": WORLD, "noise": 0, "lidar": {"range_noise": None}}}


def test_the_registry_holds_every_task_id():
    assert set(TASK_IDS.values()) <= set(ALL_IDS) and len(ALL_IDS) >= 2


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_the_envs_own_limit_is_the_only_truncation(env_id):
    env = gymnasium.make(env_id, world=WORLD)
    own = env.unwrapped.config.simulator.episode.max_steps
    assert env.spec.max_episode_steps is None and not _time_limited(env)
    expected = {
        TASK_IDS["explore"]: EXPLORE_MAX_STEPS,
        TASK_IDS["budget"]: BUDGET_SCANS,
        TASK_IDS["time"]: 61,  # 600 s / 10 s per scan, + 1: a cap that never binds
    }
    assert own == expected[env_id]
    env.close()


def _time_limited(env) -> bool:
    while isinstance(env, gymnasium.Wrapper):
        if isinstance(env, TimeLimit):
            return True
        env = env.env
    return False


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_a_users_max_episode_steps_truncates_as_gymnasium_documents(env_id):
    env = gymnasium.make(env_id, world=WORLD, max_episode_steps=2)
    assert env.spec.max_episode_steps == 2 and _time_limited(env)
    _, info = env.reset(seed=0)
    for step in range(2):
        goal = int(np.flatnonzero(info["action_mask"])[0])
        _, _, terminated, truncated, info = env.step(goal)
        assert truncated == (step == 1) and not terminated
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_an_id_refuses_another_task(env_id):
    other = next(task for task, id_ in TASK_IDS.items() if id_ != env_id)
    with pytest.raises(ConfigError, match=f"task: {env_id} is the .* task.*{TASK_IDS[other]}"):
        gymnasium.make(env_id, world=WORLD, task=other)
    assert gymnasium.make(env_id, world=WORLD, task=_task_of(env_id)).spec.id == env_id


def _task_of(env_id: str) -> str:
    return next(task for task, id_ in TASK_IDS.items() if id_ == env_id)


@pytest.mark.parametrize("config", [None, NOISE_FREE], ids=["defaults", "noise-free"])
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasium_env_checker_passes_without_warnings(env_id, config):
    from gymnasium.utils.env_checker import check_env

    kwargs = {"world": WORLD} if config is None else {"config": config}
    env = gymnasium.make(
        env_id, render_mode="rgb_array", disable_env_checker=True, **few_steps(env_id, 3), **kwargs
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_stable_baselines3_env_checker_passes_without_warnings(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gymnasium.make(env_id, world=WORLD, **few_steps(env_id, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env.unwrapped, warn=True)
    env.close()
