"""oracle-greedy: it picks the candidate whose committed scan raises Q most (checked by replaying
the seeded episode and stepping each candidate), and its evaluation leaves the environment's
state bit-identical."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from nbv_gym.core.errors import NbvGymError
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import is_oracle, load_policy
from nbv_gym.policies.oracle import OracleGreedy

WORLD, SEED, FIRST_GOAL_STEPS = "pp1-cuboids", 5, 1


def new_env(policy) -> ExploreEnv:
    return make_env(ExploreEnv(world=WORLD, noise=1, task="budget", budget_scans=4).config, policy)


def state_digest(env: ExploreEnv) -> str:
    """SHA-256 of the map, statistics, cell totals, quality and the simulator's generator."""
    sim, h = env.sim, hashlib.sha256()
    h.update(np.nan_to_num(sim.occupancy.logodds, nan=-99.0).tobytes())
    stats = sim.statistics
    for array in (stats.n_obs, stats.r_min, stats.sector_mask, stats.sum_u,
                  sim.state.tally.sums, sim.state.tally.outside, sim.state.tally.crossed):  # fmt: skip
        h.update(np.ascontiguousarray(array).tobytes())
    metrics = sim.quality.metrics()
    for array in (metrics.observed, metrics.cov, metrics.l1):
        h.update(np.nan_to_num(array).tobytes())
    h.update(repr(sim.summary.q).encode() + repr(sim.rng.bit_generator.state).encode())
    return h.hexdigest()


@pytest.fixture(scope="module")
def decision():
    """The oracle's second decision of a seeded episode (after one step), with the state's digest
    before and after it."""
    oracle = OracleGreedy(n_best=4, n_random=4)
    env = new_env(oracle)
    observation, info = env.reset(seed=SEED)
    oracle.reset(SEED)
    oracle.attach(env)
    first = oracle.act(observation, info)
    observation, *_, info = env.step(first)
    before = state_digest(env)
    goal = oracle.act(observation, info)
    return oracle, first, goal, before, state_digest(env), env


def test_the_evaluation_leaves_the_state_bit_identical(decision):
    *_, before, after, _ = decision
    assert after == before


def test_it_picks_the_candidate_whose_committed_scan_raises_q_most(decision):
    oracle, first, goal, *_ = decision
    goals, predicted = oracle.last_evaluation["goals"], oracle.last_evaluation["delta_q"]
    assert len(goals) == 8
    replay = new_env(load_policy("ig-unknown"))
    committed = []
    for candidate in goals:
        replay.reset(seed=SEED)
        replay.step(first)
        *_, info = replay.step(int(candidate))
        committed.append(info["delta_q"])
    assert np.array_equal(predicted, committed)  # the exact reward of each step
    assert goal == goals[int(np.argmax(committed))]
    assert max(committed) > 0


def test_the_episode_is_unchanged_by_the_evaluation(decision):
    _oracle, first, goal, _, _, env = decision
    *_, info = env.step(goal)
    replay = new_env(load_policy("ig-unknown"))
    replay.reset(seed=SEED)
    replay.step(first)
    *_, replayed = replay.step(goal)
    assert info["q"] == replayed["q"]


def test_it_is_an_oracle_and_needs_the_environment():
    oracle = load_policy("oracle-greedy")
    assert is_oracle(oracle)
    with pytest.raises(NbvGymError, match=r"call policy.attach\(env.unwrapped\)"):
        oracle.act({}, {})


def test_the_harness_attaches_the_oracle():
    oracle = load_policy("oracle-greedy", n_best=2, n_random=1)
    result = run_episode(new_env(oracle), oracle, seed=SEED)
    assert len(result.steps) == 1 + 4  # the first scan and the budget of 4
    assert len(oracle.last_evaluation["goals"]) == 3
