"""A built world: the mesh the lidar sees, the ground truth, and how to build and cache it."""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.config import check, to_dict
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.names import check_name
from nbv_gym.core.progress import say, say_if_compiling
from nbv_gym.core.protocol import RESOLUTION_M
from nbv_gym.worlds import shapes
from nbv_gym.worlds.groundtruth import GroundTruth, surface_voxels
from nbv_gym.worlds.placement import Layout, clear_start, empty_layout, layout
from nbv_gym.worlds.scenes.build import SceneFrame, build_scene
from nbv_gym.worlds.scenes.spec import SceneSpec
from nbv_gym.worlds.spec import ASSET_TYPES, AnySpec, WorldSpec, load_spec
from nbv_gym.worlds.trees import grow_tree, tree_mesh

#: Bump when generation changes, so cached worlds are rebuilt (2: a face on a voxel boundary
#: occupies the voxels on its upper side; the benchmark worlds' ground truth is unchanged).
GENERATOR_VERSION = 2
#: Environment variable that moves the world cache.
CACHE_ENV = "NBV_GYM_CACHE"


@dataclass(frozen=True)
class World:
    """A built world.

    Attributes:
        spec: what it was generated from.
        vertices: (V, 3) float32 vertices of the whole scene (assets and ground plane), metres.
        faces: (F, 3) int32 triangles.
        asset_faces: number of leading faces that belong to assets (the rest is ground).
        layout: the placed assets (none in a scene world).
        ground_truth: the assets' (or the scene's) surface voxels.
        frame: where a scene world lies (:class:`~nbv_gym.worlds.scenes.build.SceneFrame`);
            None for a procedural world.
    """

    spec: AnySpec
    vertices: FloatArray
    faces: IntArray
    asset_faces: int
    layout: Layout
    ground_truth: GroundTruth
    frame: SceneFrame | None = None

    @property
    def name(self) -> str:
        """The world's name (its spec's)."""
        return self.spec.name

    @property
    def ground_bounds_xy(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((x_min, y_min), (x_max, y_max)) of the ground the robot may stand on, metres."""
        if not isinstance(self.spec, WorldSpec):
            return self.scene_frame.ground_xy_m
        half = self.spec.ground_size_m / 2
        return (-half, -half), (half, half)

    @property
    def window_m(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) metres: where the assets (or the scene) stand, the box
        the goal grid is fitted to."""
        if isinstance(self.spec, WorldSpec):
            return self.spec.window_m
        return self.scene_frame.window_m

    @property
    def clear_radius_m(self) -> float:
        """The radius of the disc around the start (the origin) that no asset enters, metres."""
        if isinstance(self.spec, WorldSpec):
            return self.spec.placement.clear_radius_m
        return self.spec.scene.clear_radius_m

    @property
    def scene_frame(self) -> SceneFrame:
        """Where a scene world lies; ValueError for a procedural world (it has none)."""
        if self.frame is None:
            raise ValueError(f"world {self.name!r} is procedural: it has no scene frame")
        return self.frame

    def file_frame(self) -> dict[str, Any] | None:
        """How a scene world's frame lies in its file's: ``offset_m`` (3,) metres, ``scale`` and
        ``up`` (world = the file's points scaled to metres, turned z up, less ``offset_m``);
        None for a procedural world."""
        if not isinstance(self.spec, SceneSpec):
            return None
        scene = self.spec.scene
        return {"offset_m": list(self.scene_frame.offset_m), "scale": scene.scale, "up": scene.up}

    def check_inside(self, low_xy: tuple[float, float], high_xy: tuple[float, float], what: str):
        """Raise :class:`ConfigError` unless :attr:`window_m` lies in the box ``low_xy``–
        ``high_xy`` (metres) of ``what`` (e.g. the goal grid of a simulator)."""
        if isinstance(self.spec, WorldSpec):
            return self.spec.check_inside(low_xy, high_xy, what)
        x0, y0, x1, y1 = self.window_m
        inside = low_xy[0] <= x0 and low_xy[1] <= y0 and x1 <= high_xy[0] and y1 <= high_xy[1]
        check(
            inside,
            "scene",
            f"scene world {self.name!r} spans x from {x0:.1f} to {x1:.1f} m and y from {y0:.1f} "
            f"to {y1:.1f} m around its start, beyond {what} (x from {low_xy[0]:g} to "
            f"{high_xy[0]:g} m, y from {low_xy[1]:g} to {high_xy[1]:g} m)",
        )

    def ray_scene(self):
        """The Embree scene of this world (built once, then shared)."""
        return self._ray_scene

    @cached_property
    def _ray_scene(self):
        from nbv_gym.worlds.raycast import RayScene

        return RayScene(self.vertices, self.faces)


def build_world(spec: AnySpec) -> World:
    """Generate the world of ``spec`` (meshes, layout, ground truth); no caching."""
    if isinstance(spec, SceneSpec):
        built = build_scene(spec, RESOLUTION_M)
        return World(spec, built.vertices, built.faces, built.scene_faces, empty_layout(),
                     built.ground_truth, built.frame)  # fmt: skip
    placed = layout(spec.placement, spec.assets)
    library = _asset_library(spec, placed)
    meshes = [library[(k, v)] for k, v in zip(placed.kind, _variants(placed), strict=True)]
    footprint = np.array([shapes.footprint_radius(m) for m in meshes]) * placed.scale_xy
    xy = clear_start(placed.xy, footprint, spec.placement.clear_radius_m)
    placed = Layout(xy, placed.yaw, placed.scale_xy, placed.scale_z, placed.kind, placed.variant)
    assets = shapes.concatenate(
        [
            shapes.place(mesh, xy[n], placed.yaw[n], placed.scale_xy[n], placed.scale_z[n])
            for n, mesh in enumerate(meshes)
        ]
    )
    ground_truth = surface_voxels(*assets, RESOLUTION_M)
    vertices, faces = shapes.concatenate([assets, shapes.ground_plane(spec.ground_size_m)])
    return World(
        spec,
        vertices.astype(np.float32),
        faces.astype(np.int32),
        len(assets[1]),
        placed,
        ground_truth,
    )


def _variants(placed: Layout) -> IntArray:
    """The library variant of each asset: the tree index for trees, 0 for the other types."""
    is_tree = placed.kind == ASSET_TYPES.index("trees")
    return np.where(is_tree, placed.variant, 0)


def _asset_library(spec: WorldSpec, placed: Layout) -> dict[tuple[int, int], shapes.Mesh]:
    """The unscaled mesh of every (type, variant) the layout uses."""
    builders: dict[str, Callable[[], shapes.Mesh]] = {
        "cuboids": shapes.cuboid,
        "crosses": shapes.cross,
        "helicoids": shapes.helicoid,
    }
    library = {}
    needed_trees = sorted(set(placed.variant[placed.kind == ASSET_TYPES.index("trees")]))
    if needed_trees:
        tree_rngs = np.random.SeedSequence(spec.assets.tree_library_seed).spawn(
            spec.assets.tree_library_size
        )
        tree = spec.assets.tree
        for variant in needed_trees:
            skeleton = grow_tree(tree, np.random.default_rng(tree_rngs[variant]))
            library[(ASSET_TYPES.index("trees"), variant)] = tree_mesh(
                skeleton, tree.min_sides, tree.max_sides
            )
    for kind in sorted(set(placed.kind)):
        if ASSET_TYPES[kind] in builders:
            library[(kind, 0)] = builders[ASSET_TYPES[kind]]()
    return library


def cache_dir() -> Path:
    """Where built worlds are cached: ``$NBV_GYM_CACHE`` or the user cache directory."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("nbv-gym"))


def cache_path(spec: AnySpec) -> Path:
    """The cache file of ``spec``, keyed by its content and the generator version (the name is
    checked again: only a safe name becomes a file name)."""
    name = check_name(spec.name, "name")
    return cache_dir() / "worlds" / f"{name}-{spec.digest()}-v{GENERATOR_VERSION}.npz"


def load_world(
    name_or_path: str | Path | AnySpec, cache: bool = True, rebuild: bool = False
) -> World:
    """The world of a benchmark name, a spec file path or a spec, loaded from the cache when
    built before (and built, then cached, otherwise; ``rebuild``: built again, the cached file
    replaced atomically). A cached file is used only if its content is the one built from the
    spec (:func:`content_digest`); any other is built again.

    Processes that want the same uncached world at once (the workers of a sweep or a score)
    build it once: the builder holds a lock file beside the cache file, the others wait for it,
    then read what it cached."""
    spec = (
        name_or_path
        if isinstance(name_or_path, (WorldSpec, SceneSpec))
        else load_spec(name_or_path)
    )
    if not cache:
        return _build(spec, None)
    path = cache_path(spec)
    if not rebuild and (world := _from_cache(path, spec)) is not None:
        return world
    from filelock import FileLock

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = FileLock(path.with_suffix(".lock"))
        _acquire(lock, spec.name)
    except OSError as error:  # a read-only cache folder: build without caching
        _cannot_cache(path, error)
        return _build(spec, None)
    try:
        if not rebuild and (world := _from_cache(path, spec)) is not None:
            return world  # another process built it while this one waited
        return _build(spec, path)
    finally:
        lock.release()


def _acquire(lock, name: str) -> None:
    """Take the cache file's ``lock``; when another process holds it (building world ``name``),
    say so, then wait for it."""
    from filelock import Timeout

    try:
        lock.acquire(timeout=1.0)
    except Timeout:
        say(f"waiting for another process that builds world {name} (it holds {lock.lock_file})…")
        lock.acquire()


def _from_cache(path: Path, spec: AnySpec) -> World | None:
    """The world cached at ``path``, or None when there is none or it is unusable (then said)."""
    if not path.exists():
        return None
    try:
        return _read(path, spec)
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, NbvGymError) as error:
        say(f"the cached world {path} is unusable ({_one_line(error)}); building it again")
        return None


def _build(spec: AnySpec, path: Path | None) -> World:
    """Build the world of ``spec`` and write it to the cache file ``path`` (None: not cached)."""
    say_if_compiling()
    say(f"building world {spec.name} (mesh + ground truth), once per content…")
    start = time.perf_counter()
    world = build_world(spec)
    cached = path is not None and _store(path, world)
    say(
        f"world {spec.name} built in {time.perf_counter() - start:.0f} s"
        + (f", cached in {path}" if cached else "")
    )
    return world


def _store(path: Path, world: World) -> bool:
    """Write ``world`` to the cache file ``path``; False, saying why and what to do, if the
    cache folder cannot take it (read-only, full): the world is then built again next time."""
    try:
        _write(path, world)
        return True
    except OSError as error:
        _cannot_cache(path, error)
        return False


def _cannot_cache(path: Path, error: OSError) -> None:
    warnings.warn(
        f"cannot cache the world in {path.parent} ({error.strerror or error}); it will be "
        f"built again next time. Set {CACHE_ENV} to a writable folder to keep it.",
        stacklevel=4,
    )


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def _arrays(world: World) -> dict[str, Any]:
    """The arrays a cache file holds (besides its spec and digest); a scene world's frame as
    JSON."""
    placed = world.layout
    frame = to_dict(world.frame) if world.frame is not None else None
    return dict(
        vertices=world.vertices,
        faces=world.faces,
        asset_faces=world.asset_faces,
        ground_truth=world.ground_truth.voxels,
        res=world.ground_truth.res,
        xy=placed.xy,
        yaw=placed.yaw,
        scale_xy=placed.scale_xy,
        scale_z=placed.scale_z,
        kind=placed.kind,
        variant=placed.variant,
        frame=np.array(json.dumps(frame)),
    )


def content_digest(arrays: dict[str, Any], spec: AnySpec) -> str:
    """SHA-256 of a cache file's content: the spec's digest and generator version, then each
    array's name, dtype, shape and bytes (sorted by name)."""
    digest = hashlib.sha256(f"{spec.digest()}-v{GENERATOR_VERSION}".encode())
    for name in sorted(arrays):
        array = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def _write(path: Path, world: World) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = _arrays(world)
    temporary = path.with_suffix(f".{os.getpid()}.tmp.npz")
    try:
        np.savez(
            temporary,
            **arrays,
            spec=json.dumps(to_dict(world.spec)),
            digest=content_digest(arrays, world.spec),
        )
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def _read(path: Path, spec: AnySpec) -> World:
    """The world in the cache file ``path``, after checking that its content is the one built
    from ``spec`` (its digest, recomputed); ``ValueError`` naming what differs otherwise."""
    from nbv_gym.core.arrayfiles import read_npz

    data = read_npz(path)
    digest, stored_spec = str(data.pop("digest", "")), str(data.pop("spec", ""))
    if stored_spec != json.dumps(to_dict(spec)):
        raise ValueError("it holds another spec")
    if digest != content_digest(data, spec):
        raise ValueError("its content does not match its digest: edited, truncated or older")
    placed = Layout(
        data["xy"], data["yaw"], data["scale_xy"], data["scale_z"], data["kind"], data["variant"]
    )
    truth = GroundTruth(data["ground_truth"], float(data["res"]))
    frame = _frame(json.loads(str(data["frame"])))
    return World(
        spec, data["vertices"], data["faces"], int(data["asset_faces"]), placed, truth, frame
    )


def _frame(data: dict | None) -> SceneFrame | None:
    if data is None:
        return None
    (x0, y0), (x1, y1) = data["ground_xy_m"]
    return SceneFrame(tuple(data["window_m"]), ((x0, y0), (x1, y1)), tuple(data["offset_m"]))
