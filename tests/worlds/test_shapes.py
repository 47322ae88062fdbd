"""Asset meshes are closed solids of the analytic size."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from nbv_gym.worlds import shapes


@pytest.mark.parametrize(
    ("mesh", "volume", "extent"),
    [
        (shapes.cuboid(), 2 * 2 * 2, (2, 2, 2)),
        (shapes.cross(), 2 * (2 * 0.5 * 2) - 0.5 * 0.5 * 2, (2, 2, 2)),
    ],
    ids=["cuboid", "cross"],
)
def test_prisms_are_watertight_with_the_analytic_volume(mesh, volume, extent):
    solid = trimesh.Trimesh(*mesh)
    assert solid.is_watertight and solid.is_winding_consistent
    assert solid.volume == pytest.approx(volume)
    np.testing.assert_allclose(solid.extents, extent)


def test_helicoid_is_a_thin_closed_ribbon_on_a_shrinking_cone():
    assert trimesh.Trimesh(*shapes.helicoid()).is_watertight
    solid = trimesh.Trimesh(*shapes.helicoid(samples_per_turn=1024))
    # ribbon volume → length × width × thickness; its centre line winds 3 times up a cone
    t = np.linspace(0, 1, 20001)
    radius = 1.0 - 0.8 * t
    path = np.column_stack(
        [radius * np.cos(6 * np.pi * t), radius * np.sin(6 * np.pi * t), 2.5 * t]
    )
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert solid.volume == pytest.approx(length * 0.3 * 0.02, rel=0.005)
    assert solid.bounds[0, 2] == pytest.approx(0.0)


def test_placing_scales_turns_and_moves():
    vertices, _ = shapes.place(shapes.cuboid(), np.array([3.0, -1.0]), np.pi / 2, 1.2, 0.5)
    np.testing.assert_allclose(vertices.min(axis=0), [3 - 1.2, -1 - 1.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(vertices.max(axis=0), [3 + 1.2, -1 + 1.2, 1.0], atol=1e-12)


def test_transport_frames_are_orthonormal_and_follow_the_path():
    t = np.linspace(0, 4 * np.pi, 200)
    path = np.column_stack([np.cos(t), np.sin(t), 0.3 * t])
    u, v = shapes.transport_frames(path)
    tangent = np.cross(u, v)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", u, v), 0, atol=1e-9)
    forward = np.gradient(path, axis=0)
    assert np.all(np.einsum("ij,ij->i", tangent, forward) > 0)
