"""The four nbv-* policies: argmax of gain − α · cost, the near-uniform rule, seeded ties."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.nbv import NbvConfig, NbvSensor, predict_gains_arrays
from nbv_gym.policies.nbv import NbvNobs, NbvNomega, NbvPolicy, NbvRmin, NbvSigma, near_uniform

POLICIES = {"nobs": NbvNobs, "rmin": NbvRmin, "nomega": NbvNomega, "sigma": NbvSigma}


def observation(gains, cost=None, candidates=None, statistic="nobs"):
    gains = np.asarray(gains, np.float32)
    return {
        f"gain_{statistic}": gains,
        "nbv_candidates": np.ones_like(gains) if candidates is None else np.asarray(candidates),
        "cost": np.zeros_like(gains) if cost is None else np.asarray(cost, np.float32),
    }


def info(n, invalid=()):
    mask = np.ones(n, bool)
    mask[list(invalid)] = False
    return {"action_mask": mask}


@pytest.mark.parametrize("name", POLICIES)
def test_the_policies_declare_their_layers(name):
    policy = POLICIES[name]()
    assert policy.observation_layers == (f"gain_{name}", "nbv_candidates")
    assert isinstance(policy, NbvPolicy) and policy.alpha is None


@pytest.mark.parametrize("name", POLICIES)
def test_alpha_is_the_papers_but_in_the_time_task_and_a_given_one_wins(name):
    tuned = {"nobs": 20000.0, "rmin": 2000.0, "nomega": 20000.0, "sigma": 20000.0}[name]
    time_info = {**info(4), "remaining_s": 100.0}
    assert POLICIES[name]().task_alpha(info(4)) == 2.0  # the paper's, explore and budget tasks
    assert POLICIES[name]().task_alpha(time_info) == tuned
    assert POLICIES[name](alpha=7.0).task_alpha(time_info) == 7.0


class Corridor:
    """A row of 9 cells with an occluding wall at 4; candidates at columns 1 and 7 (both see the
    wall, neither sees past it)."""

    def __init__(self):
        self.grid = GridSpec((0.0, 0.0, 0.0), 1.0, (9, 1, 1))
        self.n_obs = np.zeros(self.grid.shape, np.int32)
        self.r_min = np.full(self.grid.shape, np.nan)
        self.sectors = np.zeros(self.grid.shape, np.uint32)
        self.sum_u = np.zeros((*self.grid.shape, 3))
        self.occluding = np.zeros(self.grid.shape, bool)
        self.occluding[4] = True

    def observation(self, cost=(0.0, 0.0)):
        candidates = np.zeros(9, bool)
        candidates[[1, 7]] = True
        config = NbvConfig(visibility="sphere")
        sensor = NbvSensor(sensor_range_m=10.0, min_range_m=0.5, sensor_height_m=0.5, n_sectors=32,
                           elevation_min_rad=-0.26, elevation_max_rad=0.26)  # fmt: skip
        layers = predict_gains_arrays(
            self.grid, self.n_obs, self.r_min, self.sectors, self.sum_u, self.occluding,
            np.array([4.5, 3.5]), candidates, config, sensor=sensor,
        )  # fmt: skip
        costs = np.ones((9, 1), np.float32)
        costs[[1, 7], 0] = cost
        return {**layers, "nbv_candidates": candidates[:, None].astype(np.float32), "cost": costs}


@pytest.mark.parametrize("name", ["nobs", "rmin", "nomega"])
@pytest.mark.parametrize("cost", [(0.0, 0.0), (0.0, 1.0)])
def test_a_candidate_seeing_unobserved_cells_beats_one_seeing_nothing_new(name, cost):
    corridor = Corridor()
    # Cells 0–4 (seen by the candidate at 1) observed a million times, from 0.5 m, from all sectors
    corridor.n_obs[:5] = 1_000_000
    corridor.r_min[:5] = 0.5
    corridor.sectors[:5] = np.uint32(0xFFFFFFFF)
    corridor.sum_u[:5, 0, 0, 1] = 1_000_000
    policy = POLICIES[name]()
    policy.reset(0)
    assert policy.act(corridor.observation(cost), info(9)) == 7


def test_nbv_sigma_prefers_a_new_direction_on_observed_cells():
    corridor = Corridor()
    corridor.n_obs[:5] = 2  # seen twice from +y: σ = 0, a view from ±x raises it
    corridor.sum_u[:5, 0, 0, 1] = 2.0
    policy = NbvSigma()
    policy.reset(0)
    assert policy.act(corridor.observation((0.0, 0.5)), info(9)) == 1


def test_the_utility_trades_gain_against_cost():
    policy = NbvNobs()
    policy.reset(0)
    # utilities 10 − 2·1 = 8, 9 − 2·0 = 9, 9.5 − 2·0.5 = 8.5
    assert policy.act(observation([10.0, 9.0, 9.5], cost=[1.0, 0.0, 0.5]), info(3)) == 1


def test_near_uniform_gains_give_a_seeded_random_candidate():
    obs = observation([10.0, 10.2, 10.4, 0.0], cost=[1.0, 0.0, 1.0, 0.0], candidates=[1, 1, 1, 0])
    choices = []
    for seed in range(40):
        policy = NbvNobs()
        policy.reset(seed)
        first = [policy.act(obs, info(4)) for _ in range(3)]
        policy.reset(seed)
        assert [policy.act(obs, info(4)) for _ in range(3)] == first  # deterministic
        choices += first
    assert set(choices) == {0, 1, 2}  # 10.4 / 10 − 1 = 0.04 ≤ 0.05: the utility is not used


def test_gains_beyond_the_tolerance_use_the_utility():
    obs = observation([10.0, 10.6], cost=[0.0, 0.0])  # 10.6 / 10 − 1 = 0.06 > 0.05
    for seed in range(10):
        policy = NbvNobs()
        policy.reset(seed)
        assert policy.act(obs, info(2)) == 1


def test_ties_are_broken_by_the_seeded_generator():
    obs = observation([5.0, 1.0, 5.0], cost=[0.5, 0.0, 0.5])
    picks = {}
    for seed in range(30):
        policy = NbvPolicy("nobs")
        policy.reset(seed)
        picks[seed] = policy.act(obs, info(3))
        policy.reset(seed)
        assert policy.act(obs, info(3)) == picks[seed]
    assert set(picks.values()) == {0, 2}


@pytest.mark.parametrize(
    ("gains", "expected"),
    [
        ([1.0, 1.05], True),
        ([1.0, 1.06], False),
        ([0.0, 0.0], True),  # min ≤ 0: near-uniform only if all equal
        ([0.0, 1e-9], False),
        ([3.0], True),
    ],
)
def test_near_uniform_rule(gains, expected):
    assert near_uniform(np.array(gains), 0.05) == expected


def test_without_candidates_a_random_valid_goal():
    obs = observation([0.0] * 5, candidates=[0] * 5)
    chosen = set()
    for seed in range(30):
        policy = NbvNomega()
        policy.reset(seed)
        chosen.add(policy.act(obs, info(5, invalid=(0, 3))))
    assert chosen == {1, 2, 4}


def test_candidates_outside_the_action_mask_are_ignored():
    policy = NbvNobs()
    policy.reset(0)
    assert policy.act(observation([9.0, 1.0, 2.0]), info(3, invalid=(0,))) == 2


def test_errors_say_what_is_missing():
    policy = NbvSigma()
    with pytest.raises(NbvGymError, match="no layer 'gain_sigma'"):
        policy.act(observation([1.0]), info(1))
    with pytest.raises(NbvGymError, match="action_mask"):
        policy.act(observation([1.0], statistic="sigma"), {})
    with pytest.raises(NbvGymError, match="no valid goal"):
        policy.act(observation([1.0], statistic="sigma"), info(1, invalid=(0,)))
    with pytest.raises(ConfigError, match="statistic"):
        NbvPolicy("variance")
