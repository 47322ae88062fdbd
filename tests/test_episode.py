"""The policy harness hands policies the agent view: a policy that reads ground truth fails in
``run``, ``sweep`` and ``record`` naming the key; an oracle declares itself, gets the full info and
its environment (the sweep's side: ``tests/sweep/test_oracles.py``)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from nbv_gym.core.protocol import EpisodeConfig
from nbv_gym.env.explore import EnvConfig, ExploreEnv
from nbv_gym.env.task import TaskConfig
from nbv_gym.env.views import PrivilegedInfoError
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import MODELS, POLICIES, is_oracle, load_policy
from nbv_gym.simulator import SimulatorConfig

WORLD = "pp1-cuboids"


def _config(max_steps: int = 2) -> EnvConfig:
    return EnvConfig(SimulatorConfig(world=WORLD, noise=1, episode=EpisodeConfig(max_steps)))


@pytest.mark.parametrize(
    ("name", "key"),
    [("peeking:Peek", "q"), ("peeking:PeekWorld", "world"), ("peeking:PeekPose", "true_pose")],
)
def test_a_policy_reading_ground_truth_fails_naming_the_key(peeking_policies, name, key):
    policy = load_policy(name)
    env = make_env(_config(), policy)
    message = rf"Policy peeking:\w+ read info\['{key}'\], which is privileged .* oracle"
    with pytest.raises(PrivilegedInfoError, match=message):
        run_episode(env, policy, seed=0)


def test_an_oracle_gets_its_environment_after_each_reset_and_the_full_info(peeking_policies):
    oracle = load_policy("peeking:Oracle")
    assert is_oracle(oracle) and not is_oracle(load_policy("closest-frontier"))
    env = make_env(_config(), oracle)
    for seed in (0, 1):
        result = run_episode(env, oracle, seed=seed)
        assert oracle.calls[0] == ("attach", ExploreEnv.__name__)  # before the first act
        acts = oracle.calls[1:]
        assert [c[0] for c in acts] == ["act", "act"] and acts[0][2] == WORLD
        assert [c[1] for c in acts] == [row["q"] for row in result.steps[:2]]
        assert [c[3] for c in acts] == [0, 1]  # the attached env is the one stepping


@pytest.mark.parametrize("name", [*POLICIES, *MODELS])
def test_every_shipped_policy_runs_on_the_agent_view(name):
    if name in MODELS:
        pytest.importorskip("sb3_contrib")
    policy = load_policy(name)
    if is_oracle(policy):
        pytest.skip("an oracle reads the full info by design")
    result = run_episode(make_env(_config(), policy), policy, seed=0)
    assert len(result.steps) == 3


def test_nbv_gym_run_refuses_a_peeking_policy_in_one_line(peeking_policies, tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "run", "--policy", "peeking:Peek", "--world", WORLD,
         "--max-steps", "2", "--no-animation", "--out", str(tmp_path / "run")],
        capture_output=True, text=True, timeout=300, cwd=peeking_policies,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr[-2000:]
    lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert len(lines) == 1 and "Traceback" not in result.stderr
    assert "read info['q'], which is privileged" in lines[0]
    assert "declare privileged = True to be an oracle" in lines[0]


def test_record_refuses_a_peeking_policy(peeking_policies, tmp_path):
    pytest.importorskip("minari")
    from nbv_gym.rl.dataset import record_dataset

    with pytest.raises(PrivilegedInfoError, match=r"read info\['world'\]"):
        record_dataset("peeking:PeekWorld", WORLD, tmp_path, TaskConfig(max_steps=1))
