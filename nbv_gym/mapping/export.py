"""A saved map out of the package: occupied voxel centres as PLY or PCD, the whole map as OctoMap.

- ``.ply`` / ``.pcd``: the centres of the known voxels with probability ≥ ``min_probability``
  (metres, float32 as PCL's ``PointXYZ`` and most viewers expect: exact to 4e-6 m below 64 m) with
  the occupancy probability as the scalar ``probability`` (a PLY vertex property, a PCD field;
  CloudCompare shows it as a scalar field). Binary little-endian; read by plyfile, pypcd4, trimesh,
  Open3D, PCL and CloudCompare.
- ``.bt``: OctoMap's binary tree of every known voxel (``min_probability`` does not apply: free
  space is what makes an OctoMap), written by the optional ``pyoctomap``
  (``pip install "nbv-gym[octomap]"``). ``.bt`` keeps OctoMap's maximum-likelihood state (each voxel
  at a clamping bound); voxels coincide with OctoMap's because both grids sit on multiples of
  the resolution.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.core import libm
from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError

FORMATS = ("ply", "pcd", "bt")


class ExportError(NbvGymError, ValueError):
    """A map cannot be exported as asked (format, threshold, missing optional package)."""


def map_voxels(occupancy, min_probability: float = 0.5) -> tuple[FloatArray, FloatArray]:
    """(n, 3) float64 centres (metres) and (n,) float32 probabilities of the known voxels of
    an :class:`~nbv_gym.mapping.OccupancyMap` with probability ≥ ``min_probability`` (0: every
    known voxel), in (x, y, z) C order of the map's grid."""
    if not 0.0 <= min_probability <= 1.0:
        raise ExportError(f"min probability must be in [0, 1], got {min_probability}")
    from nbv_gym.mapping.probability import probabilities

    index, logodds = occupancy.voxels_at_least(min_probability)  # the written blocks only
    return occupancy.grid.centres(index), probabilities(logodds)


def export_map(occupancy, path: str | Path, min_probability: float = 0.5) -> int:
    """Write ``occupancy`` to ``path`` in the format of its suffix (see the module doc); the
    number of voxels written."""
    path = Path(path)
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in FORMATS:
        raise ExportError(f"{path}: unknown map format {path.suffix!r}; use .{', .'.join(FORMATS)}")
    if suffix == "bt":
        return _write_octomap(occupancy, path)
    from nbv_gym.core.pointclouds import write_points

    centres, probability = map_voxels(occupancy, min_probability)
    write_points(path, centres, {"probability": probability}, single=True)
    return len(centres)


def _write_octomap(occupancy, path: Path) -> int:
    """Every known voxel into a pyoctomap ``OcTree`` with the map's sensor model, as ``.bt``."""
    try:
        import pyoctomap
    except ImportError:
        raise ExportError(
            'writing OctoMap .bt files needs pyoctomap: pip install "nbv-gym[octomap]"'
        ) from None
    centres, probability = map_voxels(occupancy, 0.0)
    params = occupancy.params
    tree = pyoctomap.OcTree(occupancy.grid.res)
    tree.setProbHit(params["p_hit"])
    tree.setProbMiss(params["p_miss"])
    tree.setClampingThresMin(params["p_clamp_min"])
    tree.setClampingThresMax(params["p_clamp_max"])
    tree.setOccupancyThres(params["p_occupied"])
    logodds = libm.log(probability / (1.0 - probability)).astype(np.float32)
    values, group = np.unique(logodds, return_inverse=True)
    order = np.argsort(group, kind="stable")
    bounds = np.searchsorted(group[order], np.arange(len(values) + 1))
    for v, lo, hi in zip(values, bounds[:-1], bounds[1:], strict=True):
        tree.updateNodes(centres[order[lo:hi]], float(v), True)
    tree.updateInnerOccupancy()
    if not tree.writeBinary(str(path)):
        raise ExportError(f"{path}: OctoMap could not write the file")
    return len(centres)
