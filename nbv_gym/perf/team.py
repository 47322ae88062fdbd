"""Perf suite of the team task on pp1-trees: a 3-robot team episode against a single robot's on
the same world (closest-frontier, each robot of the team its own copy; the time task's 600 s,
noise 1), :data:`SEEDS` seeds, the two runs of each seed one after the other.

Keys of :func:`run`:
- ``team3_wall_ratio``: the team episode's wall time / the single robot's (median of the
  per-seed ratios); the team takes about 3 × the scans, so about 3 is the cost per scan of one
  robot, and less is cheaper per scan.
- ``team3_scan_ratio``: the team's scans / the single robot's (median of the per-seed ratios).
- ``team3_episode_s``: the team episode's wall time, s (median).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

from nbv_gym.perf import PERF_WORLD

#: Episodes of each kind (one seed each).
SEEDS = 3
#: The team's size.
ROBOTS = 3
POLICY = "closest-frontier"


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """The team's episode wall time and scans relative to a single robot's (module docstring)."""
    from nbv_gym.env import ExploreEnv
    from nbv_gym.episode import run_episode
    from nbv_gym.policies import load_policy
    from nbv_gym.team import EachRobot, TeamEnv, run_team_episode

    single = ExploreEnv(task="time", world=PERF_WORLD, noise=1)
    team = TeamEnv(world=PERF_WORLD, noise=1, n_robots=ROBOTS)
    single.reset(seed=0)  # builds and compiles everything once, outside the timings
    team.reset(seed=0)
    walls, scans, team_s = [], [], []
    for seed in range(SEEDS):
        progress(f"a single robot and a team of {ROBOTS} on {PERF_WORLD}, seed {seed}")
        start = time.perf_counter()
        alone = len(run_episode(single, load_policy(POLICY), seed).steps)
        single_s = time.perf_counter() - start
        start = time.perf_counter()
        together = len(run_team_episode(team, EachRobot.of(POLICY, ROBOTS), seed).scans)
        team_s.append(time.perf_counter() - start)
        walls.append(team_s[-1] / single_s)
        scans.append(together / alone)
    return {
        "team3_wall_ratio": statistics.median(walls),
        "team3_scan_ratio": statistics.median(scans),
        "team3_episode_s": statistics.median(team_s),
    }
