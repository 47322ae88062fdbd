"""Probabilities of the map's log-odds, the same bits wherever they are computed.

A voxel's probability is float32 ``1 / (1 + e^−l)`` of its float32 log-odds ``l``, computed in
float64 and rounded once (:func:`sigmoid_one`); unknown (NaN) is 0.5. A map holds few distinct
log-odds (sums of the hit and miss steps, clamped), so the compiled hot paths look probabilities up
in a small direct-mapped cache keyed by the log-odds' bits (:func:`new_cache`,
:func:`probabilities_in_place`) and call :func:`sigmoid_one` only on a miss: the same bits either
way. A comparison ``p > t`` is a comparison of the log-odds with :func:`logodds_bound` ``(t)``,
also the same bits: no probability needs computing at all.
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


def logodds_bound(threshold: float) -> np.float32:
    """The least float32 log-odds ``b`` whose probability exceeds float32 ``threshold``: since
    :func:`sigmoid_one` never decreases, ``sigmoid_one(l) > t`` iff ``l >= b`` for every float32
    ``l`` (found by bisection over the float32 values in [−200, 200]; tests check both sides of
    it). An unknown voxel (p = 0.5) compares as ``l = 0``."""
    t = np.float32(threshold)
    low, high = _ordered(-200.0), _ordered(200.0)  # p(−200) = 0 and p(200) = 1 in float32
    if not sigmoid_one(_from_ordered(high)) > t:
        return np.float32(np.inf)
    while high - low > 1:  # invariant: p(low) <= t < p(high)
        middle = (low + high) // 2
        if sigmoid_one(_from_ordered(middle)) > t:
            high = middle
        else:
            low = middle
    return _from_ordered(high)


def _ordered(x: float) -> int:
    """An integer of float32 ``x`` that orders like the float (−0.0 and +0.0 both 0)."""
    bits = int(np.float32(x).view(np.int32))
    return bits if bits >= 0 else -(bits & 0x7FFFFFFF)


def _from_ordered(key: int) -> np.float32:
    """The float32 of :func:`_ordered` ``key``."""
    bits = key if key >= 0 else (-key) | -0x80000000
    return np.int32(bits).view(np.float32)


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
