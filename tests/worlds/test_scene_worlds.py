"""Mesh scene worlds: the files the tests write (boxes and a cylinder as OBJ and GLB) give the
ground truth of an independent, exact voxelisation; units, axes, start, window and identity."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import RESOLUTION_M
from nbv_gym.worlds import load_spec, load_world, shapes, surface_voxels
from nbv_gym.worlds.world import cache_path
from tests.helpers import box_mesh, box_surface_voxels

#: Axis-aligned boxes in units of 5 cm, (x0, x1, y0, y1, z1), standing on z = 0: odd numbers
#: put faces midway between voxel boundaries, even ones on them (the last two boxes: on the
#: whole and the half metre).
BOXES = [(61, 101, -39, 1, 41), (-143, -101, 43, 81, 59), (-41, 39, -181, -141, 21),
         (120, 160, 100, 140, 40), (-170, -150, -110, -90, 50)]  # fmt: skip
#: Centre (x, y), radius, height, sides; no vertex on a voxel boundary.
CYLINDER = ((3.02, 7.03), 0.76, 2.45, 24)


def cylinder_mesh():
    (cx, cy), radius, height, sides = CYLINDER
    vertices, faces = shapes.prism(shapes.regular_polygon(sides, radius), height)
    return vertices + [cx, cy, 0.0], faces


def scene(up: str = "z", scale: float = 1.0):
    """The primitives as one trimesh, in file units (``scale`` metres) with ``up`` as up."""
    vertices, faces = shapes.concatenate([*map(box_mesh, BOXES), cylinder_mesh()])
    vertices = vertices.astype(np.float32).astype(np.float64) / scale  # exact in every format
    if up == "y":
        vertices = np.column_stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]])
    return trimesh.Trimesh(vertices, faces, process=False)


def write_spec(folder, mesh_name, **scene_keys) -> str:
    keys = {"file": mesh_name, "start_m": [0.0, 0.0], **scene_keys}
    lines = [f"{k} = {v!r}".replace("'", '"') for k, v in keys.items()]
    path = folder / f"{mesh_name}.toml"
    path.write_text('name = "primitives"\n[scene]\n' + "\n".join(lines) + "\n")
    return str(path)


@pytest.mark.parametrize("suffix", [".obj", ".glb", ".ply", ".stl", ".off"])
def test_a_mesh_file_of_primitives_gives_the_analytic_ground_truth(tmp_path, suffix):
    scene().export(tmp_path / f"primitives{suffix}")
    world = load_world(write_spec(tmp_path, f"primitives{suffix}"), cache=False)
    voxels = {tuple(v) for v in world.ground_truth.voxels.tolist()}
    boxes = set().union(*map(box_surface_voxels, BOXES))
    cylinder = surface_voxels(*cylinder_mesh(), RESOLUTION_M).voxels
    assert voxels == boxes | {tuple(v) for v in cylinder.tolist()}
    assert world.frame.offset_m == (0.0, 0.0, 0.0)


def test_y_up_and_millimetres_give_the_same_world(tmp_path):
    scene().export(tmp_path / "z.obj")
    scene(up="y", scale=0.001).export(tmp_path / "y.glb")
    plain = load_world(write_spec(tmp_path, "z.obj"), cache=False)
    turned = load_world(write_spec(tmp_path, "y.glb", up="y", scale=0.001), cache=False)
    assert np.array_equal(plain.ground_truth.voxels, turned.ground_truth.voxels)
    assert turned.frame == plain.frame


def test_a_small_scene_stands_in_the_benchmarks_window_and_ground(tmp_path):
    scene().export(tmp_path / "s.obj")
    world = load_world(write_spec(tmp_path, "s.obj"), cache=False)
    (cx, cy), radius = CYLINDER[:2]
    xs = [v * 0.05 for b in BOXES for v in b[:2]] + [cx + radius, cx - radius]
    ys = [v * 0.05 for b in BOXES for v in b[2:4]] + [cy + radius, cy - radius]
    assert world.window_m == (-30.0, -30.0, 30.0, 30.0)  # the smallest: the benchmark's
    assert -30 < min(xs) and max(xs) < 30 and -30 < min(ys) and max(ys) < 30
    assert world.ground_bounds_xy == ((-32.0, -32.0), (32.0, 32.0))
    ground = world.vertices[world.faces[world.asset_faces :]].reshape(-1, 3)
    assert np.all(ground[:, 2] == 0.0) and len(world.faces) == world.asset_faces + 2


def test_a_free_start_is_chosen_and_the_world_moves_to_it(tmp_path):
    """Without start_m the start is the free point nearest the footprint's centre; the world
    frame puts it at the origin, so the ground truth is the file's shifted by whole voxels."""
    scene().export(tmp_path / "s.obj")
    given = load_world(write_spec(tmp_path, "s.obj"), cache=False)
    spec = tmp_path / "auto.toml"
    spec.write_text('name = "auto"\n[scene]\nfile = "s.obj"\n')
    world = load_world(str(spec), cache=False)
    shift = np.rint(np.asarray(world.frame.offset_m) / RESOLUTION_M).astype(int)
    assert np.array_equal(world.ground_truth.voxels + shift, given.ground_truth.voxels)
    centres = world.ground_truth.points()
    low = centres[(centres[:, 2] > 0.3) & (centres[:, 2] < 3.0)]
    assert np.hypot(low[:, 0], low[:, 1]).min() >= 2.0  # clear_radius_m around the start


def test_a_start_next_to_an_obstacle_is_refused_naming_the_key(tmp_path):
    scene().export(tmp_path / "s.obj")
    with pytest.raises(ConfigError, match=r"scene\.start_m \[3\.0, 5\.6\]: .*clear_radius_m"):
        load_world(write_spec(tmp_path, "s.obj", start_m=[3.0, 5.6]), cache=False)


def test_the_files_content_is_the_worlds_identity_not_its_path(tmp_path):
    scene().export(tmp_path / "a.obj")
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "a.obj").write_bytes((tmp_path / "a.obj").read_bytes())
    here, moved = (
        load_spec(write_spec(tmp_path, "a.obj")),
        load_spec(write_spec(tmp_path / "b", "a.obj")),
    )
    assert here.digest() == moved.digest() and cache_path(here) == cache_path(moved)
    with (tmp_path / "b" / "a.obj").open("a") as handle:
        handle.write("v 0 0 0\n")
    assert load_spec(write_spec(tmp_path / "b", "a.obj")).digest() != here.digest()


def test_a_pinned_hash_refuses_a_changed_file(tmp_path):
    scene().export(tmp_path / "a.obj")
    pinned = load_spec(write_spec(tmp_path, "a.obj")).scene.sha256
    path = write_spec(tmp_path, "a.obj", sha256=pinned)
    assert load_spec(path).scene.sha256 == pinned
    with (tmp_path / "a.obj").open("a") as handle:
        handle.write("# edited\n")
    with pytest.raises(ConfigError, match=r"scene\.sha256: .* has changed since"):
        load_spec(path)


def test_a_scene_world_is_cached_and_read_back_equal(tmp_path):
    scene().export(tmp_path / "a.obj")
    spec = load_spec(write_spec(tmp_path, "a.obj"))
    built, read = load_world(spec), load_world(spec)
    assert cache_path(spec).is_file()
    assert np.array_equal(built.ground_truth.voxels, read.ground_truth.voxels)
    assert read.frame == built.frame and read.window_m == built.window_m


def test_the_environment_explores_a_scene_world_with_its_goal_grid_fitted(tmp_path):
    """Two boxes 90 m apart: the goal grid grows past the default 60 m to hold the scene."""
    from nbv_gym.env import ExploreEnv

    far = [(-901, -861, -19, 21, 41), (861, 901, -19, 21, 41), *BOXES]
    vertices, faces = shapes.concatenate([box_mesh(box) for box in far])
    trimesh.Trimesh(vertices, faces).export(tmp_path / "far.obj")
    env = ExploreEnv(world=write_spec(tmp_path, "far.obj"), max_steps=2)
    _, info = env.reset(seed=0)
    grid = env.sim.goal_grid
    world = env.sim.world
    assert world.window_m[0] == pytest.approx(-45.05) and world.window_m[2] == pytest.approx(45.05)
    assert world.window_m[1] == -30.0 and world.window_m[3] == 30.0
    assert grid.low[0] <= -45.05 and grid.high[0] >= 45.05 and grid.shape[0] > 60
    *_, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
    assert info["world"] == "primitives" and info["discovered"] > 0 and info["q"] > 0


def write_ply(path, vertices, faces, kind: str = "double", extra: str = "") -> None:
    """An ASCII PLY mesh with ``kind`` (float or double) coordinates and, after the vertices,
    ``extra`` vertex lines that no face uses."""
    rows = [" ".join(map(repr, v)) for v in np.asarray(vertices).tolist()]
    unused = [line for line in extra.splitlines() if line.strip()]
    head = ["ply", "format ascii 1.0", f"element vertex {len(rows) + len(unused)}"]
    head += [f"property {kind} {axis}" for axis in "xyz"]
    head += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    body = rows + unused + [f"3 {a} {b} {c}" for a, b, c in np.asarray(faces).tolist()]
    path.write_text("\n".join(head + body) + "\n")


@pytest.mark.parametrize(
    ("shift", "kind"),
    [
        ((0.0, 0.0, 0.03), "double"),
        ((500_000.0, 5_000_000.0, 200.03), "double"),
        ((0.0, 0.0, 0.03), "float"),
    ],
    ids=["lifted", "utm", "float32"],
)
def test_a_scene_moved_by_whole_voxels_or_in_float32_has_the_same_ground_truth(
    tmp_path, shift, kind
):
    """Boxes with faces on the voxel lattice and between its planes: lifted, moved to UTM-like
    coordinates or written in float32, their world is the same — faces on the lattice occupy
    the voxels on their upper side whatever the last bits of the coordinates."""
    vertices, faces = shapes.concatenate([box_mesh(box) for box in BOXES])
    write_ply(tmp_path / "s.ply", vertices + shift, faces, kind)
    start = [shift[0], shift[1]]
    world = load_world(write_spec(tmp_path, "s.ply", start_m=start), cache=False)
    voxels = {tuple(v) for v in world.ground_truth.voxels.tolist()}
    assert voxels == set().union(*map(box_surface_voxels, BOXES))


@pytest.mark.parametrize("unused", ["1000000.0 1000000.0 0.0", "nan nan 0.0"])
def test_a_vertex_no_face_uses_is_no_part_of_the_scene(tmp_path, unused):
    vertices, faces = shapes.concatenate([box_mesh(box) for box in BOXES])
    write_ply(tmp_path / "s.ply", vertices, faces, extra=unused)
    write_ply(tmp_path / "plain.ply", vertices, faces)
    world = load_world(write_spec(tmp_path, "s.ply"), cache=False)
    plain = load_world(write_spec(tmp_path, "plain.ply"), cache=False)
    assert np.array_equal(world.vertices, plain.vertices) and world.frame == plain.frame
    assert np.array_equal(world.ground_truth.voxels, plain.ground_truth.voxels)


def test_a_scene_without_ground_truth_is_refused_in_one_line(tmp_path):
    """Triangles in one plane (the ground, once lifted) or of no area make no ground truth."""
    from nbv_gym.worlds.scenes.files import SceneFileError

    flat = np.array([[0.0, 0.0, 1.0], [10.0, 0.0, 1.0], [10.0, 10.0, 1.0], [0.0, 10.0, 1.0]])
    write_ply(tmp_path / "flat.ply", flat, [[0, 1, 2], [0, 2, 3]])
    with pytest.raises(SceneFileError, match=r"flat\.ply: the scene has no ground truth: every"):
        load_world(write_spec(tmp_path, "flat.ply", start_m=[5.0, 5.0]), cache=False)
