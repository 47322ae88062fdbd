"""The spec of a scene world: a world spec whose ``[scene]`` table names a mesh or point-cloud file.

::

    name = "my-park"
    description = "the park behind the lab"

    [scene]
    file = "park.glb"   # relative to this spec file
    scale = 1.0         # file units to metres
    up = "z"            # the file's up axis: "z" or "y" (glTF's)
    ground = "add"      # "add" a ground plane at the lowest point, or the "mesh" has its own

The file's SHA-256 is part of the world's identity (:meth:`SceneSpec.digest`): the world cache, run
records and scorecards change with the content, not with where the file lies. A ``sha256`` key
(written by ``nbv-gym worlds import``) pins it: a file changed since is refused.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

from nbv_gym.core.config import check, from_dict, to_dict
from nbv_gym.core.errors import ConfigError, missing_file
from nbv_gym.core.names import check_name

#: How a file becomes a world; bumped when the same file and keys make another world, so that
#: its maps, cache and scorecards are told from the earlier one's (2: faces on the voxel lattice
#: occupy the voxels on their upper side, unused vertices are left out).
SCENE_RULES = 2

#: Mesh formats (trimesh's loaders); a ``.ply`` without faces is a point cloud.
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")
#: Point-cloud formats (:mod:`nbv_gym.core.pointclouds`; LAS/LAZ through laspy).
CLOUD_SUFFIXES = (".ply", ".pcd", ".xyz", ".txt", ".pts", ".csv", ".las", ".laz")


@dataclass(frozen=True)
class SceneConfig:
    """The ``[scene]`` table: ``file`` (mesh or point cloud), ``kind`` (``"mesh"`` or
    ``"cloud"``; "" detects it from the file), ``scale`` (file units → metres), ``up`` (the
    file's up axis), ``ground`` (``"add"`` a plane at the scene's lowest point, or ``"mesh"``: the
    file holds its ground), ``start_m`` (the robot's start (x, y), metres, in the file's frame
    after scale and up; None picks the free point nearest the scene's centre), ``clear_radius_m``
    (the start's horizontal clearance from any ground-truth voxel, metres) and ``sha256`` (the
    file's content; "" for not pinned)."""

    file: str
    kind: Literal["", "mesh", "cloud"] = ""
    scale: float = 1.0
    up: Literal["z", "y"] = "z"
    ground: Literal["add", "mesh"] = "add"
    start_m: tuple[float, float] | None = None
    clear_radius_m: float = 2.0
    sha256: str = ""

    def __post_init__(self) -> None:
        check(bool(self.file.strip()), "file", "must name a mesh or point-cloud file")
        check(0 < self.scale < math.inf, "scale", f"must be > 0 and finite, got {self.scale}")
        check(
            self.start_m is None or all(map(math.isfinite, self.start_m)),
            "start_m",
            f"must be finite, got {self.start_m}",
        )
        check(0 <= self.clear_radius_m < math.inf, "clear_radius_m", "must be ≥ 0 and finite")
        check(
            self.sha256 == ""
            or (len(self.sha256) == 64 and set(self.sha256.lower()) <= set("0123456789abcdef")),
            "sha256",
            "must be the file's 64 hex digits (or left out)",
        )


@dataclass(frozen=True)
class SceneSpec:
    """A world made of one scene file (see the module doc); ``scene.file`` is absolute and
    ``scene.sha256`` and ``scene.kind`` are filled in once the spec is loaded."""

    name: str
    scene: SceneConfig
    description: str = ""

    def __post_init__(self) -> None:
        check_name(self.name, "name")

    @property
    def path(self) -> Path:
        """The scene file."""
        return Path(self.scene.file)

    def digest(self) -> str:
        """A short hash of the world's content: the file's SHA-256, the ``[scene]`` keys (the
        name, the description and the file's path excluded) and :data:`SCENE_RULES`."""
        content = to_dict(self)["scene"]
        content.pop("file")
        text = repr(sorted(content.items()))
        return hashlib.sha256((f"scene/{text}/rules {SCENE_RULES}").encode()).hexdigest()[:16]


def parse_scene_spec(data: dict[str, Any], source: str, base: Path | None) -> SceneSpec:
    """The :class:`SceneSpec` of a spec table; ``scene.file`` taken relative to ``base`` (the
    spec's folder), hashed and its kind detected. Errors name ``source`` and the key."""
    extra = sorted(set(data) & {"placement", "assets", "ground_size_m"})
    if extra:
        raise ConfigError(
            f"{source}: a [scene] world takes no procedural keys ({', '.join(extra)}); a world "
            "is either a scene file or procedural assets"
        )
    try:
        spec = from_dict(SceneSpec, data)
    except ConfigError as error:
        raise ConfigError(f"{source}: {error}") from None
    path = Path(spec.scene.file).expanduser()
    path = path if path.is_absolute() or base is None else base / path
    if not path.is_file():
        raise ConfigError(f"{source}: scene.file {str(path)!r} {missing_file(path)}.")
    kind = spec.scene.kind or detect_kind(path)
    digest = file_sha256(path)
    if spec.scene.sha256 and spec.scene.sha256 != digest:
        raise ConfigError(
            f"{source}: scene.sha256: {path} has changed since the spec was written (its SHA-256 "
            f"is {digest[:12]}…, the spec pins {spec.scene.sha256[:12]}…); import it again "
            "(nbv-gym worlds import) or delete the key"
        )
    scene = replace(spec.scene, file=str(path.resolve()), kind=kind, sha256=digest)
    return replace(spec, scene=scene)


def detect_kind(path: Path) -> Literal["mesh", "cloud"]:
    """``"mesh"`` or ``"cloud"`` from the suffix (a PLY with faces is a mesh); ConfigError for a
    suffix of neither."""
    suffix = path.suffix.lower()
    if suffix == ".ply":
        return "mesh" if _ply_faces(path) > 0 else "cloud"
    if suffix in MESH_SUFFIXES:
        return "mesh"
    if suffix in CLOUD_SUFFIXES:
        return "cloud"
    known = sorted(set(MESH_SUFFIXES + CLOUD_SUFFIXES))
    raise ConfigError(
        f"scene.file {str(path)!r}: unknown format {suffix or '(no suffix)'!r}; meshes and "
        f"point clouds in {', '.join(known)}"
    )


def _ply_faces(path: Path) -> int:
    """The face count a PLY header declares (0 for none, or an unreadable header)."""
    with path.open("rb") as handle:
        head = handle.read(64 * 1024)
    for line in head.split(b"\n"):
        words = line.split()
        if words[:2] == [b"element", b"face"] and len(words) == 3 and words[2].isdigit():
            return int(words[2])
        if words[:1] == [b"end_header"]:
            break
    return 0


_HASHES: dict[tuple[str, int, int], str] = {}


def file_sha256(path: Path) -> str:
    """The SHA-256 (hex) of a file's content, computed once per (path, size, mtime) per process."""
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    if key not in _HASHES:
        digest = hashlib.sha256()
        with path.open("rb") as handle:
            while chunk := handle.read(1 << 22):
                digest.update(chunk)
        _HASHES[key] = digest.hexdigest()
    return _HASHES[key]
