"""Statistics of the report: Q-vs-discovered curves, their area, bootstrap intervals, paired
comparisons of policies and the Table II share of significant indicator tests.

What the RL and robotics literature expects (Agarwal et al., *Deep RL at the edge of the
statistical precipice*, NeurIPS 2021), computed with numpy/scipy (the rliable package breaks under
pandas 3):

- confidence intervals: ``scipy.stats.bootstrap`` with the bias-corrected and accelerated (BCa)
  method, 95 %, 10 000 resamples, seeded from the report's generator;
- the interquartile mean (IQM): the mean of the middle 50 % of the runs (``trim_mean(x, 0.25)``),
  robust to outlier runs yet less noisy than the median;
- the probability of improvement ``P(A > B)``: per task (world and noise level) the probability
  that a run of A scores higher than a run of B, ties counting ½ (the Mann–Whitney U statistic
  over ``n_A n_B``), averaged over the tasks;
- stratified bootstrap (rliable's ``StratifiedBootstrap``): runs are resampled with replacement
  *within* each stratum — a world × noise level — never across, so an interval reflects the
  spread between repeats of the same task, not the (fixed, chosen) spread between worlds; the
  interval is the percentile one of the resampled statistic, as rliable computes it
  (:func:`stratified_interval`, :func:`probability_of_improvement_interval`,
  :func:`performance_profile`);
- the optimality gap: the mean shortfall below a target score, ``mean(max(target − x, 0))``;
- multiple comparisons: the paired Wilcoxon p-values of all policy pairs of one table are one
  family, adjusted with Holm's step-down method (controls the family-wise error rate at α
  without Bonferroni's loss of power; no independence assumption).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray


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
    """The mean of (n,) ``values`` with its BCa bootstrap confidence interval (NaN if n = 0)."""
    return bootstrap_interval(values, np.mean, rng, resamples, level)


def bootstrap_iqm(
    values: FloatArray, rng: np.random.Generator, resamples: int = 10_000, level: float = 0.95
) -> Interval:
    """The interquartile mean of (n,) ``values`` with its BCa bootstrap confidence interval."""
    return bootstrap_interval(values, iqm, rng, resamples, level)


def iqm(values: FloatArray, axis: int = -1) -> FloatArray:
    """Interquartile mean: the mean of the middle 50 % of ``values`` along ``axis``."""
    from scipy.stats import trim_mean

    return trim_mean(values, 0.25, axis=axis)


def bootstrap_interval(
    values: FloatArray, statistic, rng: np.random.Generator, resamples: int = 10_000,
    level: float = 0.95,
) -> Interval:  # fmt: skip
    """``statistic`` (a vectorised ``f(x, axis)``) of the finite (n,) ``values`` with its BCa
    bootstrap interval (``scipy.stats.bootstrap``). Undefined for n = 0 (NaN); a degenerate
    [s, s] interval when the values do not vary (n = 1 included); the percentile interval where
    BCa is undefined (a few values whose jackknife estimates are all equal)."""
    from scipy.stats import bootstrap

    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return Interval(np.nan, np.nan, np.nan, 0)
    estimate = float(statistic(values, axis=-1))
    if np.ptp(values) == 0:
        return Interval(estimate, estimate, estimate, int(values.size))
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # BCa warns where it is undefined (NaN bounds)
            result = bootstrap(
                (values,), statistic, n_resamples=resamples, confidence_level=level,
                method=method, rng=rng,
            )  # fmt: skip
        low, high = result.confidence_interval
        if np.isfinite(low) and np.isfinite(high):
            break
    return Interval(estimate, float(low), float(high), int(values.size))


def holm(p_values: FloatArray) -> FloatArray:
    """Holm's step-down adjustment of a family of (k,) p-values; NaN entries stay NaN and do
    not count in the family. Adjusted ``p_(i) = max_{j ≤ i} min(1, (m − j + 1) p_(j))`` for the
    ascending order ``p_(1) ≤ … ≤ p_(m)``: reject where the adjusted p < α."""
    p = np.asarray(p_values, float)
    out = np.full(p.shape, np.nan)
    finite = np.flatnonzero(np.isfinite(p))
    order = finite[np.argsort(p[finite], kind="stable")]
    m = order.size
    scaled = np.minimum(1.0, (m - np.arange(m)) * p[order])
    out[order] = np.maximum.accumulate(scaled)
    return out


def probability_of_improvement(a: FloatArray, b: FloatArray, tasks) -> float:
    """``P(A > B)``: for each task, the probability that a run of A (values ``a``) scores higher than a run of
    B (``b``), ties ½, i.e. ``U / (n_A n_B)`` of the Mann–Whitney test; the mean over tasks.
    ``a``, ``b`` (n,), ``tasks`` (n,) the task of each pair of runs; NaN values are dropped."""
    from scipy.stats import mannwhitneyu

    a, b, tasks = np.asarray(a, float), np.asarray(b, float), list(tasks)
    shares = []
    for task in dict.fromkeys(tasks):
        pick = np.array([t == task for t in tasks])
        x, y = a[pick], b[pick]
        x, y = x[np.isfinite(x)], y[np.isfinite(y)]
        if x.size and y.size:
            shares.append(mannwhitneyu(x, y).statistic / (x.size * y.size))
    return float(np.mean(shares)) if shares else np.nan


@dataclass(frozen=True)
class Comparison:
    """Policy A against policy B on paired runs: the mean difference A − B with its bootstrap
    interval, the share of pairs where A is better (higher) and the two-sided Wilcoxon
    signed-rank p-value (NaN when every difference is 0 or there are no pairs)."""

    difference: Interval
    a_better: float
    p_value: float


def compare_paired(
    a: FloatArray, b: FloatArray, rng: np.random.Generator, strata=None
) -> Comparison:
    """Compare (n,) ``a`` and ``b``, paired element by element; with ``strata`` (n,) the
    interval of the mean difference is the stratified bootstrap's (:func:`stratified_interval`),
    else the BCa one."""
    diff = np.asarray(a, float) - np.asarray(b, float)
    keep = np.isfinite(diff)
    diff = diff[keep]
    if strata is None:
        interval = bootstrap_mean(diff, rng)
    else:
        picked = [s for s, k in zip(strata, keep, strict=True) if k]
        interval = stratified_interval(diff, picked, np.mean, rng)
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


#: The alternatives of a test: ``"two-sided"``, ``"greater"`` or ``"less"``.
ALTERNATIVES = ("two-sided", "greater", "less")


def smallest_p_wilcoxon(n: int, alternative: str = "two-sided") -> float:
    """The smallest p-value the exact Wilcoxon signed-rank test can give for ``n`` non-zero
    paired differences: every difference of one sign has probability ``2^-n`` under the null,
    so ``2^-n`` one-sided and ``2^(1-n)`` two-sided (1 for n = 0). E.g. n = 8 two-sided: 0.0078."""
    if n < 1:
        return 1.0
    tail = 0.5**n
    return min(1.0, 2 * tail) if _two_sided(alternative) else tail


def smallest_p_mannwhitney(n_a: int, n_b: int, alternative: str = "two-sided") -> float:
    """The smallest p-value the exact Mann–Whitney U test can give for samples of ``n_a`` and
    ``n_b`` values: complete separation, one of the ``C(n_a + n_b, n_a)`` equally likely
    orderings, so ``1 / C`` one-sided and ``2 / C`` two-sided (1 if a sample is empty). E.g.
    2 runs a side, one-sided: 1/6."""
    from math import comb

    if n_a < 1 or n_b < 1:
        return 1.0
    tail = 1.0 / comb(n_a + n_b, n_a)
    return min(1.0, 2 * tail) if _two_sided(alternative) else tail


def smallest_p_spearman(n: int, alternative: str = "two-sided") -> float:
    """The smallest p-value an exact permutation test of Spearman's ρ can give for ``n`` pairs
    without ties: the perfect ordering is one of ``n!``, so ``1 / n!`` one-sided, ``2 / n!``
    two-sided; ties only make it larger, so this is a lower bound."""
    from math import factorial

    if n < 2:
        return 1.0
    tail = 1.0 / factorial(n)
    return min(1.0, 2 * tail) if _two_sided(alternative) else tail


def can_reach(smallest_p: float, family_size: int = 1, alpha: float = 0.05) -> bool:
    """Whether a test whose smallest attainable p is ``smallest_p`` can be significant at
    ``alpha`` after Holm's adjustment over ``family_size`` tests (whose smallest adjusted p is
    ``family_size · p``). False means a non-significant result says nothing: *inconclusive*."""
    return smallest_p * max(family_size, 1) < alpha


def power_note(smallest_p: float, family_size: int, test: str, alpha: float = 0.05) -> str:
    """One sentence saying that no test of a table can reach significance (empty if some can):
    the smallest attainable p of ``test`` and, for a family, its smallest Holm-adjusted p."""
    if can_reach(smallest_p, family_size, alpha):
        return ""
    adjusted = min(1.0, smallest_p * max(family_size, 1))
    family = (
        f"; Holm over the {family_size} tests of the table makes the smallest adjusted p "
        f"{adjusted:.3g}"
        if family_size > 1
        else ""
    )
    return (
        f"**Power note:** with these sample sizes the smallest p a {test} can give is "
        f"{smallest_p:.3g}{family}, so no comparison here can reach p < {alpha:g}: a "
        "non-significant entry is inconclusive, not evidence of no difference. More repeats "
        "or worlds are needed."
    )


def _two_sided(alternative: str) -> bool:
    if alternative not in ALTERNATIVES:
        raise ValueError(f"alternative must be one of {ALTERNATIVES}, got {alternative!r}")
    return alternative == "two-sided"


def share_significant(p_values: FloatArray, alpha: float = 0.05) -> float:
    """Share of the finite ``p_values`` below ``alpha`` (Table II); NaN if there are none."""
    p = np.asarray(p_values, float)
    p = p[np.isfinite(p)]
    return float(np.mean(p < alpha)) if p.size else np.nan


# -- stratified bootstrap (rliable's recipe) --------------------------------------------------------

#: Bootstrap resamples of the stratified intervals (rliable's default is 2 000; more are cheap here).
RESAMPLES = 10_000


def strata_codes(strata) -> IntArray:
    """(n,) int code of each run's stratum (any hashable labels, e.g. ``(world, noise)`` tuples),
    numbered in order of first appearance."""
    codes: dict = {}
    return np.array([codes.setdefault(label, len(codes)) for label in strata], dtype=np.int64)


def stratified_resamples(strata, resamples: int, rng: np.random.Generator) -> IntArray:
    """(resamples, n) int indices of bootstrap resamples of n runs in which position ``i`` holds
    a run drawn uniformly with replacement from the runs of ``i``'s stratum (``strata`` (n,)
    labels): every resample keeps each stratum's size."""
    codes = strata_codes(strata)
    out = np.empty((resamples, codes.size), dtype=np.int64)
    for code in range(int(codes.max(initial=-1)) + 1):
        members = np.flatnonzero(codes == code)
        out[:, members] = members[rng.integers(0, members.size, (resamples, members.size))]
    return out


def stratified_interval(
    values: FloatArray, strata, statistic, rng: np.random.Generator,
    resamples: int = RESAMPLES, level: float = 0.95,
) -> Interval:  # fmt: skip
    """``statistic`` (a vectorised ``f(x, axis)``: :func:`numpy.mean`, :func:`iqm`, …) of the
    (n,) ``values`` with its ``level`` percentile interval under the stratified bootstrap
    (``strata`` (n,) the stratum of each value, e.g. ``(world, noise)``). Non-finite values are
    dropped; NaN for none left. With one value per stratum every resample is the sample itself
    and the interval is the point ``[s, s]``."""
    values = np.asarray(values, float)
    keep = np.isfinite(values)
    values, labels = values[keep], [s for s, k in zip(strata, keep, strict=True) if k]
    if values.size == 0:
        return Interval(np.nan, np.nan, np.nan, 0)
    estimate = float(statistic(values, axis=-1))
    samples = statistic(values[stratified_resamples(labels, resamples, rng)], axis=-1)
    low, high = np.quantile(samples, [(1 - level) / 2, (1 + level) / 2])
    return Interval(estimate, float(low), float(high), int(values.size))


def optimality_gap(values: FloatArray, target: float = 1.0, axis: int = -1) -> FloatArray:
    """The mean shortfall of ``values`` below ``target`` along ``axis``:
    ``mean(max(target − x, 0))`` (rliable's optimality gap; lower is better)."""
    return np.mean(np.maximum(target - np.asarray(values, float), 0.0), axis=axis)


def probability_of_improvement_interval(
    a: FloatArray, tasks_a, b: FloatArray, tasks_b, rng: np.random.Generator,
    resamples: int = RESAMPLES, level: float = 0.95,
) -> Interval:  # fmt: skip
    """``P(A > B)`` (:func:`probability_of_improvement`: per task the share of run pairs A wins,
    ties ½, averaged over the tasks both have runs of) with its ``level`` percentile interval
    under the stratified bootstrap: per resample, the runs of A and those of B are redrawn
    independently within each task. ``a`` (n_a,) with ``tasks_a`` (n_a,), ``b`` (n_b,) with
    ``tasks_b`` (n_b,); NaN values are dropped. ``n`` of the result: the tasks compared."""
    shares, samples = [], []
    for task in dict.fromkeys(tasks_a):
        x, y = _task_values(a, tasks_a, task), _task_values(b, tasks_b, task)
        if not (x.size and y.size):
            continue
        wins = (x[:, None] > y[None, :]) + 0.5 * (x[:, None] == y[None, :])  # (n_x, n_y)
        shares.append(wins.mean())
        counts_x = _draw_counts(x.size, resamples, rng)
        counts_y = _draw_counts(y.size, resamples, rng)
        samples.append(np.einsum("bi,ij,bj->b", counts_x, wins, counts_y) / (x.size * y.size))
    if not shares:
        return Interval(np.nan, np.nan, np.nan, 0)
    estimate = float(np.mean(shares))
    low, high = np.quantile(np.mean(samples, axis=0), [(1 - level) / 2, (1 + level) / 2])
    return Interval(estimate, float(low), float(high), len(shares))


def performance_profile(
    values: FloatArray, strata, thresholds: FloatArray, rng: np.random.Generator,
    resamples: int = 2_000, level: float = 0.95,
) -> tuple[FloatArray, FloatArray, FloatArray]:  # fmt: skip
    """The run-score distribution of rliable's performance profiles: for each of the (k,)
    ``thresholds`` τ the fraction of the (n,) ``values`` above τ, with its ``level`` band under
    the stratified bootstrap (``strata`` (n,)); three (k,) arrays (fraction, low, high). Runs with
    a non-finite value are dropped."""
    values = np.asarray(values, float)
    keep = np.isfinite(values)
    values, labels = values[keep], [s for s, k in zip(strata, keep, strict=True) if k]
    tau = np.asarray(thresholds, float)
    fraction = (values[:, None] > tau).mean(axis=0)
    resampled = values[stratified_resamples(labels, resamples, rng)]  # (resamples, n)
    curves = (resampled[:, :, None] > tau).mean(axis=1)  # (resamples, k)
    low, high = np.quantile(curves, [(1 - level) / 2, (1 + level) / 2], axis=0)
    return fraction, low, high


def _task_values(values: FloatArray, tasks, task) -> FloatArray:
    """The finite entries of ``values`` whose task is ``task``."""
    picked = np.asarray(values, float)[np.array([t == task for t in tasks], dtype=bool)]
    return picked[np.isfinite(picked)]


def _draw_counts(n: int, resamples: int, rng: np.random.Generator) -> FloatArray:
    """(resamples, n) how often each of n runs is drawn in a resample of size n."""
    draws = rng.integers(0, n, (resamples, n))
    return (draws[:, :, None] == np.arange(n)).sum(axis=1).astype(float)
