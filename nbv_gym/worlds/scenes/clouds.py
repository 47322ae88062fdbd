"""Point-cloud scenes: occupied voxels from the points, and a surface the lidar hits that matches
them.

Ground truth: the voxels of the 0.1 m lattice that hold at least one point (after ``scale``, ``up``
and lifting the lowest point to z = 0) — the occupied voxels of a dense scan, as the benchmark's
paper scores a real map against a Total Station cloud.

What the lidar hits: every face an occupied voxel shares with an empty one, set back into the
occupied voxel by :data:`INSET` of a voxel and spanning the whole voxel side. Why this surface:

- a ray stops inside an occupied voxel and never in an empty one, so the map built from these
  returns sees the ground truth's voxels and nothing else (a surface through the points — a
  Poisson or ball-pivoting reconstruction — would pass through empty voxels next to sparse
  points, and needs normals and parameters a scan does not carry);
- a face lying on the voxel boundary would put half of the noisy returns (σ = 8 mm) in the empty
  voxel in front; set back by 2.5 cm (3 σ) they stay in the occupied one;
- whole sides, joined edge to edge with their neighbours', leave no slot between adjacent voxels
  (only an ε × ε sliver at a convex edge, which a ray crosses without a hit only when it also
  leaves through the empty side);
- only exposed faces: interior voxels add nothing, so the triangles grow with the surface area
  (~6–8 per occupied voxel of a thin scanned surface), not with the volume.

Cost, measured (docs/scenes.md): memory ~ 24 bytes per point while reading, then ~150 bytes per
occupied voxel for the surface; a 5 M-point cloud builds in seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.errors import MissingExtraError
from nbv_gym.worlds.scenes.files import (
    MAX_POINTS,
    SceneFileError,
    check_finite,
    check_size,
    to_metres_z_up,
)

#: How far each exposed face is set back into its voxel, as a fraction of the voxel side.
INSET = 0.25
#: The largest point-cloud file read, bytes (about :data:`MAX_POINTS` points of x, y, z floats
#: plus a few attributes).
MAX_CLOUD_BYTES = 4 << 30
#: The six face directions: (axis, sign).
_FACES = [(axis, sign) for axis in range(3) for sign in (-1, 1)]


def read_cloud(path: Path) -> FloatArray:
    """(n, 3) float64 points of a PLY, PCD, XYZ (text) or LAS/LAZ file (file units, file axes),
    checked: not empty, not larger than the bounds, finite."""
    from nbv_gym.core.pointclouds import PointCloudError, read_points

    if path.stat().st_size > MAX_CLOUD_BYTES:
        raise SceneFileError(
            path, f"{path.stat().st_size / 2**30:.1f} GiB, larger than "
            f"{MAX_CLOUD_BYTES / 2**30:.0f} GiB; thin the cloud first (e.g. a 1 cm voxel grid)"
        )  # fmt: skip
    try:
        points = _read_las(path) if path.suffix.lower() in (".las", ".laz") else read_points(path)
    except PointCloudError as error:
        raise SceneFileError(path, str(error).removeprefix(f"{path}: ")) from None
    if len(points) == 0:
        raise SceneFileError(path, "the cloud holds no points")
    if len(points) > MAX_POINTS:
        raise SceneFileError(
            path, f"{len(points):,} points, more than {MAX_POINTS:,}; thin the cloud first"
        )
    check_finite(path, points, "points")
    return points


def _read_las(path: Path) -> FloatArray:
    try:
        import laspy
    except ImportError:
        raise MissingExtraError("laspy", "las") from None
    try:
        with laspy.open(path) as reader:
            if reader.header.point_count > MAX_POINTS:
                raise SceneFileError(
                    path, f"{reader.header.point_count:,} points, more than {MAX_POINTS:,}; "
                    "thin the cloud first"
                )  # fmt: skip
            data = reader.read()
    except SceneFileError:
        raise
    except Exception as error:  # laspy raises its own and numpy's errors on a broken file
        raise SceneFileError(path, f"not a readable LAS/LAZ file ({error})") from None
    return np.column_stack([data.x, data.y, data.z]).astype(np.float64)


def cloud_voxels(points: FloatArray, resolution_m: float) -> IntArray:
    """(k, 3) int64 lattice indices (sorted, unique) of the voxels holding a point (metres)."""
    return np.unique(np.floor(points / resolution_m).astype(np.int64), axis=0)


def world_voxels(points: FloatArray, frame: dict, resolution_m: float) -> IntArray:
    """(k, 3) int64 lattice indices, world frame, of the voxels holding a point of ``points``
    (n, 3), given in a scene file's units and axes: the file's scale and up axis, the lift of
    its lowest point to z = 0 and the shift to its start, by whole voxels, of ``frame`` (a
    scene world's :meth:`~nbv_gym.worlds.world.World.file_frame`) — the ground truth a cloud
    world makes of them."""
    metres = to_metres_z_up(points, frame["scale"], frame["up"])
    offset = np.asarray(frame["offset_m"], np.float64)
    metres[:, 2] -= offset[2]
    shift = np.rint(offset[:2] / resolution_m).astype(np.int64)
    return cloud_voxels(metres, resolution_m) - np.append(shift, 0)


def cloud_surface(path: Path, scale: float, up: str, resolution_m: float):
    """The scene of a cloud: (V, 3) float64 vertices (metres, z up, file frame), (F, 3) int64
    triangles (the exposed voxel faces), the lowest point's z and the occupied voxels (k, 3)
    int64 of the frame lifted by it."""
    points = to_metres_z_up(read_cloud(path), scale, up)
    check_size(path, points, scale)
    z0 = float(points[:, 2].min())
    points[:, 2] -= z0
    voxels = cloud_voxels(points, resolution_m)
    del points
    vertices, faces = exposed_faces(voxels, resolution_m)
    vertices[:, 2] += z0
    return vertices, faces, z0, voxels


def exposed_faces(voxels: IntArray, resolution_m: float) -> tuple[FloatArray, IntArray]:
    """(4m, 3) float64 vertices and (2m, 3) int64 triangles of the m faces the (k, 3) ``voxels``
    share with an empty voxel, each set back by :data:`INSET` · ``resolution_m`` into its voxel
    (see the module doc); outward-facing."""
    low = voxels.min(axis=0) - 1
    codes = _codes(voxels - low)
    quads = []
    for axis, sign in _FACES:
        step = np.zeros(3, np.int64)
        step[axis] = sign
        neighbour = _codes(voxels - low + step)
        found = np.searchsorted(codes, neighbour)
        found = np.minimum(found, len(codes) - 1)
        exposed = voxels[codes[found] != neighbour]
        quads.append(_quads(exposed, axis, sign, resolution_m))
    corners = np.concatenate(quads)  # (m, 4, 3)
    m = len(corners)
    first = 4 * np.arange(m)[:, None]
    faces = np.concatenate([first + [0, 1, 2], first + [0, 2, 3]])
    return corners.reshape(-1, 3), faces


def _codes(index: IntArray) -> IntArray:
    """One sorted-compatible int64 per (k, 3) non-negative index (21 bits an axis)."""
    return (index[:, 0] << 42) | (index[:, 1] << 21) | index[:, 2]


def _quads(voxels: IntArray, axis: int, sign: int, resolution_m: float) -> FloatArray:
    """(m, 4, 3) corners of the face of each voxel on side ``sign`` of ``axis``, set back, in
    counter-clockwise order seen from outside."""
    u, v = (axis + 1) % 3, (axis + 2) % 3
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    if sign < 0:
        square = square[::-1]
    corners = np.empty((len(voxels), 4, 3))
    offset = (1.0 - INSET) if sign > 0 else INSET
    corners[:, :, axis] = (voxels[:, axis, None] + offset) * resolution_m
    corners[:, :, u] = (voxels[:, u, None] + square[None, :, 0]) * resolution_m
    corners[:, :, v] = (voxels[:, v, None] + square[None, :, 1]) * resolution_m
    return corners
