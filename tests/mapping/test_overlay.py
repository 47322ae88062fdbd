"""Scan trials on the live map (``ScanOverlay``): a trial gives the cell totals, crossing flags
and threshold levels that inserting the scan into a scratch copy of the map gives, bit for bit,
and never writes the map."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import PoseError
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.mapping import overlay
from nbv_gym.mapping.overlay import ScanOverlay
from nbv_gym.mapping.scratch import ScanTrial

#: The coverage thresholds whose crossings the simulator's cell totals flag.
THRESHOLDS = (0.7, 0.8)


@pytest.fixture(scope="module")
def explored():
    """The simulator after three scans on pp1-trees (noise 1), and the valid goals."""
    env = ExploreEnv(world="pp1-trees", noise=1, task="budget", budget_scans=4)
    _, info = env.reset(seed=3)
    for pick in (0, -1):
        *_, info = env.step(int(np.flatnonzero(info["action_mask"])[pick]))
    return env.sim, np.flatnonzero(info["action_mask"])


def map_bytes(sim) -> bytes:
    """The map's known voxels and log-odds, and the cell totals."""
    voxels, logodds = sim.occupancy.voxels_at_least(0.0)
    return voxels.tobytes() + logodds.tobytes() + sim.state.tally.sums.tobytes()


@pytest.mark.parametrize("capacity", [overlay.LOG_CAPACITY, 50])
def test_a_trial_gives_the_totals_and_levels_of_an_insertion(explored, capacity, monkeypatch):
    sim, goals = explored
    monkeypatch.setattr(overlay, "LOG_CAPACITY", capacity)  # 50: the log is folded many times
    trial, tried = ScanTrial(sim.state), ScanOverlay(sim.state, THRESHOLDS)
    trial.restore()
    before, crossings = map_bytes(sim), 0
    for goal in goals[:: max(1, len(goals) // 6)]:
        scan = sim.lidar.scan(sim.goal_pose(int(goal)), np.random.default_rng(int(goal)))
        totals = tried.try_scan(scan.origin, scan.points_map)
        inserted = trial.insert(scan.origin, scan.points_map)
        order = np.argsort(totals.cells)
        cells = totals.cells[order]
        assert np.array_equal(cells, inserted.touched_cells) and len(cells) > 100
        tally = trial.tally
        assert np.array_equal(totals.sums[order], tally.sums.reshape(-1)[cells])
        assert np.array_equal(totals.outside[order], tally.outside.reshape(-1)[cells])
        assert np.array_equal(totals.crossed[order], tally.crossed.reshape(-1)[cells])
        crossings += totals.crossed.sum()
        expected = trial.map.level_blocks(sim.goal_grid, sim.goal_grid.unravel(cells), tried.bounds)
        assert np.array_equal(tried.levels(cells), expected)
        trial.undo()
    assert crossings > 0
    assert map_bytes(sim) == before  # the trials read the map, never wrote it


def test_a_sensor_outside_the_map_is_refused_as_insertion_refuses_it(explored):
    sim, _ = explored
    with pytest.raises(PoseError, match="outside the map box"):
        ScanOverlay(sim.state, THRESHOLDS).try_scan(np.array([1e4, 0.0, 1.0]), np.zeros((1, 3)))


def test_a_trial_cut_short_leaves_no_marks_in_the_next(explored, monkeypatch):
    sim, goals = explored
    scan = sim.lidar.scan(sim.goal_pose(int(goals[0])), np.random.default_rng(0))
    expected = ScanOverlay(sim.state, THRESHOLDS).try_scan(scan.origin, scan.points_map)
    tried = ScanOverlay(sim.state, THRESHOLDS)

    def cut_short(origin, points, max_range, words, hit, *_):
        words[:] = hit[:] = np.uint64(0xFFFF)  # marks everywhere, then a failure
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(overlay, "_try_scan", cut_short)
        with pytest.raises(KeyboardInterrupt):
            tried.try_scan(scan.origin, scan.points_map)
    totals = tried.try_scan(scan.origin, scan.points_map)
    assert np.array_equal(totals.cells, expected.cells)
    assert np.array_equal(totals.sums, expected.sums) and len(totals.cells) > 100
