"""Explore-v0 as RL code and users rely on it: API checks, determinism, rewards, termination."""

from __future__ import annotations

import hashlib
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

import nbv_gym  # noqa: F401  (registers the environment)
from nbv_gym.env import ExploreEnv
from nbv_gym.policies import POLICIES
from nbv_gym.simulator import InvalidActionError

WORLD = "pp1-cuboids"


@pytest.fixture(scope="module")
def env():
    environment = gymnasium.make("nbv_gym/Explore-v0", world=WORLD, noise=1, max_steps=6)
    yield environment
    environment.close()


def rollout(env, seed: int, n_steps: int = 4):
    """Observations, rewards and goals of a random-valid-goal rollout."""
    observation, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    observations, rewards, goals, infos = [observation], [], [], [info]
    for _ in range(n_steps):
        goal = int(env.action_space.sample(mask=info["action_mask"].astype(np.int8)))
        observation, reward, terminated, truncated, info = env.step(goal)
        observations.append(observation)
        rewards.append(reward)
        goals.append(goal)
        infos.append(info)
        if terminated or truncated:
            break
    return observations, rewards, goals, infos


def digest(observations, rewards, goals) -> str:
    h = hashlib.sha256()
    for observation in observations:
        for key in sorted(observation):
            h.update(observation[key].tobytes())
    h.update(np.asarray(rewards).tobytes() + np.asarray(goals).tobytes())
    return h.hexdigest()


def test_observations_are_fixed_size_float32_in_the_space(env):
    observations, _, _, infos = rollout(env, seed=1, n_steps=2)
    for observation in observations:
        assert env.observation_space.contains(observation)
        assert observation["known"].shape == (3600,) and observation["state"].dtype == np.float32
    mask = infos[-1]["action_mask"]
    assert mask.shape == (3600,) and mask.any()
    np.testing.assert_array_equal(mask, env.unwrapped.action_masks())
    np.testing.assert_array_equal(observations[-1]["valid"] > 0, mask)


def test_same_seed_same_episode_and_different_seed_differs(env):
    first = digest(*rollout(env, seed=7)[:3])
    assert digest(*rollout(env, seed=7)[:3]) == first
    assert digest(*rollout(env, seed=8)[:3]) != first


def test_same_seed_same_episode_in_another_process(env):
    code = (
        "import gymnasium, nbv_gym, sys; sys.path.insert(0, 'tests/env');"
        "from test_explore import rollout, digest;"
        f"env = gymnasium.make('nbv_gym/Explore-v0', world='{WORLD}', noise=1, max_steps=6);"
        "print(digest(*rollout(env, seed=7)[:3]))"
    )
    there = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert there == digest(*rollout(env, seed=7)[:3])


def test_summed_rewards_equal_the_gain_in_q(env):
    _, rewards, _, infos = rollout(env, seed=3, n_steps=5)
    assert sum(rewards) == pytest.approx(infos[-1]["q"] - infos[0]["q"], abs=1e-12)
    assert infos[-1]["q"] > infos[0]["q"]  # scanning more improves the map


def test_action_space_samples_valid_goals(env):
    env.reset(seed=2)
    mask = env.unwrapped.action_masks()
    assert all(mask[env.action_space.sample()] for _ in range(50))


def test_invalid_goal_raises_and_says_why(env):
    env.reset(seed=2)
    with pytest.raises(InvalidActionError, match=r"within 1.0 m of the window border"):
        env.step(0)
    robot_goal = 30 * 60 + 30  # the start (0, 0) lies in cell (30, 30)
    with pytest.raises(InvalidActionError, match="robot's own cell"):
        env.step(robot_goal)
    with pytest.raises(InvalidActionError, match=r"integer index in \[0, 3600\)"):
        env.step(3600)


def test_termination_fires_exactly_when_discovered_crosses_the_target():
    environment = ExploreEnv(world=WORLD, max_steps=40)
    _, _, _, infos = rollout(environment, seed=4, n_steps=40)
    discovered = [info["discovered"] for info in infos]
    assert discovered[-1] >= 0.70 and all(d < 0.70 for d in discovered[:-1])
    assert "discovered" in infos[-1]["end_reason"]


def test_truncation_at_max_steps():
    unreachable = {
        "simulator": {"world": WORLD, "episode": {"max_steps": 3, "discovered_target": 1.0}}
    }
    _, rewards, _, infos = rollout(ExploreEnv(config=unreachable), seed=5, n_steps=10)
    assert len(rewards) == 3 and "max_steps = 3" in infos[-1]["end_reason"]


def test_runs_in_gymnasium_async_vector_env():
    # fork is unsafe once Embree's thread pool runs in the parent: use forkserver (or spawn),
    # and let the workers import nbv_gym through the "module:id" form
    envs = gymnasium.vector.AsyncVectorEnv(
        [lambda: gymnasium.make("nbv_gym:nbv_gym/Explore-v0", world=WORLD, max_steps=3)] * 2,
        context="forkserver",
    )
    try:
        observations, _infos = envs.reset(seed=[0, 1])
        assert observations["known"].shape == (2, 3600)
        masks = np.stack(envs.call("action_masks"))
        actions = np.array([np.flatnonzero(m)[0] for m in masks])
        observations, rewards, *_ = envs.step(actions)
        assert rewards.shape == (2,) and np.all(np.isfinite(rewards))
    finally:
        envs.close()


def test_runs_in_stable_baselines3_subproc_vec_env():
    vec_env = pytest.importorskip("stable_baselines3.common.vec_env")
    envs = vec_env.SubprocVecEnv(
        [lambda: gymnasium.make("nbv_gym:nbv_gym/Explore-v0", world=WORLD, max_steps=3)] * 2
    )
    try:
        observations = envs.reset()
        masks = np.stack(envs.env_method("action_masks"))
        actions = np.array([np.flatnonzero(m)[-1] for m in masks])
        observations, rewards, _dones, _infos = envs.step(actions)
        assert observations["state"].shape == (2, 6) and rewards.shape == (2,)
    finally:
        envs.close()


def test_render_draws_a_picture(env):
    environment = ExploreEnv("rgb_array", world=WORLD, max_steps=3)
    environment.reset(seed=0)
    image = environment.render()
    assert image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50  # a picture, not a blank


def test_a_kept_frame_holds_no_memory_beyond_its_pixels():
    """``nbv-gym run`` keeps one frame per step for the animation (issue 15, defect 14: views
    of larger buffers kept 4× their size alive): a frame must own exactly its pixels."""
    environment = ExploreEnv("rgb_array", world=WORLD, max_steps=3)
    environment.reset(seed=0)
    image = environment.render()
    owner = image
    while isinstance(owner.base, np.ndarray):
        owner = owner.base
    assert owner.nbytes == image.nbytes == image.shape[0] * image.shape[1] * 3


def test_unknown_observation_layer_is_refused():
    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match="observation_layers"):
        ExploreEnv(world=WORLD, observation_layers=("gain_banana",))


def test_gain_layers_are_zero_outside_the_candidates():
    from nbv_gym.nbv import CANDIDATES_LAYER, GAIN_LAYERS

    environment = ExploreEnv(world=WORLD, max_steps=3, observation_layers=GAIN_LAYERS)
    observation, info = environment.reset(seed=0)
    candidates = observation[CANDIDATES_LAYER] > 0
    assert candidates.any() and not (candidates & ~info["action_mask"]).any()
    for name in GAIN_LAYERS:
        assert observation[name].shape == (3600,)
        assert np.all(observation[name][~candidates] == 0)
    # at the start most of the world is unobserved: every candidate sees new cells
    assert np.all(observation["gain_nobs"][candidates] > 0)
    assert environment.observation_space.contains(observation)


@pytest.mark.parametrize("name", list(POLICIES))
def test_every_policy_picks_only_valid_goals(name):
    from nbv_gym.episode import make_env
    from nbv_gym.policies import is_oracle, load_policy

    small = {"n_best": 2, "n_random": 2} if name.startswith("oracle-") else {}  # few trial scans
    policy = load_policy(name, **small)
    environment = make_env(ExploreEnv(world=WORLD, max_steps=4).config, policy)
    observation, info = environment.reset(seed=1)
    policy.reset(1)
    if is_oracle(policy):
        policy.attach(environment)
    for _ in range(4):
        goal = policy.act(observation, info)
        assert info["action_mask"][goal], f"{name} chose invalid goal {goal}"
        observation, _, terminated, truncated, info = environment.step(goal)
        if terminated or truncated:
            break
