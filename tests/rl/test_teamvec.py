"""Parameter sharing on the team task: the VecEnv adapter's shapes and spaces, the busy robots'
masks, the shared reward, a tiny team training end to end, and an actor that reads only its
own robot's observation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from nbv_gym.core.errors import ConfigError
from nbv_gym.env.task import TaskConfig
from nbv_gym.rl.config import LearningConfig, TrainConfig
from nbv_gym.rl.teamagent import SharedTeamAgent
from nbv_gym.rl.teamvec import TEAMMATE_GOALS, TeamVecEnv, make_team_envs
from nbv_gym.rl.train import FINAL_MODEL, train
from nbv_gym.team import TeamEnv, run_team_episode

BUDGET_S = 60.0
SCALE = 100.0


@pytest.fixture(scope="module")
def vec(world) -> TeamVecEnv:
    """Two team envs of 2 robots on the tiny world: 4 slots."""
    return TeamVecEnv(make_team_envs([world], 2, 2, time_budget_s=BUDGET_S), SCALE)


def masks(vec: TeamVecEnv) -> np.ndarray:
    return np.stack(vec.env_method("action_masks"))


def lowest_valid(vec: TeamVecEnv, busy_action: int | None = None) -> np.ndarray:
    """Each slot's lowest valid action; ``busy_action`` for the busy slots instead."""
    found = masks(vec)
    actions = found.argmax(axis=1)
    if busy_action is not None:
        busy = found[:, : vec.envs[0].carry_on].sum(axis=1) == 0
        actions[busy] = busy_action
    return actions


def play(vec: TeamVecEnv, seed: int, busy_action: int | None = None, events: int = 200):
    """Events of both team envs until env 0's first episode ended: each event's (observations,
    masks before it, rewards, dones, infos)."""
    vec.seed(seed)
    observations = vec.reset()
    history = []
    for _ in range(events):
        found = masks(vec)
        observations, rewards, dones, infos = vec.step(lowest_valid(vec, busy_action))
        history.append((observations, found, rewards, dones, infos))
        if dones[0]:
            break
    return history


def test_observations_rewards_dones_and_infos_have_the_vecenv_shapes(vec):
    n = vec.num_envs
    assert n == 4
    observations = vec.reset()
    for observation, _, rewards, dones, infos in play(vec, 0):
        assert set(observation) == set(vec.observation_space.spaces)
        for key, space in vec.observation_space.spaces.items():
            assert observation[key].shape == (n, *space.shape)
            assert observation[key].dtype == space.dtype
        for slot in range(n):
            assert vec.observation_space.contains({k: v[slot] for k, v in observation.items()})
        assert rewards.shape == (n,) and rewards.dtype == np.float32
        assert dones.shape == (n,) and dones.dtype == bool
        assert len(infos) == n
    assert observations[TEAMMATE_GOALS].shape == (n, vec.envs[0].sim.n_goals)
    for slot in range(2):  # env 0's episode ended: every slot done, with its terminal view
        assert dones[slot]
        assert vec.observation_space.contains(infos[slot]["terminal_observation"])
    assert {"r", "l", "t"} <= set(infos[0]["episode"]) and "episode" not in infos[1]


def test_exactly_one_robot_per_team_decides_and_busy_robots_may_only_carry_on(vec):
    carry_on = vec.envs[0].carry_on
    for _, found, *_ in play(vec, 1):
        assert found.shape == (vec.num_envs, carry_on + 1)
        assert found.any(axis=1).all()  # MaskablePPO needs one valid action per slot
        for team in found.reshape(2, 2, -1):
            deciding = team[:, :carry_on].any(axis=1)
            assert deciding.sum() == 1
            assert not team[deciding, carry_on].any()
            busy = team[~deciding]
            assert busy[:, carry_on].all() and not busy[:, :carry_on].any()


def test_a_busy_robots_action_is_ignored(vec):
    carry_on = play(vec, 2, busy_action=vec.envs[0].carry_on)
    anything = play(vec, 2, busy_action=0)
    assert len(carry_on) == len(anything)
    for a, b in zip(carry_on, anything, strict=True):
        np.testing.assert_array_equal(a[2], b[2])
        np.testing.assert_array_equal(a[0]["robot"], b[0]["robot"])


def test_every_robot_of_a_team_gets_the_teams_reward(vec):
    history = play(vec, 3)
    rewards = np.array([h[2] for h in history])  # (events, slots)
    np.testing.assert_array_equal(rewards[:, 0], rewards[:, 1])
    assert rewards[:, 0].sum() == pytest.approx(history[-1][4][0]["episode"]["r"], abs=1e-5)
    assert rewards[:, 0].sum() > 0


@pytest.mark.slow  # ~10 s alone; a minute or two on a loaded machine
def test_a_tiny_team_training_runs_and_its_agent_acts_on_its_own_view(world, tmp_path):
    config = TrainConfig(
        robots=2, n_envs=1, total_timesteps=64, train_worlds=(world,), eval_worlds=(world,),
        task=TaskConfig(name="time", time_budget_s=BUDGET_S), eval_every_steps=0,
        checkpoint_every_steps=0,
        learning=LearningConfig(n_steps=16, batch_size=16, n_epochs=1),
    )  # fmt: skip
    train(config, tmp_path, progress_bar=False)
    agent = SharedTeamAgent(tmp_path / FINAL_MODEL)
    env = TeamEnv(world=world, n_robots=2, time_budget_s=BUDGET_S)
    result = run_team_episode(env, agent, seed=0)
    assert result.figures["steps"] >= 1
    observations, infos = env.reset(seed=1)
    deciding = env.possible_agents[env.sim.deciding]
    other = next(a for a in env.possible_agents if a != deciding)
    chosen = agent.act(observations, infos)[deciding]
    blank = {k: np.zeros_like(v) for k, v in observations[other].items()}
    garbage = {**infos[other], "teammate_goals": np.array([0]), "goal": 0}
    assert agent.act({**observations, other: blank}, {**infos, other: garbage})[deciding] == chosen
    assert agent.act({deciding: observations[deciding]}, {deciding: infos[deciding]}) == {
        deciding: chosen
    }


@pytest.mark.parametrize(
    ("change", "key"),
    [({"task": TaskConfig(name="budget")}, "task"), ({"algorithm": "PPO"}, "algorithm"),
     ({"train_worlds": ("random:wide",)}, "train_worlds"),
     ({"eval_every_steps": 100}, "eval_every_steps")],
)  # fmt: skip
def test_what_team_training_does_not_run_is_refused_naming_the_key(change, key):
    base = TrainConfig(
        task=TaskConfig(name="time"), eval_every_steps=0, train_worlds=("random:wide/0",)
    )
    assert replace(base, robots=2).robots == 2
    assert replace(base, robots=3, n_envs=1).learning.batch_size == 256  # 128 · 1 · 3 samples
    with pytest.raises(ConfigError, match=f"^{key}: robots = 2 trains on the team task"):
        replace(base, robots=2, **change)
