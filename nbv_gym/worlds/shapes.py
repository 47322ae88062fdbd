"""Triangle meshes of the benchmark's asset types, built from two primitives: an extruded
star-shaped polygon (cuboids, crosses) and a swept profile (helicoid ribbons, tree branches).

A mesh here is a pair ``(vertices (V, 3) float64 metres, faces (F, 3) int64)`` with outward,
counter-clockwise faces. Asset meshes stand on z = 0 around the vertical axis through the origin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from nbv_gym.core import libm
from nbv_gym.core.arrays import FloatArray, IntArray

Mesh = tuple[FloatArray, IntArray]


def prism(polygon: FloatArray, height_m: float) -> Mesh:
    """A closed prism: the (k, 2) counter-clockwise ``polygon``, star-shaped about the origin,
    extruded from z = 0 to ``height_m``. Caps are fans around the origin."""
    polygon = np.asarray(polygon, dtype=float)
    k = len(polygon)
    bottom = np.column_stack([polygon, np.zeros(k)])
    top = np.column_stack([polygon, np.full(k, height_m)])
    centres = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, height_m]])
    vertices = np.vstack([bottom, top, centres])
    i = np.arange(k)
    j = (i + 1) % k
    sides = np.vstack([np.column_stack([i, j, k + j]), np.column_stack([i, k + j, k + i])])
    bottom_cap = np.column_stack([np.full(k, 2 * k), j, i])
    top_cap = np.column_stack([np.full(k, 2 * k + 1), k + i, k + j])
    return vertices, np.vstack([sides, bottom_cap, top_cap])


def sweep(
    path: FloatArray,
    u: FloatArray,
    v: FloatArray,
    profile: FloatArray,
    scale: FloatArray | None = None,
    cap_start: bool = True,
    cap_end: bool = True,
) -> Mesh:
    """A tube: the (k, 2) counter-clockwise ``profile`` placed at each of the (m, 3) ``path``
    points in the plane spanned by the (m, 3) unit vectors ``u`` and ``v`` (with ``u × v`` along
    the path), scaled by ``scale`` (m,), and joined ring to ring. Caps are fans around the path
    end points."""
    path = np.asarray(path, dtype=float)
    m, k = len(path), len(profile)
    scale = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
    offsets = profile[None, :, :1] * u[:, None, :] + profile[None, :, 1:] * v[:, None, :]
    rings = path[:, None, :] + scale[:, None, None] * offsets
    vertices: list[FloatArray] = [rings.reshape(-1, 3)]
    ring = np.arange(m - 1)[:, None] * k
    i = np.arange(k)[None, :]
    j = (i + 1) % k
    a, b, c, d = ring + i, ring + j, ring + k + j, ring + k + i
    faces = [np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)]
    i, j = i.ravel(), j.ravel()
    if cap_start:
        vertices.append(path[:1])
        faces.append(np.column_stack([np.full(k, m * k), j, i]))
    if cap_end:
        centre = m * k + int(cap_start)
        vertices.append(path[-1:])
        faces.append(np.column_stack([np.full(k, centre), (m - 1) * k + i, (m - 1) * k + j]))
    return np.vstack(vertices), np.vstack(faces).astype(np.int64)


def transport_frames(path: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotation-minimising frames ``(u, v)``, each (m, 3), along an (m, 3) polyline: ``u`` and
    ``v`` are unit, orthogonal to each other and to the local tangent, with ``u × v`` forward."""
    tangents = _tangents(path)
    u = np.empty_like(tangents)
    u[0] = _any_perpendicular(tangents[0])
    for n in range(1, len(path)):
        w = u[n - 1] - (u[n - 1] * tangents[n]).sum() * tangents[n]  # no BLAS dot: same bits
        norm = np.sqrt((w * w).sum())  # on every CPU (np.linalg.norm of a vector is a BLAS dot)
        u[n] = w / norm if norm > 1e-9 else _any_perpendicular(tangents[n])
    return u, np.cross(tangents, u)


def regular_polygon(k: int, radius: float = 1.0) -> FloatArray:
    """(k, 2) counter-clockwise vertices of a regular k-gon of circumradius ``radius``."""
    angle = np.arange(k) * (2 * np.pi / k)
    return radius * np.column_stack([libm.cos(angle), libm.sin(angle)])


def cuboid(size_m: float = 2.0, height_m: float = 2.0) -> Mesh:
    """A box of ``size_m`` × ``size_m`` footprint and ``height_m`` height."""
    h = size_m / 2
    return prism(np.array([[-h, -h], [h, -h], [h, h], [-h, h]]), height_m)


def cross(length_m: float = 2.0, width_m: float = 0.5, height_m: float = 2.0) -> Mesh:
    """A plus-shaped prism: two ``length_m`` × ``width_m`` bars crossing at their centres."""
    a, w = length_m / 2, width_m / 2
    corners = [(a, -w), (a, w), (w, w), (w, a), (-w, a), (-w, w),
               (-a, w), (-a, -w), (-w, -w), (-w, -a), (w, -a), (w, -w)]  # fmt: skip
    return prism(np.array(corners, dtype=float), height_m)


def helicoid(
    turns: float = 3.0,
    height_m: float = 2.5,
    radius_base_m: float = 1.0,
    radius_top_m: float = 0.2,
    width_m: float = 0.3,
    thickness_m: float = 0.02,
    samples_per_turn: int = 64,
) -> Mesh:
    """A thin ribbon winding ``turns`` times up a cone whose radius shrinks from
    ``radius_base_m`` to ``radius_top_m`` over ``height_m``. The ribbon lies in the cone's
    surface, ``width_m`` wide across its centre line and ``thickness_m`` thick; a closed,
    watertight solid."""
    t = np.linspace(0.0, 1.0, int(np.ceil(turns * samples_per_turn)) + 1)
    theta = 2 * np.pi * turns * t
    radius = radius_base_m + (radius_top_m - radius_base_m) * t
    radial = np.column_stack([libm.cos(theta), libm.sin(theta), np.zeros_like(t)])
    path = radius[:, None] * radial + np.column_stack([np.zeros((len(t), 2)), height_m * t])
    tangent = _tangents(path)
    slant = (radius_top_m - radius_base_m) * radial + [0.0, 0.0, height_m]
    across = slant - np.einsum("ij,ij->i", slant, tangent)[:, None] * tangent
    across /= np.linalg.norm(across, axis=1, keepdims=True)  # in the cone, across the path
    normal = np.cross(across, tangent)
    profile = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [thickness_m / 2, width_m / 2]
    vertices, faces = sweep(path, normal, across, profile)
    vertices[:, 2] -= vertices[:, 2].min()
    return vertices, faces


def concatenate(meshes: Sequence[Mesh]) -> Mesh:
    """One mesh holding all ``meshes``."""
    offsets = np.cumsum([0] + [len(v) for v, _ in meshes[:-1]])
    vertices = np.vstack([v for v, _ in meshes])
    faces = np.vstack([f + o for (_, f), o in zip(meshes, offsets, strict=True)])
    return vertices, faces.astype(np.int64)


def place(mesh: Mesh, xy: FloatArray, yaw: float, scale_xy: float, scale_z: float) -> Mesh:
    """``mesh`` scaled by (``scale_xy``, ``scale_xy``, ``scale_z``), turned by ``yaw`` radians
    about the vertical axis and moved to ground position ``xy`` (2,) metres."""
    vertices, faces = mesh
    c, s = math.cos(yaw), math.sin(yaw)
    scaled = vertices * [scale_xy, scale_xy, scale_z]
    x, y = scaled[:, 0], scaled[:, 1]  # turned elementwise: a matrix product's BLAS kernel
    turned = np.stack((c * x - s * y, s * x + c * y, scaled[:, 2]), axis=1)  # varies by CPU
    return turned + [xy[0], xy[1], 0.0], faces


def footprint_radius(mesh: Mesh) -> float:
    """The largest horizontal distance of a vertex from the vertical axis, metres."""
    return float(np.hypot(mesh[0][:, 0], mesh[0][:, 1]).max())


def ground_plane(size_m: float) -> Mesh:
    """A ``size_m`` × ``size_m`` square at z = 0 centred on the origin, facing up."""
    h = size_m / 2
    vertices = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
    return vertices, np.array([[0, 1, 2], [0, 2, 3]])


def _tangents(path: FloatArray) -> FloatArray:
    tangents = np.gradient(np.asarray(path, dtype=float), axis=0)
    return tangents / np.linalg.norm(tangents, axis=1, keepdims=True)


def _any_perpendicular(direction: FloatArray) -> FloatArray:
    helper = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    w = np.cross(direction, helper)
    return w / np.sqrt((w * w).sum())  # not np.linalg.norm: a BLAS dot for a vector
