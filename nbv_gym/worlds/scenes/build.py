"""Building a scene world: the file in metres, z up, moved so that the start is the origin and the
ground z = 0; the ground truth voxelised as for the procedural worlds; the window fitted to it.

World frame = file frame (after ``scale`` and ``up``) − ``offset_m``, where ``offset_m`` is
(start x, start y, lowest z); the start lies on the ground-truth lattice so that the ground truth
is the file's voxels shifted by whole voxels. A mesh's coordinates within :data:`LATTICE_SNAP_M`
of a voxel boundary (the lifted frame's) count as on it, so that the file's float precision does
not decide the voxels of its faces on the lattice (:mod:`nbv_gym.worlds.groundtruth`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.errors import ConfigError
from nbv_gym.worlds import shapes
from nbv_gym.worlds.groundtruth import GroundTruth, surface_voxels
from nbv_gym.worlds.scenes.files import SceneFileError, check_size, read_mesh, to_metres_z_up
from nbv_gym.worlds.scenes.spec import SceneSpec

#: The added ground plane reaches this far beyond the scene's footprint, metres (the procedural
#: worlds' 64 m ground around their 60 m window leaves 2 m too).
GROUND_MARGIN_M = 2.0
#: The smallest window, metres, a square around the start: the benchmark worlds' 60 m, so that a
#: small scene keeps the benchmark's goal grid (and an agent's action space) and the added
#: ground covers all of it (the discovered fraction counts the goal grid's ground).
MIN_WINDOW_M = 60.0
#: Heights above the ground (metres) where a ground-truth voxel blocks a start: from above the
#: lidar's near-return filter to above the sensor (a canopy higher up does not).
START_BAND_M = (0.3, 3.0)
#: Cell of the start search, metres.
START_CELL_M = 0.5
#: A mesh coordinate this close to a voxel boundary lies on it, metres: far below any scan's
#: accuracy, and above the rounding of float32 coordinates up to 8 km from the file's origin.
LATTICE_SNAP_M = 1e-3


@dataclass(frozen=True)
class SceneFrame:
    """Where a scene world lies: ``window_m`` (x_min, y_min, x_max, y_max) the footprint of the
    scene's geometry, grown to :data:`MIN_WINDOW_M` around the start, ``ground_xy_m`` ((x_min, y_min), (x_max, y_max)) where the robot may
    stand, and ``offset_m`` (3,) the file-frame point (metres, z up) that is the world's
    origin."""

    window_m: tuple[float, float, float, float]
    ground_xy_m: tuple[tuple[float, float], tuple[float, float]]
    offset_m: tuple[float, float, float]


@dataclass(frozen=True)
class BuiltScene:
    """A scene in the world frame: ``vertices`` (V, 3) float32 metres and ``faces`` (F, 3) int32
    the lidar hits (the scene's ``scene_faces`` first, then any added ground), its
    ``ground_truth`` and its ``frame``."""

    vertices: FloatArray
    faces: IntArray
    scene_faces: int
    ground_truth: GroundTruth
    frame: SceneFrame


def build_scene(spec: SceneSpec, resolution_m: float) -> BuiltScene:
    """The scene of ``spec`` in the world frame, its ground truth at ``resolution_m`` metres."""
    surface = scene_surface(spec, resolution_m)
    vertices, truth, frame = place(spec, surface, resolution_m)
    faces = surface.faces
    scene_faces = len(faces)
    if spec.scene.ground == "add":
        (x0, y0), (x1, y1) = frame.ground_xy_m
        plane = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        square = np.array([[0, 1, 2], [0, 2, 3]])
        vertices, faces = shapes.concatenate([(vertices, faces), (plane, square)])
    return BuiltScene(
        vertices.astype(np.float32), faces.astype(np.int32), scene_faces, truth, frame
    )


@dataclass(frozen=True)
class Surface:
    """What a scene file gives: ``vertices`` (V, 3) float64 metres, z up, file frame, and
    ``faces`` (F, 3) the lidar hits; ``z0`` the scene's lowest z (the ground); ``voxels`` (k, 3)
    the occupied voxels of the frame lifted by ``z0`` where the file says them (a cloud), None
    where they are the faces' (a mesh)."""

    vertices: FloatArray
    faces: IntArray
    z0: float
    voxels: IntArray | None = None


def scene_surface(spec: SceneSpec, resolution_m: float) -> Surface:
    """The :class:`Surface` of the scene file of ``spec``."""
    scene = spec.scene
    if scene.kind == "cloud":
        from nbv_gym.worlds.scenes.clouds import cloud_surface

        return Surface(*cloud_surface(spec.path, scene.scale, scene.up, resolution_m))
    vertices, faces = read_mesh(spec.path)
    vertices = to_metres_z_up(vertices, scene.scale, scene.up)
    check_size(spec.path, vertices, scene.scale)
    return Surface(vertices, faces, float(vertices[:, 2].min()))


def place(
    spec: SceneSpec, surface: Surface, resolution_m: float
) -> tuple[FloatArray, GroundTruth, SceneFrame]:
    """The vertices in the world frame, the ground truth and the frame of a scene surface."""
    lifted = surface.vertices - [0.0, 0.0, surface.z0]
    if surface.voxels is None:
        truth = surface_voxels(lifted, surface.faces, resolution_m, LATTICE_SNAP_M)
    else:
        truth = GroundTruth(surface.voxels.astype(np.int32), resolution_m)
    if len(truth.voxels) == 0:
        raise SceneFileError(
            spec.path, "the scene has no ground truth: every face lies in the ground plane at "
            "its lowest point or has no area, so there is nothing to map (a world needs "
            "surfaces above the ground)"
        )  # fmt: skip
    low, high = lifted[:, :2].min(axis=0), lifted[:, :2].max(axis=0)
    start = _start(spec, truth, low, high)
    shift = np.rint(np.asarray(start) / resolution_m).astype(np.int64)
    offset = np.append(shift * resolution_m, 0.0)
    truth = GroundTruth((truth.voxels - np.append(shift, 0)).astype(np.int32), resolution_m)
    low = np.minimum(low - offset[:2], -MIN_WINDOW_M / 2)
    high = np.maximum(high - offset[:2], MIN_WINDOW_M / 2)
    margin = GROUND_MARGIN_M if spec.scene.ground == "add" else 0.0
    frame = SceneFrame(
        (float(low[0]), float(low[1]), float(high[0]), float(high[1])),
        ((float(low[0] - margin), float(low[1] - margin)),
         (float(high[0] + margin), float(high[1] + margin))),
        (float(offset[0]), float(offset[1]), surface.z0),
    )  # fmt: skip
    return lifted - offset, truth, frame


def _start(spec: SceneSpec, truth: GroundTruth, low: FloatArray, high: FloatArray):
    """The start (x, y), file frame: the given ``start_m``, checked, or the free point nearest
    the footprint's centre; ConfigError when there is none."""
    scene = spec.scene
    origin, clearance = _clearance(truth, low, high)
    if scene.start_m is not None:
        index = np.floor((np.asarray(scene.start_m) - origin) / START_CELL_M).astype(int)
        inside = np.all(index >= 0) and np.all(index < clearance.shape)
        room = clearance[tuple(index)] if inside else -1.0
        if room < scene.clear_radius_m:
            where = "outside the scene's footprint" if not inside else f"{room:.2g} m from it"
            raise ConfigError(
                f"scene.start_m {list(scene.start_m)}: the start must lie in the footprint with "
                f"no obstacle within scene.clear_radius_m = {scene.clear_radius_m:g} m; the "
                f"nearest obstacle is {where}. Move the start or lower clear_radius_m"
            )
        return tuple(scene.start_m)
    free = clearance >= scene.clear_radius_m
    if not free.any():
        raise ConfigError(
            f"{spec.name}: no point of the scene has {scene.clear_radius_m:g} m of free ground "
            f"around it (scene.clear_radius_m); give scene.start_m or lower clear_radius_m — "
            f'or, if the scene lies on its side, set its up axis (scene.up = "z" or "y", '
            f"now {scene.up!r}; nbv-gym worlds import --up)"
        )
    centres = origin + (np.argwhere(free) + 0.5) * START_CELL_M
    best = np.argmin(np.hypot(*(centres - (low + high) / 2).T))
    return tuple(centres[best])


def _clearance(truth: GroundTruth, low: FloatArray, high: FloatArray):
    """Cells of :data:`START_CELL_M` over the footprint: their origin (file frame) and each
    cell's distance (metres, conservative by a cell's half diagonal) to the nearest cell
    holding a ground-truth voxel in :data:`START_BAND_M`; cells on the footprint's edge count
    as blocked (a start must see the scene around it)."""
    from scipy.ndimage import distance_transform_edt

    origin = np.floor(low / START_CELL_M) * START_CELL_M
    shape = np.maximum(np.ceil((high - origin) / START_CELL_M).astype(int), 1)
    voxels = truth.voxels
    height = (voxels[:, 2] + 0.5) * truth.res
    band = voxels[(height >= START_BAND_M[0]) & (height <= START_BAND_M[1])]
    index = np.floor(((band[:, :2] + 0.5) * truth.res - origin) / START_CELL_M).astype(int)
    index = index[np.all((index >= 0) & (index < shape), axis=1)]
    free = np.ones(tuple(shape + 2), dtype=bool)
    free[0, :] = free[-1, :] = free[:, 0] = free[:, -1] = False
    free[index[:, 0] + 1, index[:, 1] + 1] = False
    distance = distance_transform_edt(free)[1:-1, 1:-1] * START_CELL_M
    return origin, distance - START_CELL_M * np.sqrt(0.5)
