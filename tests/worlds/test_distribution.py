"""World distributions ``random:…``: seeded draws, seeds disjoint from the benchmark, a bounded
pool in the cache, one simulator reused across worlds."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import astuple

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.core.grid import GridSpec
from nbv_gym.core.protocol import RESOLUTION_M
from nbv_gym.env import ExploreEnv
from nbv_gym.metrics.tracker import QualityTracker
from nbv_gym.simulator import Simulator
from nbv_gym.worlds import ASSET_TYPES, benchmark_names, cache_dir, load_spec
from nbv_gym.worlds.distribution import (
    FIRST_SEED,
    WIDE_POOL_SIZE,
    WorldDistribution,
    distribution_names,
    is_distribution,
)
from nbv_gym.worlds.groundtruth import surface_voxels

POOL = 4


def first_scan(env: ExploreEnv, seed: int) -> tuple[str, str]:
    """The world drawn by ``reset(seed)`` and a digest of the first observation."""
    observation, info = env.reset(seed=seed)
    digest = np.concatenate([observation[k] for k in sorted(observation)]).tobytes().hex()
    return info["world"], digest


def test_placement_seeds_are_disjoint_from_the_benchmark_worlds():
    benchmark = {load_spec(name).placement.seed for name in benchmark_names()}
    assert max(benchmark) < FIRST_SEED
    pool = WorldDistribution("mixed", pool_size=1000)
    seeds = {pool.spec(k).placement.seed for k in range(pool.pool_size)}
    assert len(seeds) == 1000 and not seeds & benchmark


def test_names_and_asset_mixes():
    assert distribution_names() == [f"random:{k}" for k in (*ASSET_TYPES, "mixed", "wide")]
    assert is_distribution("random:trees") and not is_distribution("pp1-trees")
    assert WorldDistribution("trees").spec(3).assets.mix == {"trees": 1.0}
    assert set(WorldDistribution("mixed").spec(0).assets.mix) == set(ASSET_TYPES)
    mixed = WorldDistribution("mixed", POOL).world(0)
    assert len(set(mixed.layout.kind.tolist())) == len(ASSET_TYPES)


def test_the_wide_pool_draws_its_numbers_per_world_and_its_worlds_have_names():
    wide = WorldDistribution("wide", WIDE_POOL_SIZE)
    specs = [wide.spec(k) for k in range(WIDE_POOL_SIZE)]
    assert WIDE_POOL_SIZE >= 256 and len({s.digest() for s in specs}) == WIDE_POOL_SIZE
    assert len({s.placement.n_assets for s in specs}) > 50  # density varies world to world
    assert len({tuple(s.assets.mix) for s in specs}) == 15  # every type and mix of types
    assert load_spec("random:wide/7") == specs[7] and specs[7].name == "random-wide-0007"
    heldout = load_spec("random:wide/heldout-7")
    assert heldout.name == "random-wide-heldout-0007" and heldout.digest() != specs[7].digest()
    assert load_spec("random:mixed/3") == WorldDistribution("mixed").spec(3)
    assert not is_distribution("random:wide/3") and is_distribution("random:wide")


def test_a_pool_world_runs_by_name_on_the_agents_goal_grid():
    """A world of random:wide with a window smaller than 60 m keeps the 60 × 60 goals a
    trained agent acts on (larger windows would grow them: the recipe stays within 60 m)."""
    spec = load_spec("random:wide/26")
    assert spec.placement.window_m[2] - spec.placement.window_m[0] < 60
    env = ExploreEnv(world="random:wide/26", max_steps=2)
    _, info = env.reset(seed=0)
    assert info["world"] == spec.name and env.sim.n_goals == 60 * 60


def test_bad_pool_world_names_are_refused_in_one_line():
    with pytest.raises(UnknownNameError, match="Did you mean 'random:wide'"):
        load_spec("random:wdie/3")
    with pytest.raises(ConfigError, match="the index must be below 100000"):
        load_spec("random:wide/heldout-100000")
    for name in ("random:wide/x3", "random:wide/-1", "random:wide/heldout--1", "random:wide/",
                 "random:wide/heldout-", "random:wide/1e3", "random:wide/\uff10", "random:wide/0/1"):  # fmt: skip
        with pytest.raises(
            ConfigError, match=r"is no pool world; a pool's world is random:<kind>/<k> or"
        ):
            load_spec(name)
    with pytest.raises(ConfigError, match="world_pool_size: must be from 1 to 100000"):
        WorldDistribution("wide", 100_001)


def test_a_distribution_where_one_world_is_needed_names_its_worlds():
    with pytest.raises(ConfigError, match=r"'random:wide' is a distribution, not one world; give"):
        load_spec("random:wide")


def test_unknown_distribution_suggests_the_near_miss():
    with pytest.raises(UnknownNameError, match="Did you mean 'random:trees'"):
        ExploreEnv(world="random:tree")
    with pytest.raises(ConfigError, match="world_pool_size: must be ≥ 1"):
        ExploreEnv(world="random:cuboids", world_pool_size=0)


def test_resets_draw_seeded_worlds_from_a_bounded_pool(tmp_path, monkeypatch):
    monkeypatch.setenv("NBV_GYM_CACHE", str(tmp_path))  # other workers cache other pool members
    env = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2)
    drawn = {seed: first_scan(env, seed) for seed in range(8)}
    worlds = {world for world, _ in drawn.values()}
    assert len(worlds) > 1 and worlds <= {f"random-cuboids-{k:04d}" for k in range(POOL)}
    assert first_scan(env, 3) == drawn[3]  # same seed, same world and episode
    different = [s for s in drawn if drawn[s][0] != drawn[0][0]]
    assert different and drawn[different[0]][1] != drawn[0][1]
    cached = list((cache_dir() / "worlds").glob("random-cuboids-*.npz"))
    assert len(cached) <= POOL


def test_episodes_per_world_draws_every_kth_reset():
    every = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2)
    third = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2,
                       episodes_per_world=3)  # fmt: skip
    drawn = [every.reset(seed=s)[1]["world"] for s in (5, 6)]
    kept = [third.reset(seed=s)[1]["world"] for s in (5, 6, 7, 6, 8, 9)]
    assert kept[:3] == [drawn[0]] * 3  # the first reset draws as usual, the next two keep it
    assert kept[3] == drawn[1] and kept[3:] == [kept[3]] * 3  # the 4th draws (seed 6) again
    with pytest.raises(ConfigError, match="episodes_per_world"):
        ExploreEnv(world="random:cuboids", episodes_per_world=0)


def test_same_seed_draws_the_same_world_in_another_process():
    code = (
        "import sys; sys.path.insert(0, 'tests/worlds');"
        "from test_distribution import first_scan, POOL; from nbv_gym.env import ExploreEnv;"
        "env = ExploreEnv(world='random:cuboids', world_pool_size=POOL, max_steps=2);"
        "print(*first_scan(env, 5))"
    )
    there = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.split()
    env = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2)
    assert tuple(there) == first_scan(env, 5)


def test_a_switched_simulator_equals_a_fresh_one():
    """After several world switches an episode is the one a new environment runs."""
    used = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2)
    for seed in range(4):
        used.reset(seed=seed)
    simulator = used.sim
    fresh = ExploreEnv(world="random:cuboids", world_pool_size=POOL, max_steps=2)
    assert first_scan(used, 6) == first_scan(fresh, 6)
    assert used.sim is simulator  # one simulator for every world


RSS_CODE = """
import numpy as np
from nbv_gym.env import ExploreEnv

def rss_mib():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024

env = ExploreEnv(world="random:cuboids", world_pool_size=8, max_steps=3)
worlds, seed, rss = [], 0, []
while len(set(worlds)) < 5:
    observation, info = env.reset(seed=seed)
    seed += 1
    if info["world"] in worlds:
        continue
    worlds.append(info["world"])
    for _ in range(2):
        observation, *_, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
    rss.append(rss_mib())
print(rss[0], rss[-1])
"""


def test_memory_stays_flat_across_worlds():
    """One environment over five worlds grows by less than one world's scene and ground truth
    (the old world-cycling training env kept a full environment per world)."""
    first, last = map(
        float,
        subprocess.run(
            [sys.executable, "-c", RSS_CODE], capture_output=True, text=True, check=True
        ).stdout.split(),
    )
    assert last - first < 64, f"RSS grew from {first:.0f} to {last:.0f} MiB over 5 worlds"


def episode(simulator: Simulator, seed: int, steps: int = 3) -> list:
    """Scan ranges, touched cells, reward and quality of a reset and ``steps`` first-valid steps."""
    outcomes = [simulator.reset(seed)]
    for _ in range(steps):
        outcomes.append(simulator.step(int(np.flatnonzero(simulator.goal_mask())[0])))
    return [(o.scan.ranges.tobytes(), o.touched.tobytes(), o.reward, o.quality) for o in outcomes]


def test_switching_back_to_a_world_gives_a_fresh_simulators_episode():
    pool = WorldDistribution("cuboids", POOL)
    simulator = Simulator(world=pool.world(0))
    simulator.set_world(pool.world(1))
    episode(simulator, seed=7)
    simulator.set_world(pool.world(0))
    np.testing.assert_equal(episode(simulator, 3), episode(Simulator(world=pool.world(0)), 3))


def test_a_simulators_ground_truth_is_the_freshly_voxelised_worlds():
    """The cached world's ground truth, and the quality lists the simulator derives from it at
    the map's voxels, equal those of a fresh voxelisation of the world's mesh."""
    world = WorldDistribution("cuboids", POOL).world(1)
    fresh = surface_voxels(world.vertices, world.faces[: world.asset_faces], RESOLUTION_M)
    np.testing.assert_array_equal(world.ground_truth.voxels, fresh.voxels)
    simulator = Simulator(world=world)
    dense = QualityTracker(fresh.occupancy(simulator.voxel_grid), simulator.quality.config)
    np.testing.assert_array_equal(simulator.quality.u_occ, dense.u_occ)
    np.testing.assert_array_equal(simulator.quality.volume, dense.volume)
    touched = np.flatnonzero(dense.u_occ)[::7]
    blocks = np.random.default_rng(0).choice(
        np.float32([0.12, 0.5, 0.9]), (len(touched), 10, 10, 10)
    )
    np.testing.assert_equal(
        astuple(simulator.quality.update_blocks(touched, blocks)),
        astuple(dense.update_blocks(touched, blocks)),
    )
    shifted = GridSpec((-3.0, 2.0, 0.0), RESOLUTION_M, (40, 30, 20))  # another grid
    np.testing.assert_array_equal(
        world.ground_truth.grid_voxels(shifted), np.argwhere(fresh.occupancy(shifted))
    )
