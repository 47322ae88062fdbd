"""Wall time of a 3-robot team episode against a single-robot episode on one world (the
closest-frontier baseline, the time task's 600 s; each robot of the team its own copy): 5 seeds,
the three runs of each seed interleaved, medians of the per-seed ratios.

    python experiments/team_wall_time.py pp1-cuboids
"""

from __future__ import annotations

import statistics
import sys
import time

from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import run_episode
from nbv_gym.policies import load_policy
from nbv_gym.team import EachRobot, TeamEnv, run_team_episode

POLICY = "closest-frontier"


def main(world: str, seeds: int = 5) -> None:
    single = ExploreEnv(task="time", world=world)
    teams = {n: TeamEnv(world=world, n_robots=n) for n in (1, 3)}
    seconds: dict[str, list[float]] = {"single": [], "team of 1": [], "team of 3": []}
    scans: dict[str, list[int]] = {name: [] for name in seconds}
    for seed in range(seeds):
        start = time.perf_counter()
        result = run_episode(single, load_policy(POLICY), seed)
        seconds["single"].append(time.perf_counter() - start)
        scans["single"].append(len(result.steps))
        for n, env in teams.items():
            start = time.perf_counter()
            team = run_team_episode(env, EachRobot.of(POLICY, n), seed)
            seconds[f"team of {n}"].append(time.perf_counter() - start)
            scans[f"team of {n}"].append(len(team.scans))
    for name, values in seconds.items():
        print(f"{name}: median {statistics.median(values):.2f} s, scans {scans[name]}")
    for name in ("team of 1", "team of 3"):
        ratios = [t / s for t, s in zip(seconds[name], seconds["single"], strict=True)]
        rounded = [round(r, 2) for r in ratios]
        print(f"{name} / single: {rounded}, median {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "pp1-cuboids")
