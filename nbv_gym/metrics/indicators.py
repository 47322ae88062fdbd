"""Viewpoint statistics as quality indicators: the one-sided Mann–Whitney U tests of Table I (*Next-Best-View selection from observation viewpoint statistics*).

For a metric M (``cov`` on U_occ cuboids, ``l1`` on U_empty cuboids) and a statistic s (``n_obs``,
``r_min``, ``n_omega``, ``sigma_theta``), the cuboids are split at the median s* of s and the two
populations are compared with a one-sided Mann–Whitney U test whose alternative H1 is (Table I):

=======  ==============================  ==========================
metric   statistic                       H1
=======  ==============================  ==========================
cov      n_obs, n_omega, sigma_theta     M[s >= s*] > M[s < s*]
cov      r_min                           M[s < s*] > M[s >= s*]
l1       n_obs, n_omega, sigma_theta     M[s >= s*] < M[s < s*]
l1       r_min                           M[s < s*] < M[s >= s*]
=======  ==============================  ==========================

A small p-value says the statistic indicates the reconstruction quality. Cuboids whose statistic or
metric is NaN (e.g. ``r_min`` of a never observed cuboid) are left out before taking the median.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import UnknownNameError
from nbv_gym.mapping.statistics import STATISTICS
from nbv_gym.metrics import MetricInputError

METRICS = ("cov", "l1")


@dataclass(frozen=True)
class IndicatorTest:
    """One test of Table I: ``p_value`` (NaN when a population is empty), the U statistic of the
    first population of H1, the median threshold and the two population sizes."""

    metric: str
    statistic: str
    alternative: str
    threshold: float
    u_statistic: float
    p_value: float
    n_at_or_above: int
    n_below: int


def hypothesis(metric: str, statistic: str) -> tuple[bool, str]:
    """Table I for (metric, statistic): (is the first population ``s >= s*``, scipy alternative)."""
    if metric not in METRICS:
        raise UnknownNameError("metric", metric, METRICS)
    if statistic not in STATISTICS:
        raise UnknownNameError("statistic", statistic, STATISTICS)
    above_first = statistic != "r_min"
    return above_first, "greater" if metric == "cov" else "less"


def indicator_test(
    metric: str, statistic: str, metric_values: FloatArray, statistic_values: FloatArray
) -> IndicatorTest:
    """The Mann–Whitney test of Table I on (n,) per-cuboid ``metric_values`` and ``statistic_values``."""
    from scipy.stats import mannwhitneyu

    above_first, alternative = hypothesis(metric, statistic)
    m, s = np.asarray(metric_values, float).ravel(), np.asarray(statistic_values, float).ravel()
    if m.shape != s.shape:
        raise MetricInputError(f"{metric} has {m.size} values but {statistic} has {s.size}")
    keep = np.isfinite(m) & np.isfinite(s)
    m, s = m[keep], s[keep]
    threshold = float(np.median(s)) if s.size else float("nan")
    above, below = m[s >= threshold], m[s < threshold]
    first, second = (above, below) if above_first else (below, above)
    if first.size == 0 or second.size == 0:
        u, p = float("nan"), float("nan")
    else:
        result = mannwhitneyu(first, second, alternative=alternative)
        u, p = float(result.statistic), float(result.pvalue)
    return IndicatorTest(
        metric, statistic, alternative, threshold, u, p, int(above.size), int(below.size)
    )


def indicator_tests(
    metrics: dict[str, FloatArray], statistics: dict[str, FloatArray]
) -> list[IndicatorTest]:
    """Every test of Table I for the given per-cuboid ``metrics`` (``cov``, ``l1``) and ``statistics``.

    Each array is per cuboid, in the same order; pass the U_occ cuboids' values for ``cov`` and the
    U_empty cuboids' values for ``l1`` by setting the others to NaN.
    """
    return [
        indicator_test(metric, statistic, metrics[metric], statistics[statistic])
        for metric in METRICS
        if metric in metrics
        for statistic in STATISTICS
        if statistic in statistics
    ]
