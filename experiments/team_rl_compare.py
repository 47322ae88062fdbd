"""A team agent trained with ``nbv-gym train --config team-ppo`` against the team references, on
team episodes (3 robots, the time task's 600 s, noise 1): the area under the team's Q(t), Q at
the end and the overlap rate, per episode and as medians.

    python experiments/team_rl_compare.py runs/team-ppo/final_model.zip pp1-cuboids:0,1,2

Policies: the shared agent (``SharedTeamAgent``, most likely goal), ``hungarian-frontier``
(coordinated) and ``closest-frontier`` on each robot (uncoordinated); the episodes of one world
and seed run one after the other.
"""

from __future__ import annotations

import statistics
import sys

import torch

from nbv_gym.rl.teamagent import SharedTeamAgent
from nbv_gym.team import TeamEnv, load_team_policy, run_team_episode

ROBOTS = 3
FIGURES = ("q_time_auc", "q", "overlap_rate")


def main(model: str, episodes: list[str]) -> None:
    torch.set_num_threads(1)  # a busy machine: more threads than free cores are slower
    policies = {
        "team-ppo (shared)": lambda: SharedTeamAgent(model),
        "hungarian-frontier": lambda: load_team_policy("hungarian-frontier", ROBOTS),
        "closest-frontier x3": lambda: load_team_policy("closest-frontier", ROBOTS),
    }
    rows: dict[str, list[dict]] = {name: [] for name in policies}
    for spec in episodes:
        world, _, seeds = spec.partition(":")
        env = TeamEnv(world=world, n_robots=ROBOTS, noise=1)
        for seed in map(int, (seeds or "0").split(",")):
            for name, make in policies.items():
                figures = run_team_episode(env, make(), seed).figures
                rows[name].append(figures)
                print(f"{world} seed {seed} {name:20s} "
                      + "  ".join(f"{k} {figures[k]:.4f}" for k in FIGURES), flush=True)  # fmt: skip
    print("medians:")
    for name, found in rows.items():
        medians = {k: statistics.median(f[k] for f in found) for k in FIGURES}
        print(f"  {name:20s} " + "  ".join(f"{k} {v:.4f}" for k, v in medians.items()))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2:])
