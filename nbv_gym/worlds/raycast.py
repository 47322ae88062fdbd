"""Embree ray casting against a triangle mesh (embreex): the scene a world builds for its lidar,
in a module of its own so that worlds and the lidar depend on it, not on each other."""

from __future__ import annotations

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray

#: The distance embreex reports for a ray that hits nothing (its initial ``tfar``); no hit in a
#: world is that far.
_NO_HIT = np.float32(1e37)


class RayScene:
    """Embree ray casting against a triangle mesh (embreex).

    Args:
        vertices: (V, 3) float vertex positions, metres.
        faces: (F, 3) int vertex indices of each triangle.
    """

    def __init__(self, vertices: FloatArray, faces: IntArray):
        from embreex import mesh_construction, rtcore_scene

        self._scene = rtcore_scene.EmbreeScene()
        self._mesh = mesh_construction.TriangleMesh(
            self._scene,
            np.ascontiguousarray(vertices, dtype=np.float32),
            np.ascontiguousarray(faces, dtype=np.int32),
        )
        self.n_triangles = len(faces)
        self._arrays = (vertices, faces)

    def __getstate__(self) -> dict:
        """Pickle the mesh, not the Embree scene (a C object): unpickling rebuilds it."""
        return {"arrays": self._arrays}

    def __setstate__(self, state: dict) -> None:
        RayScene.__init__(self, *state["arrays"])

    def cast(self, origins: FloatArray, directions: FloatArray) -> FloatArray:
        """(n,) float64 distance along each (n, 3) unit direction from each (n, 3) origin to the
        first hit, ``inf`` where the ray hits nothing."""
        tfar = self._tfar(origins, directions)
        distance = tfar.astype(np.float64)
        distance[tfar >= _NO_HIT] = np.inf
        return distance

    def hits(self, origins: FloatArray, directions: FloatArray) -> tuple[IntArray, FloatArray]:
        """The rays of :meth:`cast` that hit: (k,) int64 their indices and (k,) float64 their
        distances (the finite values of :meth:`cast`, without its (n,) float64 array). Float32
        C-ordered (n, 3) ``origins`` and ``directions`` are cast without a copy."""
        tfar = self._tfar(origins, directions)
        index = np.flatnonzero(tfar < _NO_HIT)
        return index, tfar[index].astype(np.float64)

    def _tfar(self, origins: FloatArray, directions: FloatArray) -> np.ndarray:
        """(n,) float32 embreex's hit distances (no hit: its initial tfar, :data:`_NO_HIT`)."""
        origins = np.ascontiguousarray(np.broadcast_to(origins, directions.shape), np.float32)
        return self._scene.run(
            origins, np.ascontiguousarray(directions, np.float32), query="DISTANCE"
        )  # the hit distances only, without u, v and normals
