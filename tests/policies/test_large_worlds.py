"""Every shipped policy acts on the goal grid the agent view describes: on a 120 m world (120 × 120
goals of 1 m) each runs an episode, and a learned agent trained on 60 × 60 goals is refused with
one line naming both grids."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import NbvGymError
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.episode import run_episode
from nbv_gym.policies import required_layers
from nbv_gym.policies.registry import MODELS, POLICIES, load_policy

#: 12 cuboids spread over a 120 m window.
LARGE_WORLD = """
name = "large-cuboids"
ground_size_m = 130.0

[placement]
seed = 5
n_assets = 12
window_m = [-60.0, -60.0, 60.0, 60.0]

[assets]
mix = { cuboids = 1.0 }
"""


@pytest.fixture(scope="module")
def large_world(tmp_path_factory) -> str:
    path = tmp_path_factory.mktemp("worlds") / "large.toml"
    path.write_text(LARGE_WORLD)
    return str(path)


@pytest.mark.parametrize("name", sorted(POLICIES))
def test_every_shipped_policy_runs_on_a_120_m_world(name, large_world):
    policy = load_policy(name)
    env = ExploreEnv(task="budget", world=large_world, noise=0, budget_scans=2,
                     observation_layers=required_layers(policy))  # fmt: skip
    result = run_episode(env, policy, seed=1)
    goal = result.steps[-1]["goal"]
    centre = np.array([goal // 120, goal % 120]) + 0.5 - 60.0  # 1 m cells over -60 … 60 m
    assert len(result.steps) == 3  # the first scan and both scans of the budget
    np.testing.assert_allclose(env.unwrapped.sim.pose.position[:2], centre, atol=0.2)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_a_learned_agent_refuses_a_goal_grid_it_was_not_trained_on(name, large_world):
    pytest.importorskip("sb3_contrib")
    policy = load_policy(name)
    env = ExploreEnv(task="budget", world=large_world, noise=0, budget_scans=2,
                     observation_layers=required_layers(policy))  # fmt: skip
    with pytest.raises(
        NbvGymError, match=r"chooses among 3600 goals; this world has 14400"
    ) as error:
        run_episode(env, policy, seed=1)
    assert "\n" not in str(error.value)
