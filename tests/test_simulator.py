"""The simulator on its own (no Gymnasium environment): episodes, reuse across resets, files."""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pytest

from nbv_gym.mapping import ViewpointStatistics
from nbv_gym.mapping.mapfile import load_map
from nbv_gym.metrics.cuboids import QualityConfig
from nbv_gym.metrics.tracker import evaluate_cuboids
from nbv_gym.simulator import (
    Exploration,
    InvalidActionError,
    ResetNeededError,
    Simulator,
    SimulatorConfig,
)

WORLD = "pp1-cuboids"


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return Simulator(SimulatorConfig(world=WORLD, noise=1))


def episode(sim: Simulator, seed: int, steps: int = 3) -> list[tuple]:
    """What each scan of a short episode produced (the lowest valid goal each step)."""
    outcomes = [sim.reset(seed)]
    for _ in range(steps):
        outcomes.append(sim.step(int(np.flatnonzero(sim.goal_mask())[0])))
    return [
        (astuple(o.quality), o.reward, o.discovered, o.reason, o.touched.tobytes(),
         o.scan.points_map.tobytes(), sim.goal_mask().tobytes())
        for o in outcomes
    ]  # fmt: skip


def test_an_episode_scans_improves_quality_and_moves_the_robot(sim):
    first = sim.reset(0)
    assert first.quality.q > 0 and first.touched.any() and 0 < first.discovered < 0.7
    goal = int(np.flatnonzero(sim.goal_mask())[0])
    outcome = sim.step(goal)
    assert (sim.pose.x, sim.pose.y) == tuple(sim.goal_centres[goal])
    assert sim.steps == 1 and len(sim.trajectory) == 2
    assert outcome.path_length_m == pytest.approx(sim.path_length_m) and outcome.path_length_m > 0
    assert outcome.quality.q >= first.quality.q
    assert outcome.reward == outcome.delta_q == outcome.quality.q - first.quality.q


def test_a_reset_reuses_the_arrays_and_replays_a_fresh_simulator_bit_for_bit(sim):
    map_store = sim.occupancy._store
    played = episode(sim, seed=4)
    assert episode(sim, seed=4) == played  # the same simulator, reset: same bits
    assert sim.occupancy._store is map_store  # no new map per episode
    assert episode(Simulator(SimulatorConfig(world=WORLD, noise=1)), seed=4) == played
    assert episode(sim, seed=5) != played


def test_the_robot_owns_pose_path_clock_and_noise_and_the_rest_is_shared(sim):
    sim.reset(2)
    sim.step(int(np.flatnonzero(sim.goal_mask())[0]))
    robot = sim.robot
    assert isinstance(sim, Exploration) and sim.pose is robot.pose and sim.rng is robot.rng
    assert sim.trajectory is robot.trajectory and (sim.steps, sim.path_length_m) == (
        1,
        robot.path_length_m,
    )
    assert sim.elapsed_s == sim.config.episode.effort.elapsed_s(robot.path_length_m, 1)


def test_every_attribute_is_set_in_init():
    fresh = Simulator(SimulatorConfig(world=WORLD, noise=1))
    names = set(vars(fresh))
    fresh.reset(0)
    fresh.step(int(np.flatnonzero(fresh.goal_mask())[0]))
    assert set(vars(fresh)) == names


def test_the_goal_mask_before_a_reset_asks_for_one():
    fresh = Simulator(SimulatorConfig(world=WORLD, noise=1))
    with pytest.raises(ResetNeededError, match=r"Call reset\(\) first"):
        fresh.goal_mask()
    fresh.reset(0)
    assert fresh.goal_mask().any()


def test_save_writes_the_map_and_the_statistics(sim, tmp_path):
    sim.reset(1)
    sim.save(tmp_path / "run")
    occupancy = load_map(tmp_path / "run" / "map.npz")
    np.testing.assert_array_equal(occupancy.logodds, sim.occupancy.logodds)
    statistics = ViewpointStatistics.load(tmp_path / "run" / "statistics.npz")
    np.testing.assert_array_equal(statistics.n_obs, sim.statistics.n_obs)
    np.testing.assert_array_equal(statistics.column("r_min"), sim.statistics.column("r_min"))


def test_an_invalid_goal_is_refused_with_the_reason(sim):
    sim.reset(2)
    with pytest.raises(InvalidActionError, match="robot's own cell"):
        sim.step(30 * 60 + 30)


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"quality": {"clamp_min_p": 0.2}}, "quality.clamp_min_p"),  # the map's clamp decides
        ({"quality": {"cuboid_voxels": 5}}, "quality.cuboid_voxels"),  # G's cells decide
        ({"quality": {"resolution_m": 0.05}}, "quality.resolution_m"),  # the map's voxels decide
        ({"mapping": {"statistics": {"cell_m": 0.25}}}, "statistics: G"),  # 2.5 voxels
        (
            {
                "mapping": {
                    "statistics": {"low_m": [-30.05, -30.0, 0.2], "high_m": [29.95, 30.0, 6.2]}
                }
            },
            "statistics: G",
        ),
        ({"mapping": {"statistics": {"high_m": [34.0, 30.0, 6.2]}}}, "inside the map box"),
    ],
)
def test_configs_that_cannot_work_are_refused_naming_the_key(overrides, key):
    from nbv_gym.core.config import from_dict
    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        from_dict(SimulatorConfig, overrides)


def test_quality_is_computed_on_the_maps_voxels_and_clamp():
    config = SimulatorConfig(world=WORLD)
    cuboids = Simulator(config).quality.config
    assert cuboids.resolution_m == config.mapping.map.resolution_m
    assert cuboids.clamp_min_p == config.mapping.map.p_clamp_min
    assert cuboids.cuboid_voxels * cuboids.resolution_m == pytest.approx(
        config.mapping.statistics.cell_m
    )


def test_incremental_quality_equals_a_full_recomputation_of_the_map():
    """Scan by scan the simulator re-evaluates only the touched cuboids and searches coverage
    only where a voxel crossed a threshold (one below 0.5 here, which unknown voxels exceed); the
    result must equal the metrics of the whole map recomputed from scratch, bit for bit."""
    settings = ((0.8, 0.05), (0.45, 0.1), (0.7, 0.15))
    sim = Simulator(SimulatorConfig(world=WORLD, noise=1, quality=QualityConfig(
        cov_settings=settings, q_setting=2)))  # fmt: skip
    sim.reset(3)
    for _ in range(3):
        sim.step(int(np.flatnonzero(sim.goal_mask())[-1]))
    gt = np.zeros(sim.voxel_grid.shape, bool)
    gt[tuple(sim.world.ground_truth.grid_voxels(sim.voxel_grid).T)] = True
    probability = sim.occupancy.probability(sim.voxel_grid)
    full = evaluate_cuboids(probability, gt, sim.quality.config)
    kept = sim.quality.metrics()
    np.testing.assert_array_equal(kept.observed, full.observed)
    np.testing.assert_array_equal(kept.l1, full.l1)
    np.testing.assert_array_equal(kept.cov, full.cov)
    np.testing.assert_equal(astuple(sim.summary), astuple(full.summary()))
    assert 0 < sim.summary.q < 1 and kept.observed.sum() > 100


def test_the_map_pages_of_n_scans_are_bounded_by_the_box_and_the_marking_window():
    from nbv_gym.mapping import MappingConfig
    from nbv_gym.simulator import map_page_bytes

    # the default 64 × 64 × 9 m box at 0.1 m: 40 × 40 × 23 bricks of 16 × 16 × 4 voxels; a
    # 20 m sensor's window is 408 × 408 × 96 voxels (403 rounded up to bytes of 8), at most 27
    # × 27 × 23 bricks (25.5 + 1 along x, y; the box's 23 along z)
    config = MappingConfig()
    assert map_page_bytes(config, 1) == 27 * 27 * 23 * 4096
    assert map_page_bytes(config, 3) == 40 * 40 * 23 * 4096


def test_a_scan_writes_only_pages_of_its_marking_window(sim):
    from nbv_gym.mapping import MappingConfig, OccupancyMap

    map_grid = sim.config.mapping.map.grid()
    _, window = OccupancyMap.brick_counts(map_grid, MappingConfig().sensor_range_m)
    sim.reset(3)
    sim.occupancy.take_journal()
    for _ in range(4):
        sim.step(int(np.flatnonzero(sim.goal_mask())[-1]))
        assert 0 < sim.occupancy.take_journal().sum() <= np.prod(window)


def test_an_episode_estimated_above_the_memory_limit_is_refused_before_it_starts(monkeypatch):
    import nbv_gym.simulator as simulator

    world = simulator.load_world(WORLD)
    mapping = SimulatorConfig().mapping
    monkeypatch.setattr(simulator.Lidar, "for_world", None)  # no work past the check
    # two scans (a reset and one step) fit, the default 100 steps do not
    monkeypatch.setattr(
        simulator, "MAX_EPISODE_BYTES", simulator.episode_memory_bytes(world, mapping, 2)
    )
    with pytest.raises(
        simulator.EpisodeMemoryError,
        match=r"^an episode of 100 steps on world pp1-cuboids may need 0\.\d GiB, more than "
        r"the limit of 0\.\d+ GiB \(nbv_gym\.simulator\.MAX_EPISODE_BYTES\); lower "
        r"episode\.max_steps to 1 or less, or use a smaller placement window$",
    ):
        Simulator(SimulatorConfig(world=WORLD))
    monkeypatch.setattr(simulator, "MAX_EPISODE_BYTES", 300 << 20)  # not even the world
    with pytest.raises(simulator.EpisodeMemoryError, match=r"window or fewer assets$"):
        Simulator(SimulatorConfig(world=WORLD))
