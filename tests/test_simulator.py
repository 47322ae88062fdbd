"""The simulator on its own (no Gymnasium environment): episodes, reuse across resets, files."""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from nbv_gym.mapping import OccupancyMap, ViewpointStatistics
from nbv_gym.simulator import InvalidActionError, Simulator, SimulatorConfig

WORLD = "pp1-cuboids"


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(SimulatorConfig(world=WORLD, noise=1))


def episode(sim: Simulator, seed: int, steps: int = 3) -> list[tuple]:
    """What each scan of a short episode produced (the lowest valid goal each step)."""
    outcomes = [sim.reset(seed)]
    for _ in range(steps):
        outcomes.append(sim.step(int(np.flatnonzero(sim.goal_mask())[0])))
    return [
        (astuple(o.quality), o.reward, o.discovered, o.reason, o.touched.tobytes(),
         o.scan.points_map.tobytes(), sim.goal_mask().tobytes())
        for o in outcomes
    ]  # fmt: skip


def test_an_episode_scans_improves_quality_and_moves_the_robot(sim):
    first = sim.reset(0)
    assert first.quality.q > 0 and first.touched.any() and 0 < first.discovered < 0.7
    goal = int(np.flatnonzero(sim.goal_mask())[0])
    outcome = sim.step(goal)
    assert (sim.pose.x, sim.pose.y) == tuple(sim.goal_centres[goal])
    assert sim.steps == 1 and len(sim.trajectory) == 2
    assert outcome.path_length_m == pytest.approx(sim.path_length_m) and outcome.path_length_m > 0
    assert outcome.quality.q >= first.quality.q
    assert outcome.reward == outcome.delta_q == outcome.quality.q - first.quality.q


def test_a_reset_reuses_the_arrays_and_replays_a_fresh_simulator_bit_for_bit(sim):
    map_store = sim.occupancy._store
    played = episode(sim, seed=4)
    assert episode(sim, seed=4) == played  # the same simulator, reset: same bits
    assert sim.occupancy._store is map_store  # no new map per episode
    assert episode(Simulator(SimulatorConfig(world=WORLD, noise=1)), seed=4) == played
    assert episode(sim, seed=5) != played


def test_every_attribute_is_set_in_init():
    fresh = Simulator(SimulatorConfig(world=WORLD, noise=1))
    names = set(vars(fresh))
    fresh.reset(0)
    fresh.step(int(np.flatnonzero(fresh.goal_mask())[0]))
    assert set(vars(fresh)) == names


def test_save_writes_the_map_and_the_statistics(sim, tmp_path):
    sim.reset(1)
    sim.save(tmp_path / "run")
    occupancy = OccupancyMap.load(tmp_path / "run" / "map.npz")
    np.testing.assert_array_equal(occupancy.logodds, sim.occupancy.logodds)
    statistics = ViewpointStatistics.load(tmp_path / "run" / "statistics.npz")
    np.testing.assert_array_equal(statistics.n_obs, sim.statistics.n_obs)
    np.testing.assert_array_equal(statistics.column("r_min"), sim.statistics.column("r_min"))


def test_an_invalid_goal_is_refused_with_the_reason(sim):
    sim.reset(2)
    with pytest.raises(InvalidActionError, match="robot's own cell"):
        sim.step(30 * 60 + 30)
