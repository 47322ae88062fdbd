"""``evaluate`` on maps of scene worlds: the map is in the world's frame, so a cloud in the scene
file's frame is moved into it as the world's own ground truth was; ``--world`` scores a world
larger than the benchmark's 60 m over its whole extent, as its run did; and the grid scored is
bounded before anything is allocated."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.cli.evaluate import evaluate_map
from nbv_gym.core.pointclouds import write_points
from nbv_gym.env import ExploreEnv
from nbv_gym.mapping.export import export_map
from nbv_gym.mapping.mapfile import recorded_frame
from nbv_gym.metrics import MetricInputError
from nbv_gym.metrics.evaluation import MAX_GRID_VOXELS, _truth_voxels
from nbv_gym.worlds import shapes
from tests.helpers import box_mesh

#: Where the scan lies in its file: far from the origin, 20 m up.
OFFSET = np.array([100.0, 50.0, 20.0])


def explore(spec: str, folder, steps: int = 2) -> float:
    """Save the map of a ``steps``-scan episode on ``spec`` into ``folder``; its final Q."""
    env = ExploreEnv(world=spec, noise=1, max_steps=steps)
    _, info = env.reset(seed=0)
    for _ in range(steps - 1):
        mask = info["action_mask"]
        *_, info = env.step(int(np.flatnonzero(mask)[len(np.flatnonzero(mask)) // 2]))
    env.sim.save(folder)
    export_map(env.sim.occupancy, folder / "map.ply", min_probability=0.0)
    return info["q"]


@pytest.fixture(scope="module")
def scan_world(tmp_path_factory):
    """A cloud world of a scan lying at :data:`OFFSET` in its file, explored."""
    folder = tmp_path_factory.mktemp("scan")
    rng = np.random.default_rng(0)
    points = np.vstack([rng.uniform([-8, -1, 0], [-5, 1, 3], (3000, 3)),
                        rng.uniform([5, -1, 0], [8, 1, 3], (3000, 3)),
                        rng.uniform([-10, -10, 0], [10, 10, 0.05], (3000, 3))]) + OFFSET  # fmt: skip
    np.savetxt(folder / "scan.xyz", points, fmt="%.4f")
    (folder / "scan.toml").write_text('name = "scan"\n[scene]\nfile = "scan.xyz"\n')
    explore(str(folder / "scan.toml"), folder)
    return folder


def test_a_map_records_its_scene_worlds_frame(scan_world):
    frame = recorded_frame(scan_world / "map.npz")
    assert frame["scale"] == 1.0 and frame["up"] == "z"
    assert frame["offset_m"][2] == pytest.approx(OFFSET[2], abs=1e-3)
    assert np.abs(np.asarray(frame["offset_m"][:2]) - OFFSET[:2]).max() < 3.0  # near the centre


def test_the_scan_file_moved_into_the_world_frame_is_the_worlds_ground_truth(scan_world):
    from nbv_gym.worlds import load_world

    truth = _truth_voxels(scan_world / "scan.xyz", 0.1, recorded_frame(scan_world / "map.npz"))
    world = load_world(str(scan_world / "scan.toml"))
    assert {tuple(v) for v in truth.tolist()} == {
        tuple(v) for v in world.ground_truth.voxels.tolist()
    }


def test_a_map_scored_against_its_scan_file_equals_both_in_the_world_frame(scan_world):
    """V03/V02 of the fourth round: the scan as the file holds it scores the map as the
    world-frame scan scores the map's world-frame export (a .ply records no frame)."""
    from nbv_gym.worlds import load_world

    world = load_world(str(scan_world / "scan.toml"))
    write_points(scan_world / "truth.ply", world.ground_truth.points())
    in_file = evaluate_map(scan_world / "map.npz", None, scan_world / "scan.xyz", None)
    in_world = evaluate_map(scan_world / "map.ply", None, scan_world / "truth.ply", None)
    assert in_file["q"] > 0.01
    for key, value in in_world.items():
        assert in_file[key] == pytest.approx(value, rel=1e-6, nan_ok=True), key


def test_a_world_larger_than_60_m_is_scored_over_its_whole_extent_as_its_run(tmp_path):
    """V11 of the fourth round: boxes 90 m apart, the goal grid fitted past 60 m."""
    import trimesh

    far = [(-901, -861, -19, 21, 41), (861, 901, -19, 21, 41), (61, 101, -39, 1, 41),
           (-143, -101, 43, 81, 59), (-41, 39, -181, -141, 21)]  # fmt: skip
    vertices, faces = shapes.concatenate([box_mesh(box) for box in far])
    trimesh.Trimesh(vertices, faces).export(tmp_path / "far.obj")
    (tmp_path / "far.toml").write_text(
        'name = "far"\n[scene]\nfile = "far.obj"\nstart_m = [0.0, 0.0]\n'
    )
    q = explore(str(tmp_path / "far.toml"), tmp_path)
    summary = evaluate_map(tmp_path / "map.npz", str(tmp_path / "far.toml"), None, None)
    assert summary["q"] == pytest.approx(q, rel=1e-12) and q > 0


def test_a_grid_beyond_the_bound_is_refused_before_allocating(tmp_path):
    """V09 of the fourth round: two known voxels and two scan points 10 km apart."""
    centres = np.array([[0.05, 0.05, 0.25], [10000.05, 10000.05, 0.25]])
    write_points(tmp_path / "map.ply", centres, {"probability": np.full(2, 0.9, np.float32)})
    np.savetxt(tmp_path / "scan.xyz", centres - [0, 0, 0.0], fmt="%.2f")
    with pytest.raises(MetricInputError, match=f"more than the limit of {MAX_GRID_VOXELS:,}"):
        evaluate_map(tmp_path / "map.ply", None, tmp_path / "scan.xyz", None)
