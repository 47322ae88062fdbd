"""The CNN feature extractor and the goal-map head."""

from __future__ import annotations

import numpy as np
import pytest

th = pytest.importorskip("torch")
pytest.importorskip("sb3_contrib")

from gymnasium import spaces  # noqa: E402

from nbv_gym.env.observation import BASE_LAYERS  # noqa: E402
from nbv_gym.rl.extractor import MapExtractor  # noqa: E402


def observation_space(extra: dict[str, float] | None = None) -> spaces.Dict:
    entries = {k: spaces.Box(0.0, 1.0, (3600,), np.float32) for k in BASE_LAYERS}
    for name, high in (extra or {}).items():
        entries[name] = spaces.Box(0.0, high, (3600,), np.float32)
    entries["state"] = spaces.Box(-2.0, 2.0, (6,), np.float32)
    return spaces.Dict(entries)


def batch(space: spaces.Dict, n: int = 3) -> dict[str, th.Tensor]:
    rng = np.random.default_rng(0)
    return {k: th.as_tensor(rng.uniform(0, 1, (n, *s.shape)), dtype=th.float32)
            for k, s in space.spaces.items()}  # fmt: skip


@pytest.mark.parametrize("goal_scores", [True, False], ids=["goal-map", "dense"])
def test_output_holds_goal_scores_then_global_features(goal_scores):
    space = observation_space()
    extractor = MapExtractor(space, features_dim=64, goal_scores=goal_scores)
    features = extractor(batch(space))
    assert features.shape == (3, 64 + (3600 if goal_scores else 0))
    assert extractor.features_dim == features.shape[1]


def test_layers_become_images_in_goal_order():
    """Goal g = i · 60 + j is pixel (i, j) of its layer's channel."""
    space = observation_space()
    extractor = MapExtractor(space)
    observation = {k: th.zeros(1, *s.shape) for k, s in space.spaces.items()}
    goal = 7 * 60 + 41
    observation["robot"][0, goal] = 1.0
    image = extractor._image(observation)
    channel = extractor.layer_keys.index("robot")
    assert image.shape == (1, len(BASE_LAYERS), 60, 60)
    assert image[0, channel, 7, 41] == 1.0 and image.sum() == 1.0


def test_unbounded_layers_are_log_scaled_to_their_bound():
    space = observation_space({"gain_nobs": 1000.0})
    extractor = MapExtractor(space)
    observation = {k: th.zeros(1, *s.shape) for k, s in space.spaces.items()}
    observation["gain_nobs"][0, :] = 1000.0
    image = extractor._image(observation)
    channel = extractor.layer_keys.index("gain_nobs")
    assert th.allclose(image[0, channel], th.ones(60, 60))
