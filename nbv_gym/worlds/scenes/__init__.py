"""Your own scene as a world: a mesh (OBJ, PLY, STL, OFF, GLB/GLTF) or a point cloud (PLY, PCD,
XYZ, LAS/LAZ) named by a world spec's ``[scene]`` table, built into the same :class:`World` as
the procedural worlds (docs/scenes.md)."""

from nbv_gym.worlds.scenes.spec import SceneConfig, SceneSpec

__all__ = ["SceneConfig", "SceneSpec"]
