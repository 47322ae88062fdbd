"""A tiny world for the RL tests: training runs a few hundred steps on it."""

from __future__ import annotations

import pytest

TINY_WORLD = """
name = "tiny-cuboids"
description = "10 cuboids for the RL tests"

[placement]
seed = 7
n_assets = 10
cluster_radius_m = 30.0

[assets]
mix = { cuboids = 1.0 }
"""


@pytest.fixture(scope="session")
def world(tmp_path_factory) -> str:
    """The path of the tiny world's spec file."""
    path = tmp_path_factory.mktemp("worlds") / "tiny.toml"
    path.write_text(TINY_WORLD)
    return str(path)
