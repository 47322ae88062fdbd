"""Statistics of the report: Q-vs-discovered curves, their area, bootstrap intervals, paired
comparisons of policies and the Table II share of significant indicator tests."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from nbv_gym.arrays import FloatArray


def monotone_curve(discovered: FloatArray, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A run's (discovered, Q) points with discovered made non-decreasing and, where a step
    discovered nothing new, only the last Q at that discovered fraction kept: (m,), (m,)."""
    d = np.maximum.accumulate(np.asarray(discovered, float))
    q = np.asarray(q, float)
    last = np.append(d[1:] != d[:-1], True)
    return d[last], q[last]


def q_curve(discovered: FloatArray, q: FloatArray, grid: FloatArray) -> FloatArray:
    """Q of one run linearly interpolated at the discovered fractions ``grid`` (k,); NaN outside
    the range the run covered."""
    d, q = monotone_curve(discovered, q)
    values = np.interp(grid, d, q)
    return np.where((grid >= d[0]) & (grid <= d[-1]), values, np.nan)


def q_auc(discovered: FloatArray, q: FloatArray, target: float) -> float:
    """Area under a run's Q-vs-discovered curve from 0 to min(its last discovered fraction,
    ``target``): trapezoids through (0, 0) — nothing discovered, nothing reconstructed — and its
    steps, the last one cut at ``target``. A run that stops short of the target gets less area."""
    d, q = monotone_curve(discovered, q)
    d, q = np.concatenate([[0.0], d]), np.concatenate([[0.0], q])
    if d[-1] > target:
        q_target = float(np.interp(target, d, q))
        inside = d < target
        d, q = np.append(d[inside], target), np.append(q[inside], q_target)
    return float(np.sum((d[1:] - d[:-1]) * (q[1:] + q[:-1]) / 2))


@dataclass(frozen=True)
class Interval:
    """A mean and its bootstrap confidence interval [low, high]; ``n`` values."""

    mean: float
    low: float
    high: float
    n: int


def bootstrap_mean(
    values: FloatArray, rng: np.random.Generator, resamples: int = 10_000, level: float = 0.95
) -> Interval:
    """The mean of (n,) ``values`` with a percentile-bootstrap confidence interval (NaN if n = 0)."""
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return Interval(np.nan, np.nan, np.nan, 0)
    means = values[rng.integers(0, values.size, (resamples, values.size))].mean(axis=1)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(means, [tail, 100 - tail])
    return Interval(float(values.mean()), float(low), float(high), int(values.size))


@dataclass(frozen=True)
class Comparison:
    """Policy A against policy B on paired runs: the mean difference A − B with its bootstrap
    interval, the share of pairs where A is better (higher) and the two-sided Wilcoxon
    signed-rank p-value (NaN when every difference is 0 or there are no pairs)."""

    difference: Interval
    a_better: float
    p_value: float


def compare_paired(a: FloatArray, b: FloatArray, rng: np.random.Generator) -> Comparison:
    """Compare (n,) ``a`` and ``b``, paired element by element."""
    diff = np.asarray(a, float) - np.asarray(b, float)
    diff = diff[np.isfinite(diff)]
    interval = bootstrap_mean(diff, rng)
    better = float(np.mean(diff > 0)) if diff.size else np.nan
    return Comparison(interval, better, wilcoxon_p(diff))


def wilcoxon_p(diff: FloatArray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of (n,) paired differences (NaN if all are 0)."""
    from scipy.stats import wilcoxon

    if diff.size == 0 or not np.any(diff != 0):
        return np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return float(wilcoxon(diff).pvalue)


def share_significant(p_values: FloatArray, alpha: float = 0.05) -> float:
    """Share of the finite ``p_values`` below ``alpha`` (Table II); NaN if there are none."""
    p = np.asarray(p_values, float)
    p = p[np.isfinite(p)]
    return float(np.mean(p < alpha)) if p.size else np.nan
