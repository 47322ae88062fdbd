"""Ground truth: the voxels of a fixed lattice through which a mesh surface passes (docs/protocol.md#worlds).

The lattice is the project's voxel convention anchored at the origin: voxel ``(i, j, k)`` covers
the half-open box ``[i, i + 1) × [j, j + 1) × [k, k + 1)`` times ``res``, so that every point lies
in exactly one voxel. A voxel is occupied iff a triangle of the surface meets that box (exact
triangle–box separating-axis test; a solid's interior marks nothing). A face lying on a voxel
boundary therefore occupies the voxels on its upper side (+x, +y or +z), never both sides and
never neither — the voxels its points fall in, as a point cloud's points do. One exception:
faces lying in the ground plane z = 0 (the bases of assets standing on the ground, a scene's
floor at its lowest point) mark nothing — the ground is not ground truth.

A scene read from a file snaps its coordinates within ``snap_m`` of a boundary onto it first
(:func:`surface_voxels`), so that the file's float precision and a translation by whole voxels
do not decide which voxels a face on the lattice occupies.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from nbv_gym.core.arrays import BoolArray, FloatArray, IntArray
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.grid import GridSpec


@dataclass(frozen=True)
class GroundTruth:
    """Occupied surface voxels: ``voxels`` (n, 3) int32 lattice indices (sorted, unique) at
    resolution ``res`` metres."""

    voxels: IntArray
    res: float

    @property
    def bounds(self) -> tuple[FloatArray, FloatArray]:
        """(low (3,), high (3,)) float: the bounding box of the occupied voxels, metres."""
        return self.voxels.min(axis=0) * self.res, (self.voxels.max(axis=0) + 1) * self.res

    def points(self) -> FloatArray:
        """(n, 3) float64 voxel centres, metres."""
        return (self.voxels + 0.5) * self.res

    def occupancy(self, grid: GridSpec) -> BoolArray:
        """Bool array of ``grid.shape``: which cells of ``grid`` are occupied. ``grid`` must have
        this ground truth's resolution and lie on its lattice."""
        grid_mask = np.zeros(grid.shape, dtype=bool)
        grid_mask[tuple(self.grid_voxels(grid).T)] = True
        return grid_mask

    def grid_voxels(self, grid: GridSpec) -> IntArray:
        """(k, 3) int64 indices into ``grid`` of its occupied cells, in C order — what
        ``np.argwhere(self.occupancy(grid))`` gives, without the dense grid. ``grid`` must have
        this ground truth's resolution and lie on its lattice."""
        offset = np.asarray(grid.origin) / self.res
        if not np.isclose(grid.res, self.res) or not np.allclose(offset, np.rint(offset)):
            raise ConfigError(
                f"Grid (origin {grid.origin}, res {grid.res} m) does not lie on the ground "
                f"truth's {self.res} m lattice: use that res and an origin on its multiples."
            )
        index = self.voxels - np.rint(offset).astype(np.int64)  # sorted rows stay sorted
        return index[grid.contains(index)]


#: Voxels of one slab of the marking mask in :func:`surface_voxels` (bytes: one bool each).
SLAB_VOXELS = 1 << 27


def surface_voxels(
    vertices: FloatArray, faces: IntArray, res: float, snap_m: float = 0.0
) -> GroundTruth:
    """The :class:`GroundTruth` of a triangle mesh: (V, 3) ``vertices`` metres, (F, 3) ``faces``
    (see the module doc for the rule). ``snap_m`` > 0: coordinates closer than that (metres) to
    a voxel boundary are taken to lie on it (0: as given, the procedural worlds' case).

    The voxels are marked in x slabs of at most :data:`SLAB_VOXELS` (the mesh's bounding box of a
    500 m world at 0.1 m would be gigabytes), each slab read out before the next is marked."""
    triangles = np.asarray(vertices, np.float64)[faces]
    triangles /= res  # in place: the same values as a new array, without a second copy
    if snap_m > 0:
        nearest = np.rint(triangles)
        on = np.abs(triangles - nearest) < snap_m / res
        triangles[on] = nearest[on]
    triangles = triangles[~(triangles[:, :, 2] == 0.0).all(axis=1)]  # faces on the ground
    if len(triangles) == 0:
        return GroundTruth(np.empty((0, 3), np.int32), float(res))
    low = np.floor(triangles.reshape(-1, 3).min(axis=0)).astype(np.int64) - 1
    high = np.floor(triangles.reshape(-1, 3).max(axis=0)).astype(np.int64) + 2
    triangles -= low
    shape = high - low
    width = max(1, SLAB_VOXELS // int(shape[1] * shape[2]))
    x_first = np.floor(triangles[:, :, 0].min(axis=1))
    x_last = np.floor(triangles[:, :, 0].max(axis=1))
    parts = []
    for x0 in range(0, int(shape[0]), width):
        mask = np.zeros((min(width, int(shape[0]) - x0), shape[1], shape[2]), dtype=np.bool_)
        inside = np.flatnonzero((x_last >= x0) & (x_first < x0 + len(mask)))
        _mark_triangles(triangles, inside, mask, x0)
        parts.append(np.argwhere(mask) + low + [x0, 0, 0])
    return GroundTruth(np.concatenate(parts).astype(np.int32), float(res))


@numba.njit(cache=True)
def _mark_triangles(triangles, chosen, mask, x0):
    """Mark in ``mask`` every unit voxel (half-open box) that meets one of the ``chosen`` triangles
    (coordinates in voxels), ``mask[i - x0]`` holding voxel ``i`` along x (a slab of the whole
    mask)."""
    for t in chosen:
        tri = triangles[t]
        lo = np.empty(3, np.int64)
        hi = np.empty(3, np.int64)
        for a in range(3):
            first = x0 if a == 0 else 0
            lo[a] = max(int(np.floor(tri[:, a].min())), first)
            hi[a] = min(int(np.floor(tri[:, a].max())), first + mask.shape[a] - 1)
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    if not mask[i - x0, j, k] and _overlaps(tri, i + 0.5, j + 0.5, k + 0.5):
                        mask[i - x0, j, k] = True


@numba.njit(cache=True)
def _overlaps(tri, cx, cy, cz):
    """Whether a triangle (3, 3) meets the half-open unit box [c − ½, c + ½)³ centred at (cx,
    cy, cz): the separating-axis test of Akenine-Möller on the 13 candidate axes, on each axis
    with the box's projection closed at an end the box reaches and open at one it does not."""
    v = np.empty((3, 3))
    for n in range(3):
        v[n, 0] = tri[n, 0] - cx
        v[n, 1] = tri[n, 1] - cy
        v[n, 2] = tri[n, 2] - cz
    e = np.empty((3, 3))
    for n in range(3):
        for a in range(3):
            e[n, a] = v[(n + 1) % 3, a] - v[n, a]
    for a in range(3):  # box face normals
        if min(v[0, a], v[1, a], v[2, a]) >= 0.5 or max(v[0, a], v[1, a], v[2, a]) < -0.5:
            return False
    for n in range(3):  # edge × box axis
        for a in range(3):
            axis = np.zeros(3)
            axis[(a + 1) % 3] = -e[n, (a + 2) % 3]
            axis[(a + 2) % 3] = e[n, (a + 1) % 3]
            if _separates(v, axis):
                return False
    normal = np.cross(e[0], e[1])
    return not _separates(v, normal)


@numba.njit(cache=True)
def _separates(v, axis):
    """Whether ``axis`` separates the triangle ``v`` (3, 3), box-centred, from the half-open
    box: the box projects onto [−r, r]; its lower end belongs to it iff no component of
    ``axis`` is negative (the corner reaching it has no coordinate + ½), its upper end iff none
    is positive, and a triangle touching an end the box does not reach is apart."""
    radius = 0.5 * (abs(axis[0]) + abs(axis[1]) + abs(axis[2]))
    if radius == 0.0:
        return False
    p0 = v[0, 0] * axis[0] + v[0, 1] * axis[1] + v[0, 2] * axis[2]
    p1 = v[1, 0] * axis[0] + v[1, 1] * axis[1] + v[1, 2] * axis[2]
    p2 = v[2, 0] * axis[0] + v[2, 1] * axis[1] + v[2, 2] * axis[2]
    low, high = min(p0, p1, p2), max(p0, p1, p2)
    if low > radius or high < -radius:
        return True
    positive = axis[0] > 0.0 or axis[1] > 0.0 or axis[2] > 0.0
    negative = axis[0] < 0.0 or axis[1] < 0.0 or axis[2] < 0.0
    return (low == radius and positive) or (high == -radius and negative)
