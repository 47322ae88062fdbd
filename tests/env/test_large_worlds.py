"""Worlds larger than the default 60 m window: the map box, G and the goals grow to hold the world's
placement window; worlds of a 60 m window keep the 60 × 60 goals exactly."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.env.actions import nearest_valid_goal
from nbv_gym.mapping import MappingConfig
from nbv_gym.simulator import Simulator, SimulatorConfig

ROOT = Path(__file__).parents[2]

#: A 20-cuboid world in an 80 × 70 m window (not square), off-centre.
WIDE_WORLD = """
name = "wide-cuboids"
ground_size_m = 104.0

[placement]
seed = 3
n_assets = 20
window_m = [-45.0, -30.5, 35.0, 39.2]

[assets]
mix = { cuboids = 1.0 }
"""


def readme_example_world() -> str:
    """The example spec of the README (or of the docs it moved to): the TOML block named
    "my-forest", 200 assets in a 100 m square."""
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("**/*.md"))]:
        if path.is_file():
            for block in re.findall(r"```toml\n(.*?)```", path.read_text(), re.S):
                if 'name = "my-forest"' in block:
                    return block
    raise AssertionError("no TOML block named my-forest in README.md or docs/")


def test_the_default_window_keeps_the_configured_boxes():
    config = MappingConfig()
    assert config.for_window((-30.0, -30.0, 30.0, 30.0)) is config
    assert config.for_window((-12.0, -5.0, 30.0, 20.0)) is config  # smaller: 60 × 60 goals kept


def test_a_larger_window_grows_g_by_whole_cells_and_moves_the_map_box_with_it():
    fitted = MappingConfig().for_window((-45.0, -30.5, 35.0, 39.2))
    # G: x from −45 (15 cells more), y from −31 (rounded out to whole 1 m cells) to 40
    assert fitted.statistics.low_m == (-45.0, -31.0, 0.2)
    assert fitted.statistics.high_m == (35.0, 40.0, 6.2)
    assert fitted.statistics.grid().shape == (80, 71, 6)
    # the map keeps its 2 m margins around G, and its z extent
    assert fitted.map.low_m == (-47.0, -33.0, -1.0)
    assert fitted.map.high_m == (37.0, 42.0, 8.0)
    assert fitted.map.grid().shape == (840, 750, 90)


def test_nearest_valid_goal_on_a_grid_that_is_not_square():
    mask = np.zeros(80 * 71, bool)
    mask[[3 * 71 + 70, 5 * 71]] = True  # (3, 70) and (5, 0)
    assert nearest_valid_goal(4 * 71 + 69, mask, (80, 71)) == 3 * 71 + 70
    assert nearest_valid_goal(4 * 71 + 1, mask, (80, 71)) == 5 * 71


def test_a_world_wider_than_60_m_runs_on_goals_that_cover_its_window(tmp_path):
    spec = tmp_path / "wide.toml"
    spec.write_text(WIDE_WORLD)
    sim = Simulator(SimulatorConfig(world=str(spec), noise=0))
    assert sim.goal_grid.shape[:2] == (80, 71) and sim.n_goals == 80 * 71
    assert sim.voxel_grid.shape == (800, 710, 60)
    sim.reset(0)
    goal = int(np.flatnonzero(sim.goal_mask())[0])
    outcome = sim.step(goal)
    assert sim.pose.x == pytest.approx(sim.goal_centres[goal][0])
    assert 0 < outcome.discovered < 1 and outcome.quality.q > 0


def test_a_world_outside_the_boxes_is_refused_when_not_fitted(tmp_path):
    spec = tmp_path / "wide.toml"
    spec.write_text(WIDE_WORLD)
    config = SimulatorConfig(world=str(spec), mapping=MappingConfig(fit_to_world=False))
    with pytest.raises(ConfigError, match=r"placement\.window_m.*outside the goal grid.*fit_to_w"):
        Simulator(config)


def test_a_window_beyond_the_largest_fitted_grid_is_refused_naming_the_limit(tmp_path):
    spec = tmp_path / "wide.toml"
    spec.write_text(WIDE_WORLD)
    config = SimulatorConfig(world=str(spec), mapping=MappingConfig(max_window_m=75.0))
    with pytest.raises(ConfigError, match=r"outside the goal grid .*max_window_m = 75 m"):
        Simulator(config)
    fitted = MappingConfig(max_window_m=80.0).fitted((-45.0, -30.5, 35.0, 39.2))
    assert fitted.statistics.low_m[0] == -45.0  # 80 m: at the limit, fitted


@pytest.mark.slow
def test_the_readme_example_world_runs_with_nbv_gym_run(tmp_path):
    spec = tmp_path / "my-forest.toml"
    spec.write_text(readme_example_world())
    out = tmp_path / "run"
    result = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "run", "--world", str(spec), "--max-steps", "2",
         "--no-animation", "--out", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    steps = (out / "steps.csv").read_text().splitlines()
    assert len(steps) == 4  # header, reset, two steps
    goals = [int(line.split(",")[1]) for line in steps[2:]]
    assert all(0 <= g < 100 * 100 for g in goals)
