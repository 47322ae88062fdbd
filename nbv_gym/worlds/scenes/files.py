"""Reading a scene file into metres, z up: a triangle mesh (trimesh) or a point cloud, checked.

Every problem raises :class:`SceneFileError`, one line naming the file, what is wrong and what to
do: an unreadable or empty file, non-finite coordinates, a scene whose size after ``scale`` is
not a plausible outdoor scene in metres (the usual sign of millimetres or kilometres), or more
triangles or points than the stated bounds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.errors import DataFileError
from nbv_gym.core.grid import MAX_WINDOW_M

#: The largest mesh read (triangles) and point cloud (points): ~1.3 GB of working memory for
#: either at these sizes (docs/scenes.md).
MAX_TRIANGLES = 20_000_000
MAX_POINTS = 50_000_000
#: The plausible horizontal size of a scene after ``scale``, metres: from a room (1 m) to the
#: largest window the goal grid grows to.
MIN_SIZE_M = 1.0
MAX_SIZE_M = MAX_WINDOW_M


class SceneFileError(DataFileError):
    """A scene file cannot make a world; the message names it and says what to do."""

    def __init__(self, path: str | Path, problem: str):
        super().__init__(f"{path}: {problem}")


def read_mesh(path: Path) -> tuple[FloatArray, IntArray]:
    """(V, 3) float64 vertices (file units, the file's axes) and (F, 3) int64 triangles of the
    mesh in ``path`` (a multi-mesh GLB/GLTF scene flattened with its node transforms); only the
    vertices a triangle uses, in the file's order (an unused vertex is no part of the scene)."""
    import trimesh

    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as error:  # trimesh raises many types for a broken file
        problem = f"not a readable mesh ({type(error).__name__}: {error})"
        raise SceneFileError(path, problem) from None
    vertices = np.asarray(getattr(mesh, "vertices", np.empty((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(mesh, "faces", np.empty((0, 3))), dtype=np.int64)
    if len(faces) == 0:
        raise SceneFileError(path, "the mesh holds no triangles; export it with its faces")
    if len(faces) > MAX_TRIANGLES:
        raise SceneFileError(
            path, f"{len(faces):,} triangles, more than {MAX_TRIANGLES:,}; decimate it first"
        )
    outside = (faces < 0) | (faces >= len(vertices))
    if outside.any():
        raise SceneFileError(
            path,
            f"a triangle names vertex {int(faces[outside][0])}, but the file holds "
            f"{len(vertices):,} vertices (0 … {len(vertices) - 1:,}); repair the file",
        )
    used, faces = np.unique(faces, return_inverse=True)
    vertices = vertices[used]
    check_finite(path, vertices, "vertices")
    return vertices, faces.reshape(-1, 3)


def check_finite(path: Path, points: FloatArray, what: str) -> None:
    """SceneFileError unless every coordinate of ``points`` (n, 3) is finite."""
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise SceneFileError(
            path,
            f"{int(bad.sum()):,} of {len(points):,} {what} are NaN or infinite (e.g. "
            f"{points[bad][0].tolist()}); repair or remove them",
        )


def to_metres_z_up(points: FloatArray, scale: float, up: str) -> FloatArray:
    """(n, 3) ``points`` scaled to metres and turned so that the file's ``up`` axis ("z" or "y")
    is +z (y up: (x, y, z) → (x, -z, y), a right-handed quarter turn about x)."""
    points = np.asarray(points, dtype=np.float64) * scale
    if up == "y":
        points = np.column_stack([points[:, 0], -points[:, 2], points[:, 1]])
    return points


def check_size(path: Path, points: FloatArray, scale: float) -> None:
    """SceneFileError unless the horizontal extent of ``points`` (metres) is plausible."""
    size = float(np.ptp(points[:, :2], axis=0).max())
    if MIN_SIZE_M <= size <= MAX_SIZE_M:
        return
    hint = "millimetres? try scale = 0.001" if size > MAX_SIZE_M else "kilometres? try scale = 1000"
    raise SceneFileError(
        path,
        f"the scene is {size:,.4g} m across at scale = {scale:g}, outside {MIN_SIZE_M:g}–"
        f"{MAX_SIZE_M:g} m ({hint}; or check [scene] up)",
    )
