"""Scan trials on a scratch map: undoing a trial (copying back only the blocks its insertion wrote)
leaves the scratch map and cell totals equal to the source's, trial after trial."""

from __future__ import annotations

import numpy as np

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.mapping.scratch import ScanTrial


def test_undo_after_each_trial_leaves_the_scratch_equal_to_the_source():
    env = ExploreEnv(world="pp1-cuboids", noise=1, task="budget", budget_scans=3)
    _, info = env.reset(seed=2)
    *_, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
    sim = env.sim
    trial = ScanTrial(sim.state)
    trial.restore()
    source = np.nan_to_num(sim.occupancy.logodds, nan=-99.0)
    goals = np.flatnonzero(info["action_mask"])[::40][:4]
    for goal in goals:
        scan = sim.lidar.scan(sim.goal_pose(int(goal)), np.random.default_rng(int(goal)))
        update = trial.insert(scan.origin, scan.points_map)
        assert update.touched.any()
        assert not np.array_equal(np.nan_to_num(trial.map.logodds, nan=-99.0), source)
        trial.undo()
        assert np.array_equal(np.nan_to_num(trial.map.logodds, nan=-99.0), source)
        for name in ("sums", "outside", "crossed"):
            assert np.array_equal(getattr(trial.tally, name), getattr(sim.state.tally, name))
    assert not trial.map.take_journal().any()  # undo took the journal
