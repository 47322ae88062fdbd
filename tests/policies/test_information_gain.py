"""ig-unknown and ig-entropy: argmax of gain · exp(−λ · path length) over the candidates."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.policies import is_oracle, load_policy
from nbv_gym.policies.information_gain import IgEntropy, IgUnknown


def observation(layer: str, gains, costs, candidates):
    n = 6
    out = {layer: np.zeros(n, np.float32), "cost": np.ones(n, np.float32),
           "nbv_candidates": np.zeros(n, np.float32)}  # fmt: skip
    out[layer][: len(gains)] = gains
    out["cost"][: len(costs)] = costs
    out["nbv_candidates"][list(candidates)] = 1.0
    return out


@pytest.mark.parametrize(
    ("cls", "layer"), [(IgUnknown, "gain_unknown"), (IgEntropy, "gain_entropy")]
)
def test_the_goal_maximises_gain_times_exp_minus_lambda_path(cls, layer):
    # goal 0: 100 voxels at 2 m; goal 1: 300 at 16 m; goal 2: 1000 but not a candidate
    obs = observation(layer, [100, 300, 1000], [0.1, 0.8, 0.0], candidates=(0, 1))
    info = {"action_mask": np.ones(6, np.int8), "cost_range_m": 20.0}
    near, far = 100 * math.exp(-0.1 * 2), 300 * math.exp(-0.1 * 16)  # 81.9 > 60.6
    assert near > far
    assert cls(lam=0.1).act(obs, info) == 0
    assert cls(lam=0.0).act(obs, info) == 1  # no travel cost: the largest gain


def test_lambda_after_at_and_bad_lambdas():
    assert load_policy("ig-unknown@0.25").lam == 0.25
    assert not is_oracle(load_policy("ig-entropy"))
    with pytest.raises(ConfigError, match="lam: expected a number from 0 to 100, got 'fast'"):
        IgUnknown(lam="fast")
    with pytest.raises(ConfigError, match=r"lam: expected a number from 0 to 100 .*got -1$"):
        IgUnknown(lam=-1.0)
    with pytest.raises(ConfigError, match=r"overflow\), got 1e\+308$"):
        IgUnknown(lam=1e308)  # once an overflow warning from numpy
    assert IgUnknown(lam=100).lam == 100.0


def test_without_candidates_a_valid_goal():
    obs = observation("gain_unknown", [5, 5], [0, 0], candidates=())
    mask = np.array([0, 0, 0, 1, 0, 0], np.int8)
    policy = IgUnknown()
    policy.reset(3)
    assert policy.act(obs, {"action_mask": mask, "cost_range_m": 20.0}) == 3
