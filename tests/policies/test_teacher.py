"""oracle-time, the time task's teacher: an oracle (privileged, ranked apart) whose values are
each candidate's exact reward per second^β — checked by stepping to the chosen goal — and whose
choice is their argmax; −inf off the candidates."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.benchmark.scorecard import policy_identity
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import is_oracle, load_policy
from nbv_gym.policies.teacher import DEFAULT_BETA, OracleTime


@pytest.fixture(scope="module")
def decision():
    """oracle-time's second decision of a time-task episode on pp1-cuboids, its values, and the
    step to its goal."""
    teacher = OracleTime(n_best=8, n_random=8)
    env = make_env(ExploreEnv(world="pp1-cuboids", noise=1, task="time",
                              observation_layers=teacher.observation_layers).config, teacher)  # fmt: skip
    observation, info = env.reset(seed=4)
    teacher.reset(4)
    teacher.attach(env.unwrapped)
    observation, *_, info = env.step(teacher.act(observation, info))
    before = env.unwrapped.sim.elapsed_s
    values = teacher.values(observation, info)
    evaluation = dict(teacher.last_evaluation)
    goal = int(evaluation["goals"][int(np.argmax(evaluation["value"]))])
    _, reward, *_, stepped = env.step(goal)
    return values, evaluation, goal, (reward, stepped), env.unwrapped.sim.elapsed_s - before


def test_values_are_the_candidates_reward_per_second_and_minus_inf_elsewhere(decision):
    values, evaluation, goal, stepped, spent = decision
    goals = evaluation["goals"]
    assert values.shape == (3600,) and values.dtype == np.float64
    assert np.all(np.isfinite(values[goals])) and np.isneginf(np.delete(values, goals)).all()
    assert np.array_equal(
        values[goals], evaluation["reward"] / evaluation["cost_s"] ** DEFAULT_BETA
    )
    chosen = int(np.flatnonzero(goals == goal)[0])
    reward, info = stepped
    assert info["delta_q"] == evaluation["delta_q"][chosen]  # the exact ΔQ of the step
    assert reward == evaluation["reward"][chosen]  # and its exact reward
    assert evaluation["cost_s"][chosen] == pytest.approx(spent)  # the step's seconds


def test_it_chooses_the_highest_value_the_first_on_a_tie():
    teacher = OracleTime(n_best=4, n_random=0, beta=0.5)
    env = make_env(ExploreEnv(world="pp1-cuboids", noise=0, task="time",
                              observation_layers=teacher.observation_layers).config, teacher)  # fmt: skip
    observation, info = env.reset(seed=5)
    teacher.reset(5)
    teacher.attach(env.unwrapped)
    goal = teacher.act(observation, info)
    evaluation = teacher.last_evaluation
    assert goal == evaluation["goals"][int(np.argmax(evaluation["value"]))]
    assert evaluation["value"] == pytest.approx(evaluation["reward"] / evaluation["cost_s"] ** 0.5)


def test_it_is_an_oracle_ranked_apart_and_needs_the_environment():
    teacher = load_policy("oracle-time")
    assert is_oracle(teacher) and policy_identity("oracle-time")["oracle"] is True
    assert teacher.beta == DEFAULT_BETA and load_policy("oracle-time@0.25").beta == 0.25
    with pytest.raises(NbvGymError, match=r"call policy.attach\(env.unwrapped\)"):
        teacher.act({}, {"action_mask": np.ones(4, bool)})
    with pytest.raises(ConfigError, match="beta must be a finite number ≥ 0"):
        OracleTime(beta=-1.0)


def test_the_harness_attaches_the_teacher():
    teacher = load_policy("oracle-time", n_best=2, n_random=1)
    env = ExploreEnv(world="pp1-cuboids", noise=1, task="budget", budget_scans=3,
                     observation_layers=teacher.observation_layers)  # fmt: skip
    result = run_episode(env, teacher, seed=6)
    assert len(result.steps) == 1 + 3 and len(teacher.last_evaluation["goals"]) == 3
