"""Transcendental functions with the same bits on every x86-64 CPU: the C library's.

numpy chooses, when it is imported, the SIMD loop of ``np.exp``, ``np.log``, ``np.sin``,
``np.cos``, ``np.arctan2``, ``np.arcsin``, ``np.log1p`` … that the CPU supports. Its AVX-512
loops (float64) and its AVX2 loops (float32, and ``tanh``) are numpy's own approximations, which
differ from the C library's in the last bit; on a CPU without them numpy calls the C library.
A figure computed with them moves with the machine (a lidar ray, a pose, a gain: a point crosses
a voxel face, a decision flips). ``numpy.lib.introspect.opt_func_info()`` lists the dispatched
loops and the one this CPU runs.

Every transcendental on a path that moves a result (world building, the lidar, poses, the gains
and the policies' utilities, the agent's observation) goes through this module instead: the C
library's function, called value by value — from :mod:`math` for one value, from a numba kernel
for arrays (numba lowers ``math.cos`` to a call of the C library's ``cos``; it vectorises such
calls only with Intel's SVML, which nbv-gym's dependencies do not install and the tests check is
off). These give the bits numpy gives on a CPU without AVX-512 (tested here against
:mod:`math`), so results computed before on such a CPU are unchanged.

The exact arithmetic of numpy (``+ − × ÷``, ``sqrt``, ``hypot``, comparisons, ``minimum``,
``maximum``, ``floor``, its pairwise sums) gives the same bits on every CPU and stays numpy's.
"""

from __future__ import annotations

import math

from numba import vectorize

# Each is a ufunc: float64 in (other dtypes are cast), float64 out, any shape (broadcasting),
# the C library's value element by element.


@vectorize(["float64(float64)"], cache=True)
def cos(x):  # pragma: no cover - compiled
    """The cosine of ``x`` radians."""
    return math.cos(x)


@vectorize(["float64(float64)"], cache=True)
def sin(x):  # pragma: no cover - compiled
    """The sine of ``x`` radians."""
    return math.sin(x)


@vectorize(["float64(float64, float64)"], cache=True)
def arctan2(y, x):  # pragma: no cover - compiled
    """The angle of (x, y) in radians, in [−π, π]."""
    return math.atan2(y, x)


@vectorize(["float64(float64)"], cache=True)
def arcsin(x):  # pragma: no cover - compiled
    """The angle in [−π/2, π/2] whose sine is ``x`` (NaN outside [−1, 1]), radians."""
    return math.asin(x)


@vectorize(["float64(float64)"], cache=True)
def exp(x):  # pragma: no cover - compiled
    """e^x."""
    return math.exp(x)


@vectorize(["float64(float64)"], cache=True)
def log(x):  # pragma: no cover - compiled
    """ln x: −inf at 0, NaN below."""
    return math.log(x)


@vectorize(["float64(float64)"], cache=True)
def log1p(x):  # pragma: no cover - compiled
    """ln(1 + x): −inf at −1, NaN below."""
    return math.log1p(x)
