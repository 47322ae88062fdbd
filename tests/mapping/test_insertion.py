"""The store-order insertion kernel gives the maps of the ray-order kernel it replaced
(tests/mapping/reference_insertion.py), bit for bit in every output: the voxels, the block flags
and journal, the touched cells of G, the cell totals, the column counts and the navigation grid —
on scans of real episodes in a world of each asset type, with the OS1-64 preset, with rays whose
float walk veers off their endpoint's voxel, and with rays leaving the map."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.pose import Pose
from nbv_gym.mapping import ExplorationState, MappingConfig
from nbv_gym.mapping.navigation import NavigationLayer
from nbv_gym.mapping.statistics import ViewpointStatistics
from nbv_gym.mapping.tally import new_log
from nbv_gym.sensor.lidar import Scan
from nbv_gym.sensor.presets import lidar_config
from nbv_gym.simulator import Simulator, SimulatorConfig
from tests.mapping.reference_insertion import ReferenceMap, veering_rays

KINDS = ("cuboids", "crosses", "helicoids", "trees")
STEPS = 7  # a reset and 7 steps: 8 scans a world, 32 over the four
#: (sensor, return) pairs in metres, in the default map, whose walks veer off the return's
#: voxel (a coordinate on a voxel border, as on a face of a box aligned to the grid); found by
#: searching random rays with ``veering_rays``
VEERING = (
    ((1.369616873214543, -2.302132862361297, 0.41081947047872386),
     (12.100000000000001, 3.948358343242123, 0.6752751008080273)),
    ((-3.9755679374427655, 3.8628785764695746, 0.41757271418458053),
     (-2.8631962653271614, 16.2, -0.609779136869515)),
    ((4.85660700262123, 3.2937560312811627, 0.4121174111194805),
     (11.992624674333966, 7.5, 1.273568677477614)),
)  # fmt: skip


def world_spec(folder, kind: str):
    path = folder / f"{kind}.toml"
    path.write_text(
        f'name = "tiny-{kind}"\ndescription = "6 {kind} near the start"\n\n'
        "[placement]\nseed = 3\nn_assets = 6\ncluster_radius_m = 10.0\n\n"
        f"[assets]\nmix = {{ {kind} = 1.0 }}\n"
    )
    return path


def episode_scans(config: SimulatorConfig, steps: int) -> tuple[Simulator, list[list[Scan]]]:
    """The scans of episodes (a reset, then steps to random valid goals): ``steps`` steps in
    all, a new episode where one ends."""
    sim = Simulator(config)
    episodes = [[sim.reset(seed=5).scan]]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        if sim.ended:
            episodes.append([sim.reset(seed=len(episodes) + 5).scan])
        episodes[-1].append(sim.step(int(rng.choice(np.flatnonzero(sim.goal_mask())))).scan)
    return sim, episodes


def twin_states(config: SimulatorConfig) -> tuple[ExplorationState, ExplorationState]:
    """Two empty states as a simulator of ``config`` (fitted to its world) builds its own: one
    with the map's kernel, one with the reference kernel."""
    mapping, quality = config.mapping, config.quality
    band = (quality.unknown_low, quality.unknown_high)
    thresholds = tuple(p for p, _ in quality.cov_settings)
    ours = ExplorationState.from_config(mapping, band, thresholds)
    m = mapping.map
    occupancy = ReferenceMap(
        m.grid(), p_hit=m.p_hit, p_miss=m.p_miss, p_clamp_min=m.p_clamp_min,
        p_clamp_max=m.p_clamp_max, p_occupied=m.p_occupied, max_range_m=mapping.sensor_range_m,
    )  # fmt: skip
    statistics = ViewpointStatistics.from_config(mapping.statistics, mapping.sensor_range_m)
    navigation = NavigationLayer.from_config(mapping.navigation, statistics.grid)
    reference = ExplorationState(occupancy, statistics, navigation, band, thresholds)
    reference.update_navigation(np.zeros(2))
    return ours, reference


def assert_same(ours: ExplorationState, reference: ExplorationState, episodes) -> None:
    """Apply the scans of each episode to both states, cleared between episodes; after each
    scan, every output must be equal bit for bit."""
    for episode in episodes:
        ours.clear()
        reference.clear()
        for index, scan in enumerate(episode):
            assert_same_scan(ours, reference, scan, f"scan {index}")


def assert_same_scan(ours: ExplorationState, reference: ExplorationState, scan: Scan, where: str):
    """Apply ``scan`` to both states: every output equal bit for bit (``where`` names it)."""
    a, b = ours.apply(scan), reference.apply(scan)
    for name in ("n_points", "n_dropped", "n_occupied", "n_updated"):
        assert getattr(a, name) == getattr(b, name), f"{where}: {name}"
    for name in ("touched", "touched_cells", "columns"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=where)
    x, y = ours.occupancy, reference.occupancy
    np.testing.assert_array_equal(x._store.view(np.uint32), y._store.view(np.uint32), where)
    np.testing.assert_array_equal(x.written_blocks(), y.written_blocks(), err_msg=where)
    np.testing.assert_array_equal(x.take_journal(), y.take_journal(), err_msg=where)
    for name in ("sums", "outside", "crossed"):
        np.testing.assert_array_equal(
            getattr(ours.tally, name), getattr(reference.tally, name), err_msg=where
        )
    for name in ("known", "occupied", "distance"):
        np.testing.assert_array_equal(
            getattr(ours.navigation, name), getattr(reference.navigation, name), where
        )
    np.testing.assert_array_equal(ours.take_crossed(), reference.take_crossed(), where)


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_an_episode_inserts_as_the_reference_kernel_does(kind, tmp_path):
    config = SimulatorConfig(world=str(world_spec(tmp_path, kind)), noise=1)
    sim, episodes = episode_scans(config, STEPS)
    assert sum(map(len, episodes)) >= STEPS + 1
    assert_same(*twin_states(sim.config), episodes)


@pytest.mark.slow
def test_an_os1_64_episode_inserts_as_the_reference_kernel_does(tmp_path):
    spec = world_spec(tmp_path, "trees")
    sim, episodes = episode_scans(SimulatorConfig(world=str(spec), lidar=lidar_config("os1-64")), 2)
    assert min(len(scan) for scan in episodes[0]) > 20_000  # 64 × 1024 rays
    assert_same(*twin_states(sim.config), episodes)


def scan_of(origin, points) -> Scan:
    """A scan of map-frame ``points`` from the sensor at ``origin`` (metres)."""
    pose = Pose(*origin, 0.0)
    points = np.asarray(points, np.float64)
    return Scan(points, np.zeros(len(points)), np.zeros(len(points), np.int64), pose, pose, points)


def test_veering_walks_and_walks_leaving_the_map_insert_as_the_reference_kernel_does():
    config = MappingConfig()
    grid = config.map.grid()
    rng = np.random.default_rng(1)
    scans = []
    for origin, point in VEERING:
        # the veering return among others: near, far (beyond the range), twice in one voxel,
        # not finite
        near = np.asarray(point) + rng.normal(0.0, 2.0, (200, 3))
        points = np.vstack([[point], near, near[:5], [[np.nan, 0.0, 0.0], [0.0, np.inf, 1.0]]])
        scans.append(scan_of(origin, points))
        to_grid = (np.asarray(points[:1]) - grid.low) / grid.res
        veers = veering_rays((np.asarray(origin) - grid.low) / grid.res, to_grid,
                             config.sensor_range_m / grid.res)  # fmt: skip
        assert veers == 1
    # a sensor near the map's corner, rays leaving the box on every side (and its top and bottom)
    corner = grid.low + np.array([0.5, 0.5, 1.4])
    directions = rng.normal(size=(3000, 3))
    scans.append(scan_of(corner, corner + directions * rng.uniform(1, 40, (3000, 1))))
    ours, reference = twin_states(SimulatorConfig(mapping=config))
    for state in (ours, reference):  # a log too short for a scan's changes: the cells recounted
        state.tally.log = new_log(64, state.tally.sums.size)
    assert_same(ours, reference, [scans])
