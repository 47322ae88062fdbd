"""rl-zoo3 trains on nbv-gym out of the box: its own train entry point runs PPO (which reads no
action mask) with ``invalid_action="snap"`` and the project's hyper-parameter file, and the saved
model runs as an ``sb3:`` policy."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("rl_zoo3")

from nbv_gym.configs import config_file
from nbv_gym.core.protocol import BUDGET_ID
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import load_policy

ZOO_CONFIG = config_file("rl-zoo3-ppo")
BUDGET = 6


def zoo_train(world: str, logs: Path, timesteps: int) -> subprocess.CompletedProcess:
    """``python -m rl_zoo3.train`` on the budget id, as the README shows it, made small."""
    command = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", BUDGET_ID,
        "--gym-packages", "nbv_gym", "-conf", str(ZOO_CONFIG), "-f", str(logs),
        "-n", str(timesteps), "--eval-freq", "-1", "--seed", "0", "--num-threads", "1",
        "--env-kwargs", f"world:'{world}'", "invalid_action:'snap'", f"budget_scans:{BUDGET}",
        "-params", "n_envs:1", "n_steps:64", "batch_size:64", "n_epochs:1",
    ]  # fmt: skip
    return subprocess.run(command, capture_output=True, text=True)


def test_rl_zoo3_trains_ppo_and_the_model_finishes_an_episode_as_a_policy(world, tmp_path):
    done = zoo_train(world, tmp_path / "logs", timesteps=256)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    (model,) = (tmp_path / "logs" / "ppo").glob(f"*/{BUDGET_ID.replace('/', '-')}.zip")

    policy = load_policy(f"sb3:{model}")
    assert not policy.masked
    env = make_env(ExploreEnv(task="budget", world=world, budget_scans=BUDGET).config, policy)
    result = run_episode(env, policy, seed=1)
    assert result.end_reason  # the episode ended: the budget, or no goal left
    assert len(result.steps) == BUDGET + 1 or "no valid goal" in result.end_reason
    goals = [row["goal"] for row in result.steps[1:]]
    assert all(0 <= goal < 3600 for goal in goals)
