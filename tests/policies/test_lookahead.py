"""The oracles' look-ahead (``FastLookahead``): on real episode states, every candidate's ΔQ
equals the insert-score-undo reference (``simulator.Lookahead``: the scan inserted into a scratch
copy of the map, Q recomputed, both undone) bit for bit, in two threads or one, and the
environment's state is left as it was."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import make_env
from nbv_gym.policies import load_policy
from nbv_gym.policies.lookahead import FastLookahead
from nbv_gym.policies.oracle import OracleGreedy
from nbv_gym.simulator import Lookahead, ResetNeededError


def state_digest(sim) -> str:
    """SHA-256 of the map's known voxels, the cell totals, the quality and the generator."""
    h = hashlib.sha256()
    for array in (*sim.occupancy.voxels_at_least(0.0), sim.state.tally.sums,
                  sim.state.tally.outside, sim.quality.metrics().l1):  # fmt: skip
        h.update(np.ascontiguousarray(array).tobytes())
    h.update(repr((sim.summary.q, sim.rng.bit_generator.state)).encode())
    return h.hexdigest()


@pytest.mark.parametrize(("world", "noise", "steps"), [("pp1-trees", 1, 3), ("pp1-crosses", 2, 5)])
def test_every_candidates_delta_q_equals_the_exact_look_ahead_bit_for_bit(world, noise, steps):
    driver = load_policy("ig-unknown")
    env = make_env(ExploreEnv(world=world, noise=noise, task="time",
                              observation_layers=driver.observation_layers).config, driver)  # fmt: skip
    observation, info = env.reset(seed=7)
    driver.reset(7)
    for _ in range(steps):
        observation, *_, info = env.step(driver.act(observation, info))
    sampler = OracleGreedy()
    sampler.reset(7)
    goals = sampler.candidates(observation, info)
    assert len(goals) == 64
    sim = env.unwrapped.sim
    before = state_digest(sim)
    exact = Lookahead(sim).delta_q(goals)
    assert state_digest(sim) == before
    for threads in (2, 1):
        assert np.array_equal(FastLookahead(sim, threads).delta_q(goals), exact)
        assert state_digest(sim) == before
    assert np.count_nonzero(exact) > 32 and len(set(exact.tolist())) > 32


def test_it_needs_a_reset_simulator():
    env = ExploreEnv(world="pp1-cuboids")
    with pytest.raises(ResetNeededError, match=r"reset\(\) before building a FastLookahead"):
        FastLookahead(env.unwrapped.sim)
