"""``nbv-gym worlds import`` → ``worlds preview`` → ``run``: a scene file becomes a world every
command takes; units and axes are detected, and a file that cannot make a world writes nothing."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
import trimesh

from nbv_gym.worlds import load_spec, shapes
from nbv_gym.worlds.importer import summarise
from tests.helpers import run_cli

#: A 10 m square 1 m up (lifted to the ground plane: no ground truth), and a slab 0.1 m thick
#: (ground truth below the 0.2 m where map quality is scored only).
FLAT = "v 0 0 1\nv 10 0 1\nv 10 10 1\nv 0 10 1\nf 1 2 3\nf 1 3 4\n"
SLAB = "".join(
    f"v {x} {y} {z}\n" for z in (0, 0.1) for x, y in ((0, 0), (10, 0), (10, 10), (0, 10))
)
SLAB += "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\n"
SLAB += "f 3 8 7\nf 4 1 5\nf 4 5 8\n"


def write_scene(path, scale: float = 1.0, up: str = "z") -> None:
    """Six 2 m boxes around the origin, in units of ``scale`` metres, ``up`` as up."""
    boxes = [shapes.cuboid() for _ in range(6)]
    at = [(8.0 * np.cos(a), 8.0 * np.sin(a), 0.0) for a in np.arange(6) * np.pi / 3]
    vertices, faces = shapes.concatenate([(v + p, f) for (v, f), p in zip(boxes, at, strict=True)])
    if up == "y":
        vertices = np.column_stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]])
    trimesh.Trimesh(vertices / scale, faces, process=False).export(path)


@pytest.mark.parametrize(
    ("scale", "given", "units"),
    [(1.0, None, "metres"), (0.001, None, "millimetres"), (0.01, 0.01, "centimetres")],
)
def test_the_units_are_detected_or_given(tmp_path, scale, given, units):
    write_scene(tmp_path / "s.obj", scale)
    summary = summarise(tmp_path / "s.obj", scale=given)
    assert (summary.scale, summary.units, summary.up, summary.kind) == (scale, units, "z", "mesh")
    assert summary.count == 6 * 16  # a prism of 4 sides: 8 side and 2 × 4 cap triangles
    assert summary.high_m[:2] - summary.low_m[:2] == pytest.approx(
        [18.0, 16 * np.sin(np.pi / 3) + 2]
    )


def test_a_glb_is_taken_as_y_up(tmp_path):
    write_scene(tmp_path / "s.glb", up="y")
    summary = summarise(tmp_path / "s.glb")
    assert summary.up == "y" and summary.low_m[2] == pytest.approx(0.0)
    assert summary.high_m[2] == pytest.approx(2.0)


def test_import_preview_and_run_a_scene_world(tmp_path):
    write_scene(tmp_path / "scene.obj", scale=0.001)
    result = run_cli("worlds", "import", "scene.obj", "--out", "scene.toml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "units millimetres (scale = 0.001)" in result.stdout
    spec = tomllib.loads((tmp_path / "scene.toml").read_text())
    assert spec["scene"]["file"] == "scene.obj" and spec["scene"]["scale"] == 0.001
    assert spec["scene"]["sha256"] == load_spec(tmp_path / "scene.toml").scene.sha256
    preview = run_cli("worlds", "preview", "scene.toml", "--out", "scene.png", cwd=tmp_path)
    assert preview.returncode == 0 and (tmp_path / "scene.png").stat().st_size > 10_000
    args = ["--world", "scene.toml", "--max-steps", "3", "--no-animation", "--json"]
    run = run_cli("run", *args, "--out", "run", "--lidar", "vlp-16", cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    summary = json.loads(run.stdout)
    assert summary["lidar"] == "vlp-16" and summary["final"]["discovered"] > 0
    assert summary["config"]["simulator"]["world"] == "scene.toml"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", "the mesh holds no triangles"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "the mesh holds no triangles"),
        ("v nan 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n", "1 of 3 vertices are NaN or infinite"),
        ("v 0 0 0\nv 2000 0 0\nv 0 2000 1\nf 1 2 3\n", "2,000 m across at scale = 1"),
        ("v 0 0 0\nv 0.002 0 0\nv 0 0.002 1\nf 1 2 3\n", "kilometres? try scale = 1000"),
        (FLAT, "the scene has no ground truth: every face lies in the ground plane"),
        (SLAB, "has no ground-truth voxel in the box where map quality is scored"),
    ],
    ids=["empty", "no faces", "nan", "2 km", "2 mm", "flat", "slab"],
)
def test_a_bad_mesh_gives_one_line_and_writes_nothing(tmp_path, content, message):
    (tmp_path / "bad.obj").write_text(content)
    result = run_cli("worlds", "import", "bad.obj", "--out", "bad.toml", "--scale", "1",
                     cwd=tmp_path)  # fmt: skip
    lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert message in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.obj"]


def test_an_unreadable_format_gives_one_line(tmp_path):
    (tmp_path / "scene.glb").write_bytes(b"not a glb at all")
    (tmp_path / "scene.dwg").write_bytes(b"AC1032")
    for name, message in (("scene.glb", "not a readable mesh"), ("scene.dwg", "unknown format")):
        result = run_cli("worlds", "import", name, "--out", "s.toml", cwd=tmp_path)
        lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
        assert result.returncode == 2 and len(lines) == 1 and message in lines[0], result.stderr
    assert not (tmp_path / "s.toml").exists()


def test_a_point_cloud_imports_as_a_cloud_world(tmp_path):
    from nbv_gym.core.pointclouds import write_points

    rng = np.random.default_rng(0)
    wall = np.column_stack([rng.uniform(5, 9, 4000), np.full(4000, 6.05), rng.uniform(0, 2, 4000)])
    write_points(tmp_path / "scan.pcd", np.vstack([wall, [[-9.0, -9.0, 0.0]]]))
    result = run_cli("worlds", "import", "scan.pcd", "--out", "scan.toml", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert "scan.pcd: cloud, 4,001 points, units metres" in result.stdout
    assert tomllib.loads((tmp_path / "scan.toml").read_text())["scene"]["kind"] == "cloud"


@pytest.mark.parametrize(
    ("content", "message"),
    [("", "the point cloud is empty"), ("0 0 0\nnan 1 1\n5 5 1\n", "NaN or infinite")],
    ids=["empty", "nan"],
)
def test_a_bad_cloud_gives_one_line_and_writes_nothing(tmp_path, content, message):
    (tmp_path / "bad.xyz").write_text(content)
    result = run_cli("worlds", "import", "bad.xyz", "--out", "bad.toml", cwd=tmp_path)
    lines = [line for line in result.stderr.splitlines() if line.startswith("Error: ")]
    assert result.returncode == 2 and len(lines) == 1 and message in lines[0], result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.xyz"]


def test_an_import_whose_out_another_import_wrote_meanwhile_is_refused_keeping_it(
    tmp_path, monkeypatch
):
    """Two imports into one --out: the one that finishes second writes nothing and says so in
    one line; the spec there stays the first one's, whole."""
    import nbv_gym.worlds.world as worlds
    from tests.helpers import invoke

    write_scene(tmp_path / "s.obj")
    monkeypatch.chdir(tmp_path)
    build = worlds.load_world

    def meanwhile(spec, *args, **kwargs):  # the other import finishes while this one builds
        world = build(spec, *args, **kwargs)
        (tmp_path / "w.toml").write_text("# the other import's spec\n")
        return world

    monkeypatch.setattr(worlds, "load_world", meanwhile)
    result = invoke("worlds", "import", "s.obj", "--out", "w.toml")
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert "w.toml exists: another process wrote it while this one ran" in result.err
    assert "this command wrote nothing (give another --out, or --force" in result.err
    assert (tmp_path / "w.toml").read_text() == "# the other import's spec\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.obj", "w.toml"]
