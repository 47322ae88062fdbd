"""``evaluate --map MAP --ground-truth CLOUD``: the paper's Alg. 1 (both grids' bounding boxes
intersected, 1 m cuboids) scores an nbv-gym map, saved or exported as a cloud, exactly as
``evaluate --world`` does when the ground-truth cloud is the world's."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.cli.evaluate import evaluate_map
from nbv_gym.core.pointclouds import write_points
from nbv_gym.env import ExploreEnv
from nbv_gym.episode import run_episode
from nbv_gym.mapping.export import export_map
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.cuboids import benchmark_grid
from nbv_gym.metrics.evaluation import alg1_grid
from nbv_gym.policies import load_policy
from nbv_gym.worlds import load_world
from tests.helpers import run_cli

#: Eight cuboids within 10 m of the start: an episode's map knows every voxel around them.
NEAR_WORLD = """
name = "near"
[placement]
seed = 7
n_assets = 8
cluster_radius_m = 8.0
window_m = [-10.0, -10.0, 10.0, 10.0]
[assets]
mix = { cuboids = 1.0 }
"""


def test_alg1_grid_is_whole_benchmark_cuboids_over_the_boxes_intersection():
    box = np.array([[-50, -7, -10], [13, 400, 80]])  # voxels: x -5.0..1.4, y -0.7..40.1 m
    truth = np.array([[-100, 3, 5], [4, 250, 27]])  # x -10..0.5, y 0.3..25.1, z 0.5..2.8 m
    grid = alg1_grid(box, truth, 0.1, "map", "truth")
    # intersection x [-5.0, 0.5), y [0.3, 25.1), z [0.5, 2.8) m, on cuboids x, y ≡ 0 and
    # z ≡ 0.2 (mod 1 m): x -5..1, y 0..26, z 0.2..3.2
    assert grid.low == pytest.approx([-5.0, 0.0, 0.2])
    assert grid.high == pytest.approx([1.0, 26.0, 3.2])
    with pytest.raises(MetricInputError, match=r"map and truth do not overlap"):
        alg1_grid(box, truth + [0, 0, 200], 0.1, "map", "truth")


@pytest.fixture(scope="module")
def explored(tmp_path_factory):
    """An explore episode's map (saved and exported as a cloud of every known voxel) and the
    world's ground truth as the benchmark scores it (its voxels in G) as a cloud."""
    folder = tmp_path_factory.mktemp("alg1")
    spec = folder / "near.toml"
    spec.write_text(NEAR_WORLD)
    env = ExploreEnv(world=str(spec), noise=1)
    result = run_episode(env, load_policy("closest-frontier"), seed=0)
    env.sim.save(folder)
    export_map(env.sim.occupancy, folder / "map.ply", min_probability=0.0)
    grid = benchmark_grid()
    truth = load_world(spec).ground_truth.grid_voxels(grid)
    write_points(folder / "truth.ply", grid.centres(truth))
    return folder, str(spec), result.final["q"]


@pytest.mark.parametrize("map_name", ["map.npz", "map.ply"])
def test_a_map_scored_against_its_worlds_cloud_equals_scoring_against_the_world(explored, map_name):
    folder, spec, q = explored
    against_world = evaluate_map(folder / "map.npz", spec, None, None)
    against_cloud = evaluate_map(folder / map_name, None, folder / "truth.ply", None)
    assert against_world["q"] == pytest.approx(q, rel=1e-12)  # what the episode reported
    assert against_cloud.keys() == against_world.keys()
    for key, value in against_world.items():
        assert against_cloud[key] == pytest.approx(value, rel=1e-6, nan_ok=True), key


def test_evaluate_refuses_a_world_and_a_cloud_together_in_one_line(explored):
    folder, spec, _ = explored
    args = ["--map", "map.npz", "--ground-truth", "truth.ply", "--world", spec]
    result = run_cli("evaluate", *args, cwd=folder)
    lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert result.returncode == 2 and len(lines) == 1
    assert "give exactly one of --world NAME and --ground-truth" in lines[0]


def test_an_octomap_scores_as_its_maximum_likelihood_voxels(explored):
    """A .bt keeps each known voxel's state only, read back at the reading tree's clamping
    bounds (OctoMap's defaults: the format holds no parameters); scoring it equals scoring a PLY
    of the map's known voxels at those bounds, pruned leaves and all."""
    pyoctomap = pytest.importorskip("pyoctomap")
    from nbv_gym.mapping.export import map_voxels
    from nbv_gym.mapping.mapfile import load_map

    folder, _, _ = explored
    occupancy = load_map(folder / "map.npz")
    export_map(occupancy, folder / "map.bt")
    centres, probability = map_voxels(occupancy, 0.0)
    tree = pyoctomap.OcTree(0.1)
    high, low = tree.getClampingThresMax(), tree.getClampingThresMin()
    bound = np.where(probability > occupancy.params["p_occupied"], high, low)
    write_points(
        folder / "bounds.ply", centres, {"probability": bound.astype(np.float32)}, single=True
    )
    octomap = evaluate_map(folder / "map.bt", None, folder / "truth.ply", None)
    expected = evaluate_map(folder / "bounds.ply", None, folder / "truth.ply", None)
    for key, value in expected.items():
        assert octomap[key] == pytest.approx(value, rel=1e-5, nan_ok=True), key
