"""Numba readers of the occupancy map's bricked store by coarse cell (a cuboid of G is one such
cell): log-odds and threshold levels of each cell's voxels, whether a cell reaches a log-odds, and
the known/occupied projection of voxel columns. Voxel (a, b, k) of the store is at ``x_offset[a] +
y_offset[b] + z_offset[k]`` (:func:`~nbv_gym.mapping.traversal.axis_offsets`); the map
(:class:`~nbv_gym.mapping.occupancy.OccupancyMap`) checks the arguments."""

from __future__ import annotations

import numpy as np
from numba import njit

from nbv_gym.mapping.store import KNOWN_ZERO, is_known


@njit(cache=True)
def gather_logodds(store, x_offset, y_offset, z_offset, dims, offset, cells, out):
    """Fill ``out`` (k, f, f, f) with the log-odds (NaN = unknown, also outside the map) of
    ``cells`` (coarse indices) from the bricked ``store`` (voxel (a, b, k) at ``x_offset[a] +
    y_offset[b] + z_offset[k]``)."""
    nx, ny, nz = dims[2], dims[3], dims[4]
    f = out.shape[1]
    out[:] = np.nan
    for c in range(cells.shape[0]):
        x0 = offset[0] + cells[c, 0] * f
        y0 = offset[1] + cells[c, 1] * f
        z0 = offset[2] + cells[c, 2] * f
        for a in range(max(0, -x0), min(f, nx - x0)):
            for b in range(max(0, -y0), min(f, ny - y0)):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(max(0, -z0), min(f, nz - z0)):
                    value = store[column + z_offset[z0 + d]]
                    if is_known(value):
                        out[c, a, b, d] = value if value != KNOWN_ZERO else np.float32(0.0)


@njit(cache=True)
def mark_reaching(store, x_offset, y_offset, z_offset, dims, offset, cells, f, logodds, out):
    """Set ``out[c]`` iff coarse cell ``cells[c]`` (``f`` voxels a side) holds a known voxel
    of log-odds ≥ ``logodds`` (float32; :data:`KNOWN_ZERO` read as 0)."""
    nx, ny, nz = dims[2], dims[3], dims[4]
    zero = np.float32(0.0)
    for c in range(cells.shape[0]):
        x0 = offset[0] + cells[c, 0] * f
        y0 = offset[1] + cells[c, 1] * f
        z0 = offset[2] + cells[c, 2] * f
        for a in range(max(0, -x0), min(f, nx - x0)):
            for b in range(max(0, -y0), min(f, ny - y0)):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(max(0, -z0), min(f, nz - z0)):
                    value = store[column + z_offset[z0 + d]]
                    if is_known(value) and (zero if value == KNOWN_ZERO else value) >= logodds:
                        out[c] = True
                        break
                if out[c]:
                    break
            if out[c]:
                break


@njit(cache=True)
def gather_levels(store, x_offset, y_offset, z_offset, dims, offset, cells, bounds, out):
    """Fill ``out`` (k, f, f, f) uint32 with the bitmask of the ``bounds`` each voxel's
    log-odds reaches (unknown and outside the map: log-odds 0) for the coarse ``cells``."""
    nx, ny, nz = dims[2], dims[3], dims[4]
    f = out.shape[1]
    unknown = np.uint32(0)  # the stored value of an unknown voxel is 0 too
    for s in range(bounds.shape[0]):
        unknown |= np.uint32(bounds[s] <= 0.0) << np.uint32(s)
    out[:] = unknown
    for c in range(cells.shape[0]):
        x0 = offset[0] + cells[c, 0] * f
        y0 = offset[1] + cells[c, 1] * f
        z0 = offset[2] + cells[c, 2] * f
        for a in range(max(0, -x0), min(f, nx - x0)):
            for b in range(max(0, -y0), min(f, ny - y0)):
                column = x_offset[x0 + a] + y_offset[y0 + b]
                for d in range(max(0, -z0), min(f, nz - z0)):
                    value = store[column + z_offset[z0 + d]]  # KNOWN_ZERO compares like 0
                    level = np.uint32(0)
                    for s in range(bounds.shape[0]):
                        level |= np.uint32(value >= bounds[s]) << np.uint32(s)
                    out[c, a, b, d] = level


@njit(cache=True)
def project_columns(store, x_offset, y_offset, z_offset, x0, y0, f, known_layers, occupied_layers,  # noqa: C901 — a numba kernel: helpers taking arrays cost reference counting per call
                     bound, cells, known, occupied):  # fmt: skip
    """Set ``known[i, j]`` and ``occupied[i, j]`` of each (i, j) of ``cells``: whether some voxel
    of the cell's f × f columns (first column (x0 + f·i, y0 + f·j)) in the [k0, k1) layers is
    known, respectively known and ≥ ``bound`` (a positive bound needs no test of known-ness:
    unknown is 0). Voxel (a, b, k) is ``store[x_offset[a] + y_offset[b] + z_offset[k]]``
    (:func:`~nbv_gym.mapping.traversal.axis_offsets`); the loops are written out (a helper
    taking the arrays would cost numba reference counting per call)."""
    for c in range(cells.shape[0]):
        i, j = cells[c, 0], cells[c, 1]
        xa, ya = x0 + f * i, y0 + f * j
        for target in range(2):  # 0: known, 1: occupied
            layers = occupied_layers if target else known_layers
            found = False
            for k in range(layers[0], layers[1]):
                for a in range(xa, xa + f):
                    base = z_offset[k] + x_offset[a]
                    for b in range(ya, ya + f):
                        value = store[base + y_offset[b]]
                        if target:
                            found = value >= bound and (bound > 0.0 or is_known(value))
                        else:
                            found = is_known(value)
                        if found:
                            break
                    if found:
                        break
                if found:
                    break
            if target:
                occupied[i, j] = found
            else:
                known[i, j] = found
