"""The team task: N robots exploring one world with one map and one clock, as a PettingZoo
``ParallelEnv`` (docs/team.md)."""

from nbv_gym.team.env import TeamEnv
from nbv_gym.team.episode import TeamEpisodeResult, run_team_episode
from nbv_gym.team.policies import (
    EachRobot,
    HungarianFrontier,
    UtilityFrontier,
    load_team_policy,
)
from nbv_gym.team.simulator import TeamSimulator, start_points

__all__ = [
    "EachRobot",
    "HungarianFrontier",
    "TeamEnv",
    "TeamEpisodeResult",
    "TeamSimulator",
    "UtilityFrontier",
    "load_team_policy",
    "run_team_episode",
    "start_points",
]
