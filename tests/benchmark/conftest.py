"""A tiny suite with the standard suite's shape, for tests that score through the real code."""

from __future__ import annotations

import pytest

from nbv_gym.benchmark.suites import Part, Suite
from nbv_gym.env.task import TaskConfig
from nbv_gym.worlds.spec import AssetConfig, PlacementConfig, WorldSpec

#: A small generated world (10 crosses build in well under a second).
TINY_WORLD = WorldSpec(
    "tiny-test", PlacementConfig(seed=5, n_assets=10), AssetConfig(mix={"crosses": 1.0})
)


@pytest.fixture(scope="session")
def tiny_suite() -> Suite:
    """Time task of 40 s (2–3 scans) on a generated world, budget task of 2 scans on
    pp1-cuboids and on the generated world, explore task of at most 3 steps (too few to reach
    70 %) on pp1-cuboids; noise 0, 2 repeats (16 runs)."""
    return Suite(
        "tiny",
        (
            Part(
                "time-test",
                TaskConfig(name="time", time_budget_s=40.0),
                (TINY_WORLD,),
                noise=(0,),
                repeats=2,
            ),
            Part(
                "benchmark",
                TaskConfig(name="budget", budget_scans=2),
                ("pp1-cuboids",),
                noise=(0,),
                repeats=2,
            ),
            Part(
                "test",
                TaskConfig(name="budget", budget_scans=2),
                (TINY_WORLD,),
                noise=(0,),
                repeats=2,
            ),
            Part("explore", TaskConfig(max_steps=3), ("pp1-cuboids",), noise=(0,), repeats=2),
        ),
        seed=0,
    )
