"""Binary erosion and dilation of 2D masks by disc-like footprints, as
``scipy.ndimage.binary_erosion(mask, footprint, border_value=0)`` and
``scipy.ndimage.binary_dilation(mask, footprint)`` give them (tests check the two agree).

Written here for the navigation layer's four passes per scan: a footprint whose rows are runs
centred on its middle column (discs, squares) is read row by row from prefix sums of the mask's
rows, one lookup per footprint row and cell, and the environment need not import scipy.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def erode(mask: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """(nx, ny) bool: cells whose footprint (centred on them; its row half widths ``widths`` from
    :func:`half_widths`) lies inside the grid and covers only True cells of the (nx, ny) bool
    ``mask``."""
    return _morph(mask, widths, erode=True)


def dilate(mask: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """(nx, ny) bool: cells whose footprint (row half widths ``widths``) covers a True cell of
    ``mask``."""
    return _morph(mask, widths, erode=False)


def half_widths(footprint: np.ndarray) -> np.ndarray:
    """(rows,) int64 half width of each row of an odd-sized bool ``footprint`` (−1: empty row);
    ValueError unless every row is a run centred on the middle column and the footprint is
    symmetric about its middle row (so that dilation need not reflect it)."""
    footprint = np.asarray(footprint, bool)
    rows, cols = footprint.shape
    if rows % 2 == 0 or cols % 2 == 0:
        raise ValueError(f"a footprint needs odd sides, got {footprint.shape}")
    if not np.array_equal(footprint, footprint[::-1]):
        raise ValueError("a footprint must be symmetric about its middle row")
    widths = footprint.sum(axis=1) // 2 - (~footprint.any(axis=1))
    centre = cols // 2
    for row, w in zip(footprint, widths, strict=True):
        if not np.array_equal(row, np.abs(np.arange(cols) - centre) <= w):
            raise ValueError("every footprint row must be a run centred on the middle column")
    return widths.astype(np.int64)


def _morph(mask: np.ndarray, widths: np.ndarray, erode: bool) -> np.ndarray:
    mask = np.ascontiguousarray(mask, bool)
    out = np.empty(mask.shape, bool)
    _morph_kernel(mask, widths, erode, out)
    return out


@njit(cache=True)
def _morph_kernel(mask, widths, erode, out):
    """``out[i, j]``: for erosion, every footprint cell of (i, j) is inside and True; for
    dilation, some footprint cell of (i, j) is inside and True. Footprint row ``a`` covers
    ``(i + a − k, j − widths[a] … j + widths[a])``."""
    nx, ny = mask.shape
    k = len(widths) // 2
    prefix = np.zeros((nx, ny + 1), np.int32)  # prefix[i, j]: True cells of mask[i, :j]
    for i in range(nx):
        for j in range(ny):
            prefix[i, j + 1] = prefix[i, j] + mask[i, j]
    for i in range(nx):
        for j in range(ny):
            result = erode
            for a in range(len(widths)):
                w = widths[a]
                if w < 0:
                    continue
                r, lo, hi = i + a - k, j - w, j + w + 1
                if erode:
                    inside = 0 <= r < nx and lo >= 0 and hi <= ny
                    if not (inside and prefix[r, hi] - prefix[r, lo] == hi - lo):
                        result = False
                        break
                elif 0 <= r < nx and prefix[r, min(hi, ny)] > prefix[r, max(lo, 0)]:
                    result = True
                    break
            out[i, j] = result
