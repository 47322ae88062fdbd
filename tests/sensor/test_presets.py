"""Lidar presets: the default is the benchmark's sensor, each preset's beams are its datasheet's,
every preset passes the environment checkers, and unknown names fail in one line with the near
miss, everywhere a preset is named."""

from __future__ import annotations

import math
import warnings

import gymnasium
import numpy as np
import pytest

import nbv_gym  # noqa: F401  (registers the environments)
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.core.pose import LocalisationNoise, Pose
from nbv_gym.env import ExploreEnv
from nbv_gym.sensor.lidar import Lidar, LidarConfig
from nbv_gym.sensor.presets import LIDAR_PRESETS, lidar_config, lidar_preset
from nbv_gym.worlds.raycast import RayScene
from tests.helpers import run_cli

WORLD = "pp1-cuboids"
#: Datasheet figures, typed in here independently of the registry: beams, lowest and highest
#: elevation (degrees), azimuth samples per revolution.
DATASHEETS = {
    "os1-64": (64, -16.6, 16.6, 1024),
    "os1-128": (128, -22.5, 22.5, 1024),
    "vlp-16": (16, -15.0, 15.0, 1800),
    "hdl-32e": (32, -30.67, 10.67, 2170),
}


def test_the_default_preset_is_the_benchmarks_sensor():
    assert lidar_config("os1-16") == LidarConfig()
    assert ExploreEnv(world=WORLD, lidar="os1-16").config == ExploreEnv(world=WORLD).config


@pytest.mark.parametrize("name", sorted(DATASHEETS))
def test_each_preset_has_its_datasheets_beams(name):
    channels, low, high, azimuth = DATASHEETS[name]
    directions = lidar_config(name).directions()
    elevation = np.degrees(np.arcsin(directions[:, 2]))
    assert len(directions) == channels * azimuth
    assert np.unique(np.round(elevation, 6)).size == channels
    assert elevation.min() == pytest.approx(low) and elevation.max() == pytest.approx(high)


def test_a_vlp16_on_flat_ground_sees_its_eight_lower_rings_at_their_ranges():
    """Beams at -15°, -13°, …, -1° from 0.42 m hit the ground at 0.42 / sin(-elevation)."""
    ground = np.array([[-500.0, -500.0, 0.0], [500.0, -500.0, 0.0], [500.0, 500.0, 0.0],
                       [-500.0, 500.0, 0.0]])  # fmt: skip
    scene = RayScene(ground, np.array([[0, 1, 2], [0, 2, 3]]))
    config = lidar_config("vlp-16")
    lidar = Lidar(scene, config.directions(), config.mount_height_m, 0.0, 0.0, None,
                  LocalisationNoise.level(0))  # fmt: skip
    scan = lidar.scan(Pose(0.0, 0.0, 0.0, 0.0), np.random.default_rng(0))
    expected = [0.42 / math.sin(math.radians(-e)) for e in range(-15, 0, 2)]
    assert np.unique(np.round(scan.ranges, 4)) == pytest.approx(sorted(expected), abs=1e-4)
    assert len(scan) == 8 * 1800


#: Every environment id of the package, from Gymnasium's registry.
ALL_IDS = sorted(env_id for env_id in gymnasium.registry if env_id.startswith("nbv_gym/"))


@pytest.mark.parametrize("env_id", ALL_IDS)
@pytest.mark.parametrize("name", sorted(LIDAR_PRESETS))
def test_every_preset_passes_the_gymnasium_checker(name, env_id):
    from gymnasium.utils.env_checker import check_env

    config = {"simulator": {"world": WORLD, "noise": 0, "lidar": {"range_noise": None}}}
    length = {"budget_scans" if "Budget" in env_id else "max_steps": 3}
    env = gymnasium.make(env_id, config=config, lidar=name, **length, disable_env_checker=True)
    assert env.unwrapped.config.simulator.lidar.n_azimuth == lidar_config(name).n_azimuth
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("name", sorted(LIDAR_PRESETS))
def test_every_preset_passes_the_stable_baselines3_checker(name):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gymnasium.make("nbv_gym/ExploreBudget-v0", world=WORLD, lidar=name, budget_scans=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(env.unwrapped, warn=True)
    env.close()


def test_an_unknown_preset_names_the_near_miss():
    with pytest.raises(UnknownNameError, match=r"Unknown lidar 'vlp16'\. Did you mean 'vlp-16'"):
        lidar_preset("vlp16")
    with pytest.raises(UnknownNameError, match="Did you mean 'os1-64'"):
        ExploreEnv(world=WORLD, lidar="os1_64")


def test_a_training_config_refuses_an_unknown_preset_naming_the_key():
    from nbv_gym.rl.config import train_config

    with pytest.raises(ConfigError, match=r"^lidar: Unknown lidar 'os-64'\. Did you mean"):
        train_config({"lidar": "os-64"})


def test_sweep_lidar_sets_the_pattern_keeps_the_default_and_refuses_a_clash():
    from nbv_gym.sweep.config import SweepConfig, with_lidar

    config = SweepConfig(worlds=(WORLD,), policies=("closest-frontier",))
    assert with_lidar(config, "os1-16") == config  # same fingerprint: resumes the same folder
    dense = with_lidar(config, "os1-64")
    assert dense.env_config(WORLD, 0).simulator.lidar == lidar_config("os1-64")
    assert dense.results_fingerprint() != config.results_fingerprint()
    assert with_lidar(dense, "vlp-16").task.lidar == "vlp-16"  # a name, replaced as one
    own = SweepConfig(worlds=(WORLD,), policies=("closest-frontier",),
                      env={"simulator": {"lidar": {"elevation_max_rad": 0.3}}})  # fmt: skip
    with pytest.raises(ConfigError, match=r"sets env\.simulator\.lidar\.elevation_max_rad itself"):
        with_lidar(own, "vlp-16")


def test_a_suite_with_another_lidar_is_another_suite():
    from nbv_gym.benchmark.suites import QUICK

    assert QUICK.with_lidar("os1-16").content_hash() == QUICK.content_hash()
    other = QUICK.with_lidar("vlp-16")
    assert other.content_hash() != QUICK.content_hash()
    assert other.parts[0].env_config().simulator.lidar == lidar_config("vlp-16")


@pytest.mark.parametrize(
    "args",
    [
        ["run", "--lidar", "vlp16", "--out", "out"],
        ["sweep", "quick", "--lidar", "vlp16", "--out", "out"],
        ["score", "closest-frontier", "--suite", "quick", "--lidar", "vlp16", "--out", "out"],
        ["record", "--policy", "random-free", "--world", WORLD, "--lidar", "vlp16", "--out", "o"],
        ["train", "--config", "ppo", "--lidar", "vlp16", "--out", "out"],
    ],
    ids=lambda args: args[0],
)
def test_each_command_refuses_an_unknown_preset_in_one_line_writing_nothing(tmp_path, args):
    result = run_cli(*args, cwd=tmp_path)
    lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert result.returncode == 2 and len(lines) == 1, result.stderr[-2000:]
    assert "Did you mean 'vlp-16'" in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_configs_lidars_lists_every_preset():
    result = run_cli("configs", "lidars")
    assert result.returncode == 0, result.stderr
    names = [line.split()[0] for line in result.stdout.splitlines()[1:] if line.strip()]
    assert names[: len(LIDAR_PRESETS)] == list(LIDAR_PRESETS)
