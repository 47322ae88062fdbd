"""``nbv-gym worlds import``: the world spec of a scene file, with what was detected.

The units are a guess from the scene's horizontal size: the first of metres, millimetres (CAD
exports) and centimetres (scale 1, 0.001, 0.01) that makes it 1–500 m across — a guess only,
since an 18 m scene in millimetres is also a plausible 180 m one in centimetres: the command
prints what it took, and ``--scale`` says it instead. The up axis is glTF's y for GLB/GLTF files
and z otherwise (``--up`` says it instead). The spec pins the file's SHA-256.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.worlds.scenes.files import MAX_SIZE_M, MIN_SIZE_M, check_size, to_metres_z_up
from nbv_gym.worlds.scenes.spec import detect_kind

if TYPE_CHECKING:
    from nbv_gym.worlds.world import World

#: Candidate scales, in the order they are tried: metres, millimetres, centimetres.
UNITS = {1.0: "metres", 0.001: "millimetres", 0.01: "centimetres"}


@dataclass(frozen=True)
class SceneSummary:
    """What ``worlds import`` found in a file: ``kind`` ("mesh" or "cloud"), ``count``
    (triangles or points), ``scale`` and ``up`` (detected or given), ``units`` (their name),
    and ``low_m``/``high_m`` (3,) the bounds in metres, z up, file frame."""

    path: Path
    kind: str
    count: int
    scale: float
    up: str
    units: str
    low_m: FloatArray
    high_m: FloatArray


def summarise(path: Path, scale: float | None = None, up: str | None = None) -> SceneSummary:
    """Read ``path`` and detect what a spec needs (see the module doc)."""
    kind = detect_kind(path)
    points, count = _geometry(path, kind)
    up = up or ("y" if path.suffix.lower() in (".glb", ".gltf") else "z")
    scale = scale if scale is not None else _guess_scale(points, up)
    metres = to_metres_z_up(points, scale, up)
    check_size(path, metres, scale)
    units = UNITS.get(scale, f"scale {scale:g}")
    return SceneSummary(path, kind, count, scale, up, units, metres.min(0), metres.max(0))


def _geometry(path: Path, kind: str) -> tuple[FloatArray, int]:
    """The points that bound the scene (used vertices, or the cloud) and the triangle or
    point count."""
    if kind == "cloud":
        from nbv_gym.worlds.scenes.clouds import read_cloud

        points = read_cloud(path)
        return points, len(points)
    from nbv_gym.worlds.scenes.files import read_mesh

    vertices, faces = read_mesh(path)
    return vertices, len(faces)


def _guess(summary: SceneSummary) -> str:
    """The unit guess of ``summary`` in words, with the size that led to it."""
    across = float(np.max((summary.high_m - summary.low_m)[:2])) / summary.scale
    return (
        f"{summary.units}, since the file is {across:,.4g} units across; if they are metres or "
        "another unit, give --scale"
    )


def _guess_scale(points: FloatArray, up: str) -> float:
    for scale in UNITS:
        size = float(np.ptp(to_metres_z_up(points, scale, up)[:, :2], axis=0).max())
        if MIN_SIZE_M <= size <= MAX_SIZE_M:
            return scale
    return 1.0  # none fits: check_size then says why


def spec_text(summary: SceneSummary, name: str, spec_path: Path, sha256: str, ground: str) -> str:
    """The TOML of the world spec, ``scene.file`` relative to the spec's folder."""
    try:
        file = os.path.relpath(summary.path.resolve(), spec_path.resolve().parent)
    except ValueError:  # another drive (Windows)
        file = str(summary.path.resolve())
    low, high = summary.low_m, summary.high_m
    what = "triangles" if summary.kind == "mesh" else "points"
    size = high - low
    return "\n".join(
        [
            f"# Written by nbv-gym worlds import from {summary.path.name}: {summary.kind}, "
            f"{summary.count:,} {what}, units {summary.units}, up {summary.up}.",
            f"# Bounds in metres, z up, file frame: x {low[0]:.2f} … {high[0]:.2f}, "
            f"y {low[1]:.2f} … {high[1]:.2f}, z {low[2]:.2f} … {high[2]:.2f}.",
            f'name = "{name}"',
            f'description = "{summary.path.name}: {summary.count:,} {what}, '
            f'{size[0]:.1f} m × {size[1]:.1f} m × {size[2]:.1f} m"',
            "",
            "[scene]",
            f"file = {_quoted(file)}",
            f'kind = "{summary.kind}"',
            f"scale = {summary.scale!r}",
            f'up = "{summary.up}"',
            f'ground = "{ground}"',
            "clear_radius_m = 2.0",
            "# start_m = [x, y]  # metres, file frame; left out: the free point nearest the centre",
            f'sha256 = "{sha256}"',
            "",
        ]
    )


def _quoted(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def import_scene(
    file: Path,
    out: Path,
    name: str | None,
    scale: float | None,
    up: str | None,
    ground: str,
    accept: Callable[[World], object] | None = None,
    replace: bool = False,
) -> list[str]:
    """Write the spec of ``file`` to ``out`` once its world is built (and cached) and has passed
    ``accept`` (a check that raises, e.g. that the world has ground truth where map quality is
    scored); the lines to show. Any problem raises before ``out`` is written, and ``out`` is
    written whole (``replace``: replacing the file there; otherwise only if none is there by
    then, another import of the same ``out`` having finished first, say)."""
    from nbv_gym.core.config import check
    from nbv_gym.core.outputs import write_new, write_text
    from nbv_gym.worlds.scenes.spec import file_sha256, parse_scene_spec
    from nbv_gym.worlds.world import load_world

    check(up in (None, "z", "y"), "--up", f"expected z or y, got {up!r}")
    check(ground in ("add", "mesh"), "--ground", f"expected add or mesh, got {ground!r}")
    if not file.is_file():
        from nbv_gym.core.errors import missing_file

        raise ConfigError(f"{file} {missing_file(file)}.")
    summary = summarise(file, scale, up)
    name = name or default_name(file)
    text = spec_text(summary, name, out, file_sha256(file), ground)
    from nbv_gym.core.config import parse_toml

    spec = parse_scene_spec(parse_toml(text, str(out)), str(out), out.resolve().parent)
    try:
        world = load_world(spec)
    except NbvGymError as error:
        if scale is not None or summary.scale == 1.0:
            raise
        raise ConfigError(f"{error} (the units are a guess: {_guess(summary)})") from None
    if accept is not None:
        accept(world)
    if replace:
        write_text(out, text)
    else:
        write_new(out, text, "give another --out, or --force to replace it")
    x0, y0, x1, y1 = world.window_m
    start = np.asarray(world.scene_frame.offset_m)
    what = "triangles" if summary.kind == "mesh" else "points"
    return [
        f"{file.name}: {summary.kind}, {summary.count:,} {what}, units {summary.units} "
        f"(scale = {summary.scale:g}), up {summary.up}",
        f"world {name}: {x1 - x0:.1f} m × {y1 - y0:.1f} m, start ({start[0]:.1f}, "
        f"{start[1]:.1f}) m in the file's frame, {len(world.ground_truth.voxels):,} "
        f"ground-truth voxels → {out}",
    ]


def default_name(file: Path) -> str:
    """A world name from the file's stem (characters a name may not hold become ``-``)."""
    import re

    from nbv_gym.core.names import MAX_NAME_LENGTH

    name = re.sub(r"[^A-Za-z0-9._-]+", "-", file.stem).strip(".-_")
    name = re.sub(r"\.{2,}", ".", name)[:MAX_NAME_LENGTH]
    return name or "scene"
