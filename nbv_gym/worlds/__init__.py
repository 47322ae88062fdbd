"""Procedural benchmark worlds: specs, asset meshes, placement, ground truth and the cache."""

from nbv_gym.worlds.groundtruth import GroundTruth, surface_voxels
from nbv_gym.worlds.spec import ASSET_TYPES, WorldSpec, benchmark_names, load_spec, parse_spec
from nbv_gym.worlds.world import World, build_world, cache_dir, load_world

__all__ = [
    "ASSET_TYPES",
    "GroundTruth",
    "World",
    "WorldSpec",
    "benchmark_names",
    "build_world",
    "cache_dir",
    "load_spec",
    "load_world",
    "parse_spec",
    "surface_voxels",
]
