"""Point-cloud scene worlds: occupied voxels from the points, a surface the lidar hits only in
them, every format the same world, and a cloud sampled from a procedural world's surfaces
exploring like the procedural world itself."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nbv_gym.core.pointclouds import write_points
from nbv_gym.core.pose import LocalisationNoise, Pose
from nbv_gym.env import ExploreEnv
from nbv_gym.episode import run_episode
from nbv_gym.policies import load_policy
from nbv_gym.sensor.lidar import Lidar, LidarConfig
from nbv_gym.worlds import load_world, surface_voxels
from nbv_gym.worlds.scenes import clouds
from nbv_gym.worlds.scenes.clouds import INSET, exposed_faces
from nbv_gym.worlds.scenes.files import SceneFileError
from tests.helpers import write_tiny_world

RES = 0.1


def blob(seed: int = 0) -> np.ndarray:
    """A random lump of voxels with interior ones (k, 3), sorted and unique."""
    rng = np.random.default_rng(seed)
    voxels = rng.integers(0, 5, size=(200, 3))
    return np.unique(voxels, axis=0)


def test_one_voxel_has_six_faces_set_back_inside_it():
    vertices, faces = exposed_faces(np.array([[2, -3, 5]]), RES)
    assert faces.shape == (12, 3)
    low, high = np.array([2, -3, 5]) * RES, np.array([3, -2, 6]) * RES
    assert np.all(vertices >= low - 1e-12) and np.all(vertices <= high + 1e-12)
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    assert mesh.is_volume is False  # crossing planes, not a closed box
    planes = np.unique(np.round(mesh.triangles_center, 9)[:, :], axis=0)
    assert len(planes) == 12
    offsets = sorted({round(float(v), 9) for v in vertices[:, 0]})
    assert offsets == [round(2 * RES, 9), round((2 + INSET) * RES, 9),
                       round((3 - INSET) * RES, 9), round(3 * RES, 9)]  # fmt: skip


def test_the_surface_voxelises_back_to_the_voxels_with_an_empty_neighbour():
    voxels = blob()
    codes = {tuple(v) for v in voxels.tolist()}
    steps = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    outer = {v for v in codes if any(tuple(np.add(v, s)) not in codes for s in steps)}
    assert len(outer) < len(codes)  # the blob has interior voxels, which get no face
    vertices, faces = exposed_faces(voxels, RES)
    # each face spans its voxel's whole side, edges on the boundaries with the next voxels:
    # shrunk by a hair towards its centre, it lies in its own voxel and meets no other
    corners = vertices.reshape(-1, 4, 3)
    centres = corners.mean(axis=1, keepdims=True)
    inside = (centres + (1 - 1e-6) * (corners - centres)).reshape(-1, 3)
    back = surface_voxels(inside, faces, RES).voxels
    assert {tuple(v) for v in back.tolist()} == outer
    exposed = sum(tuple(np.add(v, s)) not in codes for v in codes for s in steps)
    assert len(faces) == 2 * exposed


def write_blob_cloud(folder, suffix: str) -> str:
    """Points at the centres of :func:`blob`'s voxels (moved 3 m from the start) and jittered
    inside them, as ``cloud<suffix>``, and its spec."""
    rng = np.random.default_rng(1)
    centres = (blob() + [30, 30, 0] + 0.5) * RES
    points = np.repeat(centres, 4, axis=0) + rng.uniform(-0.04, 0.04, (4 * len(centres), 3))
    points = np.vstack([points, [[-30 * RES, -30 * RES, 0.01]]])  # a far point: a 6 m scene
    if suffix in (".las", ".laz"):
        laspy = pytest.importorskip("laspy")
        header = laspy.LasHeader(point_format=3, version="1.2")
        header.scales, header.offsets = np.array([1e-4] * 3), np.zeros(3)
        data = laspy.LasData(header)
        data.x, data.y, data.z = points.T
        data.write(str(folder / f"cloud{suffix}"))
    else:
        write_points(folder / f"cloud{suffix}", points)
    spec = folder / f"cloud{suffix}.toml"
    spec.write_text(f'name = "blob"\n[scene]\nfile = "cloud{suffix}"\nstart_m = [0.0, 0.0]\n')
    return str(spec)


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".xyz", ".las", ".laz"])
def test_every_cloud_format_gives_the_voxels_of_its_points(tmp_path, suffix):
    world = load_world(write_blob_cloud(tmp_path, suffix), cache=False)
    expected = blob() + [30, 30, 0]
    truth = world.ground_truth.voxels
    assert world.spec.scene.kind == "cloud"
    assert {tuple(v) for v in truth.tolist()} == {tuple(v) for v in expected.tolist()} | {
        (-30, -30, 0)
    }


def test_the_lidar_hits_a_cloud_world_only_in_its_occupied_voxels(tmp_path):
    world = load_world(write_blob_cloud(tmp_path, ".ply"), cache=False)
    config = LidarConfig(n_channels=64, n_azimuth=2048, range_noise=None)
    lidar = Lidar.for_world(world, config, LocalisationNoise.level(0))
    scan = lidar.scan(Pose(0.0, 0.0, 0.0, 0.0), np.random.default_rng(0))
    above = scan.points_map[scan.points_map[:, 2] > 1e-6]  # the added ground plane aside
    assert len(above) > 500
    hit = {tuple(v) for v in np.floor(above / RES).astype(int).tolist()}
    assert hit <= {tuple(v) for v in world.ground_truth.voxels.tolist()}


def test_a_cloud_sampled_from_a_procedural_world_explores_like_it(tmp_path):
    """The tiny procedural world's asset surfaces (bases on the ground left out) sampled every
    ≤ 3 cm: 98.6 % of its ground-truth voxels are found, and closest-frontier's budget episodes
    (12 scans, seeds 0–2) end within 0.005 of its Q and 0.03 of its discovered fraction on
    average; the first scan (same pose, same noise) within 8 % of its Q."""
    spec = write_tiny_world(tmp_path)
    procedural = load_world(spec)
    vertices = procedural.vertices.astype(np.float64)
    faces = procedural.faces[: procedural.asset_faces]
    faces = faces[np.abs(vertices[faces][:, :, 2]).max(axis=1) > 1e-9]  # no base on the ground
    dense, tris = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=0.03)
    points = np.vstack([dense, dense[tris].mean(axis=1)])
    points = points[np.all(np.abs(points[:, :2]) < 30, axis=1)]  # the benchmark window
    write_points(tmp_path / "cloud.ply", points)
    (tmp_path / "cloud.toml").write_text(
        'name = "tiny-cloud"\n[scene]\nfile = "cloud.ply"\nstart_m = [0.0, 0.0]\n'
    )
    cloud = load_world(str(tmp_path / "cloud.toml"))
    truth = {tuple(v) for v in procedural.ground_truth.voxels.tolist()}
    found = {tuple(v) for v in cloud.ground_truth.voxels.tolist()}
    assert len(found & truth) / len(truth) > 0.98 and len(found - truth) / len(truth) < 0.002
    results = {}
    for name, world in (("procedural", spec), ("cloud", str(tmp_path / "cloud.toml"))):
        runs = []
        for seed in range(3):
            env = ExploreEnv(world=world, noise=1, task="budget")
            first = env.reset(seed=seed)[1]["q"]
            final = run_episode(env, load_policy("closest-frontier"), seed=seed).final
            runs.append((first, final["q"], final["discovered"]))
        results[name] = np.mean(runs, axis=0)
    (first_p, q_p, disc_p), (first_c, q_c, disc_c) = results["procedural"], results["cloud"]
    assert first_c == pytest.approx(first_p, rel=0.08)
    assert abs(q_c - q_p) < 0.005 and abs(disc_c - disc_p) < 0.03


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "the point cloud is empty"),
        ("0 0 0\nnan 1 1\n5 5 1\n", "holds NaN or infinite coordinates"),
        ("0 0 0\n1e6 0 0\n", "1e+06 m across at scale = 1"),
    ],
    ids=["empty", "nan", "too wide"],
)
def test_a_bad_cloud_is_refused_in_one_line(tmp_path, content, message):
    (tmp_path / "c.xyz").write_text(content)
    (tmp_path / "c.toml").write_text('name = "c"\n[scene]\nfile = "c.xyz"\n')
    with pytest.raises(SceneFileError, match=message.replace("+", r"\+")):
        load_world(str(tmp_path / "c.toml"), cache=False)


def test_a_cloud_over_the_point_bound_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(clouds, "MAX_POINTS", 100)
    write_points(tmp_path / "c.ply", np.random.default_rng(0).uniform(0, 10, (101, 3)))
    (tmp_path / "c.toml").write_text('name = "c"\n[scene]\nfile = "c.ply"\n')
    with pytest.raises(SceneFileError, match="101 points, more than 100; thin the cloud first"):
        load_world(str(tmp_path / "c.toml"), cache=False)
