"""Benchmark worlds: seeded, shared layouts, clear start, cached, with clear errors on bad specs."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import numpy as np
import pytest

from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.worlds import (
    ASSET_TYPES,
    benchmark_names,
    build_world,
    load_spec,
    load_world,
    parse_spec,
)
from nbv_gym.worlds.world import cache_path

VALID_SPEC = """
name = "tiny"
[placement]
seed = 5
n_assets = 6
[assets]
mix = { cuboids = 1.0 }
"""


def vertex_hash(world) -> str:
    return hashlib.sha256(world.vertices.tobytes() + world.faces.tobytes()).hexdigest()


def test_the_twelve_benchmark_worlds():
    names = benchmark_names()
    assert names == sorted(f"pp{p}-{a}" for p in (1, 2, 3) for a in ASSET_TYPES)
    for name in names:
        spec = load_spec(name)
        assert spec.name == name and spec.placement.n_assets == 50
        assert spec.placement.parents == 3 and spec.placement.cluster_radius_m == 30


@pytest.mark.parametrize("name", ["pp1-cuboids", "pp2-crosses", "pp3-helicoids", "pp1-trees"])
def test_assets_lie_in_the_window_and_clear_the_start(name):
    world = load_world(name)
    assert len(world.layout.xy) == 50
    x0, y0, x1, y1 = world.spec.placement.window_m
    assert np.all((world.layout.xy >= [x0, y0]) & (world.layout.xy <= [x1, y1]))
    asset_vertices = world.vertices[np.unique(world.faces[: world.asset_faces])]
    assert np.hypot(asset_vertices[:, 0], asset_vertices[:, 1]).min() >= 2.0 - 1e-4
    assert asset_vertices[:, 2].min() >= -1e-6  # assets stand on the ground


def test_worlds_of_one_realization_share_the_layout():
    cuboids, trees = load_world("pp2-cuboids").layout, load_world("pp2-trees").layout
    for field in ("yaw", "scale_xy", "scale_z"):
        np.testing.assert_array_equal(getattr(cuboids, field), getattr(trees, field))
    # positions agree but for assets pushed out of the start disc by their own footprint
    moved = np.any(cuboids.xy != trees.xy, axis=1)
    assert moved.sum() <= 2
    assert np.all(np.hypot(*trees.xy[moved].T) < 10)


def test_scales_and_yaws_are_in_their_ranges():
    placed = load_world("pp3-cuboids").layout
    assert placed.scale_xy.min() >= 0.7 and placed.scale_xy.max() <= 1.3
    assert placed.scale_z.min() >= 0.7 and placed.scale_z.max() <= 1.3
    assert placed.yaw.min() >= 0 and placed.yaw.max() < 2 * np.pi
    assert placed.yaw.std() > 1.0  # spread over the circle, not constant


def test_ground_truth_lies_on_the_assets_not_the_ground():
    world = load_world("pp1-cuboids")
    points = world.ground_truth.points()
    assert points[:, 2].min() > 0  # the ground plane is not ground truth
    # every voxel is within a voxel diagonal of an asset vertex's box
    assert points[:, 2].max() <= world.vertices[:-4, 2].max() + 0.1


def test_same_seed_same_world_in_another_process(tmp_path):
    spec_file = tmp_path / "tiny.toml"
    spec_file.write_text(VALID_SPEC)
    here = vertex_hash(build_world(parse_spec(VALID_SPEC, "tiny")))
    code = (
        "import hashlib, sys; from nbv_gym.worlds import build_world, load_spec; "
        "w = build_world(load_spec(sys.argv[1])); "
        "print(hashlib.sha256(w.vertices.tobytes() + w.faces.tobytes()).hexdigest())"
    )
    there = subprocess.run(
        [sys.executable, "-c", code, str(spec_file)], capture_output=True, text=True, check=True
    ).stdout.strip()
    assert here == there
    other = build_world(parse_spec(VALID_SPEC.replace("seed = 5", "seed = 6"), "tiny"))
    assert vertex_hash(other) != here


def test_world_generation_leaves_global_random_state_alone():
    state = np.random.get_state()[1].copy()  # noqa: NPY002 (the state under test)
    build_world(parse_spec(VALID_SPEC.replace("cuboids", "trees"), "tiny"))
    np.testing.assert_array_equal(np.random.get_state()[1], state)  # noqa: NPY002


def test_cache_round_trip_and_corrupt_file_recovery(world_cache):
    spec = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 42"), "tiny")
    built = load_world(spec)
    path = cache_path(spec)
    assert path.exists() and path.is_relative_to(world_cache)
    loaded = load_world(spec)
    np.testing.assert_array_equal(loaded.vertices, built.vertices)
    np.testing.assert_array_equal(loaded.ground_truth.voxels, built.ground_truth.voxels)
    path.write_bytes(path.read_bytes()[:100])  # truncated
    np.testing.assert_array_equal(load_world(spec).vertices, built.vertices)


def test_unknown_world_suggests_and_lists():
    with pytest.raises(UnknownNameError, match=r"Did you mean 'pp1-trees'.*pp3-trees"):
        load_spec("pp1-tres")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (VALID_SPEC.replace("seed = 5\n", ""), r"placement: .*seed"),
        (VALID_SPEC.replace("seed = 5", "sede = 5"), r"Unknown key placement\.sede"),
        (
            VALID_SPEC.replace("n_assets = 6", "n_assets = 'six'"),
            r"placement\.n_assets: expected int",
        ),
        (VALID_SPEC.replace("cuboids", "pyramids"), r"assets: mix: unknown asset type"),
        (
            VALID_SPEC.replace("n_assets = 6", "n_assets = 0"),
            r"placement: n_assets: must be from 2 to 1000, got 0",
        ),
        (VALID_SPEC.replace('name = "tiny"', ""), r"missing required key 'name'"),
        ("name = [", r"not valid TOML"),
    ],
    ids=["missing", "typo", "type", "asset", "range", "name", "toml"],
)
def test_malformed_spec_names_the_field(text, message):
    with pytest.raises(ConfigError, match=message):
        parse_spec(text, "my.toml")


#: One process of the concurrent-build test: waits until ``go`` exists, then loads the world of
#: ``spec`` from the (cold) cache, with the phase messages on stderr.
_LOAD_AFTER_GO = """
import sys, time
from pathlib import Path
from nbv_gym.core.progress import speak_on_stderr
from nbv_gym.worlds import load_world
speak_on_stderr()
spec, go = sys.argv[1], Path(sys.argv[2])
while not go.exists():
    time.sleep(0.01)
load_world(spec)
"""


def test_two_processes_on_a_cold_cache_build_a_world_once(tmp_path):
    spec = tmp_path / "concurrent.toml"
    spec.write_text(VALID_SPEC.replace('"tiny"', '"concurrent"').replace("6", "40"))
    go = tmp_path / "go"
    env = {**os.environ, "NBV_GYM_CACHE": str(tmp_path / "cache")}
    workers = [
        subprocess.Popen(
            [sys.executable, "-c", _LOAD_AFTER_GO, str(spec), str(go)],
            env=env,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    go.touch()  # both start loading at the same moment
    stderr = [worker.communicate(timeout=300)[1] for worker in workers]
    assert [worker.returncode for worker in workers] == [0, 0], stderr
    assert sum(text.count("building world concurrent") for text in stderr) == 1, stderr
    assert len(list((tmp_path / "cache" / "worlds").glob("concurrent-*.npz"))) == 1


def _rewrite_cache(path, **changes):
    """Rewrite the cache file ``path`` as a valid .npz with some arrays changed."""
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays.update(changes)
    with open(path, "wb") as file:
        np.savez(file, **arrays)


@pytest.mark.parametrize(
    "tamper",
    [
        lambda a: {"ground_truth": a["ground_truth"][: len(a["ground_truth"]) // 2]},
        lambda a: {"ground_truth": a["ground_truth"][:0]},
        lambda a: {"vertices": a["vertices"] + 0.5},
        lambda a: {"xy": a["xy"][::-1]},
        lambda a: {"digest": np.array("0" * 64)},
        lambda a: {"spec": np.array(str(a["spec"]).replace('"seed": 43', '"seed": 44'))},
    ],
    ids=["shortened truth", "no truth", "moved mesh", "other layout", "digest", "spec"],
)
def test_a_tampered_cache_file_is_rebuilt_not_trusted(tmp_path, monkeypatch, tamper):
    monkeypatch.setenv("NBV_GYM_CACHE", str(tmp_path))  # its own: the cases run side by side
    spec = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 43"), "tiny")
    built = load_world(spec)
    path = cache_path(spec)
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    _rewrite_cache(path, **tamper(arrays))
    loaded = load_world(spec)
    np.testing.assert_array_equal(loaded.ground_truth.voxels, built.ground_truth.voxels)
    np.testing.assert_array_equal(loaded.vertices, built.vertices)
    np.testing.assert_array_equal(loaded.layout.xy, built.layout.xy)
    with np.load(path) as data:  # and the cache holds the true world again
        np.testing.assert_array_equal(data["ground_truth"], built.ground_truth.voxels)


def test_a_cache_file_of_another_spec_under_this_name_is_rebuilt(world_cache):
    mine = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 45"), "tiny")
    other = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 46"), "tiny")
    load_world(other)
    cache_path(other).replace(cache_path(mine))
    np.testing.assert_array_equal(load_world(mine).vertices, build_world(mine).vertices)


def test_a_read_only_cache_folder_is_named_and_the_world_still_loads(world_cache, monkeypatch):
    import errno

    def read_only(file, **arrays):
        raise OSError(errno.EROFS, "Read-only file system", str(file))

    monkeypatch.setattr("nbv_gym.worlds.world.np.savez", read_only)  # root writes anywhere
    spec = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 47"), "tiny")
    folder = cache_path(spec).parent
    with pytest.warns(UserWarning, match=f"cannot cache the world in {folder} \\(Read-only"):
        world = load_world(spec)
    assert world.ground_truth.voxels.size > 0 and not cache_path(spec).exists()
    assert not list(folder.glob("*.tmp.npz"))


def test_a_world_whose_cache_lock_another_process_holds_says_it_waits(world_cache, caplog):
    import logging
    import threading
    import time

    from filelock import FileLock

    spec = parse_spec(VALID_SPEC.replace("seed = 5", "seed = 48"), "tiny")
    cache_path(spec).parent.mkdir(parents=True, exist_ok=True)
    taken = threading.Event()

    def hold() -> None:  # another holder: its own thread and descriptor, for 2 s
        with FileLock(cache_path(spec).with_suffix(".lock")):
            taken.set()
            time.sleep(2.0)

    threading.Thread(target=hold).start()
    taken.wait()
    with caplog.at_level(logging.INFO, logger="nbv_gym"):
        world = load_world(spec)
    assert world.ground_truth.voxels.size > 0
    assert any("waiting for another process that builds world tiny" in m for m in caplog.messages)
