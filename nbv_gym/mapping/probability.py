"""Probabilities of the map's log-odds, the same bits wherever they are computed.

A voxel's probability is float32 ``1 / (1 + e^−l)`` of its float32 log-odds ``l``, computed in
float64 and rounded once (:func:`sigmoid_one`); unknown (NaN) is 0.5. A map holds few distinct
log-odds (sums of the hit and miss steps, clamped), so the compiled hot paths look probabilities up
in a small direct-mapped cache keyed by the log-odds' bits (:func:`new_cache`,
:func:`probabilities_in_place`) and call :func:`sigmoid_one` only on a miss: the same bits either
way.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Entries of the probability cache: 2 ** CACHE_BITS.
CACHE_BITS = 12
_SHIFT = np.uint64(32 - CACHE_BITS)


def new_cache() -> tuple[np.ndarray, np.ndarray]:
    """An empty probability cache: (2^bits,) uint32 keys (NaN's bits: empty) and float32 values."""
    size = 1 << CACHE_BITS
    return np.full(size, np.float32(np.nan).view(np.uint32), np.uint32), np.zeros(size, np.float32)


@njit(cache=True)
def sigmoid_one(logodds):
    """float32 1 / (1 + e^−l) of one known log-odds, computed in float64 and rounded once."""
    return np.float32(1.0 / (1.0 + math.exp(-np.float64(logodds))))


@njit(cache=True)
def probabilities_in_place(logodds, count, cache):
    """Replace the first ``count`` float32 log-odds of the 1-D contiguous ``logodds`` by their
    probabilities (0.5 for NaN), through ``cache`` = (keys, values) of :func:`new_cache` (updated
    on a miss). Written as one loop over an array: a per-value cache function is ~20× slower
    under numba."""
    keys, values = cache
    bits = logodds.view(np.uint32)
    for i in range(count):
        value = logodds[i]
        if np.isnan(value):
            logodds[i] = 0.5
            continue
        key = bits[i]
        product = (np.uint64(key) * np.uint64(2654435761)) & np.uint64(0xFFFFFFFF)  # Fibonacci
        slot = np.int64(product >> _SHIFT)
        if keys[slot] != key:
            keys[slot] = key
            values[slot] = sigmoid_one(value)
        logodds[i] = values[slot]


def probabilities(logodds: np.ndarray) -> np.ndarray:
    """float32 probability of float32 log-odds of any shape, 0.5 for NaN (unknown)."""
    logodds = np.ascontiguousarray(logodds, dtype=np.float32)
    return _sigmoid(logodds.ravel()).reshape(logodds.shape)


@njit(cache=True)
def _sigmoid(logodds):
    """(n,) float32 probabilities of (n,) float32 log-odds; 0.5 for NaN."""
    out = np.empty(logodds.shape[0], np.float32)
    for i in range(logodds.shape[0]):
        value = logodds[i]
        out[i] = 0.5 if np.isnan(value) else sigmoid_one(value)
    return out
