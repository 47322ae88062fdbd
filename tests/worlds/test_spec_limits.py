"""World specs whose assets could not stand on the ground inside the map are refused, naming the
key; a world placed beyond the simulator's grid is refused before it is built."""

from __future__ import annotations

import warnings

import pytest

from nbv_gym.core.errors import ConfigError
from nbv_gym.mapping.state import MappingConfig
from nbv_gym.simulator import Simulator, SimulatorConfig
from nbv_gym.worlds import load_spec, parse_spec

SPEC = """
name = "edge"
ground_size_m = 64.0
[placement]
seed = 1
n_assets = 10
window_m = [-30.0, -30.0, 30.0, 30.0]
clear_radius_m = 2.0
[assets]
mix = { cuboids = 1.0 }
"""


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (
            "clear_radius_m = 2.0",
            "clear_radius_m = 1000",
            r"placement: clear_radius_m: the clear disc around the start must lie inside "
            r"window_m \(radius < 30 m, its nearest edge\), got 1000",
        ),
        ("clear_radius_m = 2.0", "clear_radius_m = inf", r"clear_radius_m: must be ≥ 0 and finite"),
        ("ground_size_m = 64.0", "ground_size_m = -64", r"ground_size_m: must be > 0 and finite"),
        (
            "ground_size_m = 64.0",
            "ground_size_m = 40",
            r"ground_size_m: the ground \(±20 m around the origin\) must cover placement.window_m",
        ),
        ("cuboids = 1.0", "cuboids = inf", r"assets: mix: needs finite non-negative weights"),
        ("cuboids = 1.0", "cuboids = nan", r"assets: mix: needs finite non-negative weights"),
        ("window_m = [-30.0", "window_m = [-inf", r"placement: window_m: must be finite"),
    ],
)
def test_a_degenerate_spec_is_refused_naming_the_key(old, new, message):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy RuntimeWarning on the way
        with pytest.raises(ConfigError, match=message):
            parse_spec(SPEC.replace(old, new), "edge.toml")


def test_a_window_larger_than_any_map_is_refused_when_the_spec_is_read():
    text = SPEC.replace("ground_size_m = 64.0", "ground_size_m = 2000.0")
    wide = text.replace("[-30.0, -30.0, 30.0, 30.0]", "[-300.0, -10.0, 300.0, 10.0]")
    with pytest.raises(ConfigError, match=r"window_m: its sides must be at most 500 m .* 600 m"):
        parse_spec(wide, "edge.toml")  # it built for minutes before a run refused it


def test_a_window_beyond_the_goal_grid_is_refused_before_the_world_is_built(tmp_path):
    spec = tmp_path / "wide.toml"
    text = SPEC.replace("ground_size_m = 64.0", "ground_size_m = 400.0")
    spec.write_text(text.replace("[-30.0, -30.0, 30.0, 30.0]", "[-200.0, -200.0, 200.0, 200.0]"))
    assert load_spec(spec).placement.window_m[0] == -200  # a valid spec on its own
    small = SimulatorConfig(world=str(spec), mapping=MappingConfig(max_window_m=100.0))
    with pytest.raises(ConfigError, match=r"placement.window_m: world 'edge' places assets in "
                       r"\(-200.0, -200.0, 200.0, 200.0\), outside the goal grid"):  # fmt: skip
        Simulator(small)


def test_an_empty_world_name_says_so():
    with pytest.raises(ConfigError, match=r"^The world name is empty; give a benchmark world"):
        load_spec("")
