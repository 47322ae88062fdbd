"""Volumetric information gain of candidate goals: the unknown voxels and the occupancy entropy a
scan from a candidate would see, over the sight lines of the statistic NBV.

Sources: "An information gain formulation for active volumetric 3D reconstruction" (S. Isler,
R. Sabzevari, J. Delmerico, D. Scaramuzza, ICRA 2016) and "Receding horizon 'next-best-view'
planner for 3D exploration" (A. Bircher, M. Kamel, K. Alexis, H. Oleynikova, R. Siegwart,
ICRA 2016) count the unknown voxels visible from a view; "A comparison of volumetric information
gain metrics for active 3D object reconstruction" (J. Delmerico, S. Isler, R. Sabzevari,
D. Scaramuzza, Autonomous Robots 2018) sums the occupancy entropy along the visible rays.

What is counted, exactly (a cell-level approximation of the voxel rays): a candidate T sees the
cells of G (1 m) whose centre's sight line from T's sensor lies inside the lidar's vertical field
of view and range window ``[min_range_m, sensor_range_m)`` and crosses no *blocking* cell — a cell
holding an occupied voxel (p ≥ the map's occupied threshold 0.5); a blocking cell is seen itself
(the ``fov`` model of :mod:`nbv_gym.nbv.visibility`, the same sight lines and the same compiled
traversal :func:`~nbv_gym.nbv.visibility.credited_rays` as the statistic gains). Then

- ``gain_unknown(T)`` = Σ over the seen cells of the number of unknown voxels they hold;
- ``gain_entropy(T)`` = Σ over the seen cells of Σ over their voxels of the binary entropy
  H(p) = −p log₂ p − (1 − p) log₂ (1 − p) in bits (an unknown voxel, p = 0.5, holds 1 bit).

Why cells, not 0.1 m voxel rays: a voxel-level ray cast from each of ~1,140 candidates with the
lidar's angular resolution would walk ~10⁸ voxels per decision (about 1,000 × the cell traversal);
per-cell totals make a decision cost the same traversal as the statistic NBV, with the per-cell
sums kept up to date from the cells each scan touched.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from nbv_gym.core.arrays import BoolArray, FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap
from nbv_gym.nbv.config import NbvSensor
from nbv_gym.nbv.occlusion import OcclusionGrid
from nbv_gym.nbv.visibility import SightModel, credited_rays, occluder_cells, sight_lines

#: The volumetric gain layers, in the order of :attr:`VoxelTotals.table`'s columns.
VOLUMETRIC_LAYERS: tuple[str, ...] = ("gain_unknown", "gain_entropy")

#: Cells of G whose voxels are read at once (4 kB of float32 each).
CHUNK_CELLS = 4096
#: A cell blocks the sight lines iff it holds a voxel with p ≥ this (the map's occupied threshold).
BLOCKING_PROBABILITY = 0.5


class VoxelTotals:
    """Per cell of G: the number of unknown voxels and their summed binary entropy (bits), kept
    up to date from the cells each scan touched, and the blocking mask of the sight lines.

    Args:
        grid: the statistics grid G (cells a whole number of voxels, aligned to the map).
        resolution_m: the map's voxel size, metres.

    Attributes:
        table: (nx · ny · nz, 2) float64 per cell (C order): unknown voxels, entropy in bits.
        blocking: the :class:`~nbv_gym.nbv.occlusion.OcclusionGrid` of occupied cells.
    """

    def __init__(self, grid: GridSpec, resolution_m: float = MapConfig.resolution_m):
        self.grid = grid
        self.blocking = OcclusionGrid(grid, resolution_m, BLOCKING_PROBABILITY)
        self.voxels_per_cell = round(grid.res / resolution_m) ** 3
        self.table = np.empty((grid.size, 2))
        self.reset()

    def reset(self) -> None:
        """Every voxel unknown (an empty map)."""
        self.table[:] = self.voxels_per_cell
        self.blocking.reset()

    def update(self, occupancy_map: OccupancyMap, touched: BoolArray | None = None) -> None:
        """Recompute the ``touched`` (nx, ny, nz) bool cells from ``occupancy_map`` (all when
        None)."""
        self.blocking.update(occupancy_map, touched)
        touched = np.ones(self.grid.shape, bool) if touched is None else np.asarray(touched, bool)
        cells = np.argwhere(touched)
        for start in range(0, len(cells), CHUNK_CELLS):
            chunk = cells[start : start + CHUNK_CELLS]
            blocks = occupancy_map.logodds_blocks(self.grid, chunk)
            flat = np.ravel_multi_index(tuple(chunk.T), self.grid.shape)
            _block_totals(blocks.reshape(len(chunk), -1), flat, self.table)


def sight_model(sensor: NbvSensor) -> SightModel:
    """The sight lines of the volumetric gains: the ``fov`` model of ``sensor``."""
    return SightModel(
        "fov", sensor.sensor_height_m, sensor.min_range_m, sensor.sensor_range_m,
        sensor.elevation_min_rad, sensor.elevation_max_rad,
    )  # fmt: skip


def volumetric_gains(
    grid: GridSpec,
    table: FloatArray,
    blocking: BoolArray,
    candidates: BoolArray,
    sensor: NbvSensor,
) -> dict[str, np.ndarray]:
    """The volumetric gain layers of the candidates (module docstring).

    Args:
        grid: the statistics grid G (its x, y cells are the goals).
        table: (nx · ny · nz, 2) float per cell: unknown voxels, entropy in bits
            (:attr:`VoxelTotals.table`).
        blocking: (nx, ny, nz) bool cells that block the sight lines.
        candidates: (nx · ny,) or (nx, ny) bool candidate goals.
        sensor: the sensor (range window, height, field of view).

    Returns:
        ``{"gain_unknown": …, "gain_entropy": …}``, each (nx, ny) float32, 0 outside the
        candidates.
    """
    nx, ny, nz = grid.shape
    table = np.ascontiguousarray(table, np.float64)
    if table.shape != (grid.size, 2):
        raise NbvGymError(f"table must have shape ({grid.size}, 2), got {table.shape}")
    blocking = np.asarray(blocking, bool)
    if blocking.shape != grid.shape:
        raise NbvGymError(f"blocking must have G's shape {grid.shape}, got {blocking.shape}")
    candidates = np.asarray(candidates, bool).reshape(nx, ny)
    cells = np.argwhere(candidates).astype(np.int64)
    lines = sight_lines(grid, sight_model(sensor))
    sums = _sums_kernel(
        cells, occluder_cells(blocking), lines.reach, nz, lines.crossing_start,
        lines.crossing_rays, lines.dx_start, lines.dx, lines.dy, lines.k, lines.aimed, nx, ny,
        table,
    )  # fmt: skip
    out = {}
    for column, name in enumerate(VOLUMETRIC_LAYERS):
        layer = np.zeros((nx, ny), np.float32)
        layer[cells[:, 0], cells[:, 1]] = sums[:, column]
        out[name] = layer
    return out


@njit(cache=True)
def _sums_kernel(candidates, occluders, reach, nz, crossing_start, crossing_rays, dx_start, dx,
                 dy, k, aimed, nx, ny, table):  # fmt: skip
    """(m, v) float64: per candidate, the sum of the (n_cells, v) ``table`` rows of the cells it
    sees (:func:`~nbv_gym.nbv.visibility.credited_rays`, ``fov`` sight lines)."""
    m, v = candidates.shape[0], table.shape[1]
    sums = np.zeros((m, v))
    stamps = np.full(len(dx), -1, np.int64)
    rays = np.empty(len(dx), np.int64)
    for c in range(m):
        ci, cj = candidates[c, 0], candidates[c, 1]
        n = credited_rays(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, dx_start,
                          dy, aimed, nx, ny, stamps, c, rays)  # fmt: skip
        for q in range(n):
            r = rays[q]
            cell = ((ci + dx[r]) * ny + cj + dy[r]) * nz + k[r]
            for a in range(v):
                sums[c, a] += table[cell, a]
    return sums


@njit(cache=True)
def _block_totals(logodds, flat, table):
    """Write each (k, f³) float32 ``logodds`` block's unknown count (NaN) and entropy (bits) to
    ``table[flat[i]]``."""
    for i in range(logodds.shape[0]):
        unknown = 0.0
        entropy = 0.0
        for x in logodds[i]:
            if math.isnan(x):
                unknown += 1.0
                entropy += 1.0
            else:
                entropy += binary_entropy(1.0 / (1.0 + math.exp(-float(x))))
        table[flat[i], 0] = unknown
        table[flat[i], 1] = entropy


@njit(cache=True)
def binary_entropy(p: float) -> float:
    """H(p) in bits; 0 at p = 0 and p = 1."""
    if p <= 0.0 or p >= 1.0:
        return 0.0
    return -(p * math.log2(p) + (1.0 - p) * math.log2(1.0 - p))
