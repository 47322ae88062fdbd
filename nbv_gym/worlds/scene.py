"""Embree ray casting against a triangle mesh (embreex): the scene a world builds for its lidar,
in a module of its own so that worlds and the lidar depend on it, not on each other."""

from __future__ import annotations

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray


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
        origins = np.ascontiguousarray(np.broadcast_to(origins, directions.shape), np.float32)
        result = self._scene.run(origins, np.ascontiguousarray(directions, np.float32), output=1)
        distance = result["tfar"].astype(np.float64)
        distance[result["geomID"] < 0] = np.inf
        return distance
