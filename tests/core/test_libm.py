"""``nbv_gym.core.libm`` gives the C library's value of each element: the same bits as
:mod:`math` (which calls the C library), whatever numpy's own loops on this CPU give."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nbv_gym.core import libm

RNG = np.random.default_rng(0)
#: (function, its math twin, arguments): random values over the ranges the package uses, and the
#: edges (zeros of both signs, the domain's ends, subnormals, the largest floats).
CASES = [
    (libm.cos, math.cos, [RNG.uniform(-10, 10, 4000), [0.0, -0.0, 1e300, -1e300, 5e-324]]),
    (libm.sin, math.sin, [RNG.uniform(-10, 10, 4000), [0.0, -0.0, 1e300, -1e300, 5e-324]]),
    (libm.exp, math.exp, [RNG.uniform(-700, 700, 4000), [0.0, -0.0, -745.0, 5e-324]]),
    (libm.log, math.log, [RNG.uniform(1e-300, 1e3, 4000), [1.0, 5e-324, 1.7e308]]),
    (libm.log1p, math.log1p, [RNG.uniform(-0.999, 1e3, 4000), [0.0, -0.0, 5e-324, 1.7e308]]),
    (libm.arcsin, math.asin, [RNG.uniform(-1, 1, 4000), [1.0, -1.0, 0.0, -0.0, 5e-324]]),
]


def _bits(values) -> np.ndarray:
    return np.asarray(values, np.float64).view(np.int64)


@pytest.mark.parametrize(
    ("ours", "theirs", "parts"), CASES, ids=lambda c: getattr(c, "__name__", "")
)
def test_each_element_is_the_c_librarys_value(ours, theirs, parts):
    x = np.concatenate([np.asarray(p, np.float64) for p in parts])
    expected = [theirs(v) for v in x.tolist()]
    np.testing.assert_array_equal(_bits(ours(x)), _bits(expected))


def test_arctan2_is_the_c_librarys_in_every_quadrant_and_on_the_axes():
    y = np.concatenate([RNG.uniform(-50, 50, 4000), [0.0, -0.0, 0.0, -0.0, 1.0, -1.0]])
    x = np.concatenate([RNG.uniform(-50, 50, 4000), [0.0, 0.0, -0.0, -0.0, 0.0, -0.0]])
    expected = [math.atan2(a, b) for a, b in zip(y.tolist(), x.tolist(), strict=True)]
    np.testing.assert_array_equal(_bits(libm.arctan2(y, x)), _bits(expected))


def test_outside_the_domain_gives_what_numpy_gives_not_an_error():
    with np.errstate(invalid="ignore", divide="ignore"):
        assert np.isnan(libm.log(-1.0)) and libm.log(0.0) == -np.inf
        assert np.isnan(libm.log1p(-2.0)) and libm.log1p(-1.0) == -np.inf
        assert np.isnan(libm.arcsin(1.5)) and np.isnan(libm.cos(np.inf))


def test_shapes_broadcast_and_other_dtypes_compute_in_float64():
    grid = libm.arctan2(np.ones((3, 1)), np.arange(4.0))
    assert grid.shape == (3, 4) and grid.dtype == np.float64
    assert libm.cos(np.float32(1.0)) == math.cos(1.0)  # the float32 value, widened exactly
    assert libm.exp(np.arange(3)).dtype == np.float64


def test_numba_does_not_vectorise_the_calls_with_svml():
    # Intel's SVML (installed by intel-cmplr-lib-rt or icc_rt) would replace the C library's
    # functions by vector approximations that follow the CPU's width.
    import numba

    assert not numba.config.USING_SVML
