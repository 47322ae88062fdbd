"""The hand-written statistics against the libraries they stand in for: Holm's correction against
statsmodels' ``multipletests``, the stratified bootstrap of an IQM against a direct computation in
the manner of rliable (``rliable.library.get_interval_estimates``: per resample, each task's runs
redrawn with replacement, the aggregate of the pooled draws, percentile interval)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import trim_mean

from nbv_gym.reporting.inference import holm, iqm, stratified_interval

multitest = pytest.importorskip("statsmodels.stats.multitest")


@pytest.mark.parametrize("seed", range(6))
def test_holm_matches_statsmodels_multipletests(seed):
    """Families of 1–30 p-values, with ties (p-values rounded to 2 places) and a share of
    small ones; NaN entries stay NaN and are not counted in the family."""
    rng = np.random.default_rng(seed)
    m = int(rng.integers(1, 31))
    p = np.round(np.where(rng.random(m) < 0.3, rng.random(m) * 0.01, rng.random(m)), 2)
    reject, expected, _, _ = multitest.multipletests(p, alpha=0.05, method="holm")
    np.testing.assert_allclose(holm(p), expected, rtol=1e-12, atol=0)
    assert ((holm(p) <= 0.05) == reject).all()
    with_nan = np.insert(p, rng.integers(0, m + 1, 3), np.nan)
    adjusted = holm(with_nan)
    assert np.isnan(adjusted).sum() == 3
    np.testing.assert_allclose(adjusted[np.isfinite(with_nan)], expected, rtol=1e-12, atol=0)


def direct_stratified_iqm_interval(values, strata, resamples, rng, level=0.95):
    """rliable's recipe written out: for each resample, draw every task's runs with replacement
    (``rng.choice``), pool them, take the IQM (scipy's 25 % trimmed mean); the percentile
    interval of the resampled IQMs."""
    values, strata = np.asarray(values, float), np.asarray(strata)
    groups = [values[strata == s] for s in dict.fromkeys(strata.tolist())]
    draws = np.empty(resamples)
    for k in range(resamples):
        pooled = np.concatenate([rng.choice(g, size=g.size, replace=True) for g in groups])
        draws[k] = trim_mean(pooled, 0.25)
    return trim_mean(values, 0.25), *np.quantile(draws, [(1 - level) / 2, (1 + level) / 2])


def test_stratified_iqm_interval_matches_a_direct_rliable_style_computation():
    """Three tasks of different sizes and levels: the same estimate, and the same percentile
    interval to within the Monte Carlo error of 4000 resamples (5 % of its half-width)."""
    rng = np.random.default_rng(11)
    values = np.concatenate(
        [rng.normal(0.2, 0.05, 9), rng.normal(0.5, 0.1, 6), rng.gamma(2.0, 0.1, 12)]
    )
    strata = ["a"] * 9 + ["b"] * 6 + ["c"] * 12
    estimate, low, high = direct_stratified_iqm_interval(
        values, strata, 4000, np.random.default_rng(1)
    )
    ours = stratified_interval(values, strata, iqm, np.random.default_rng(2), 4000)
    assert ours.mean == pytest.approx(estimate, rel=1e-12)
    half = (high - low) / 2
    assert ours.low == pytest.approx(low, abs=0.05 * half)
    assert ours.high == pytest.approx(high, abs=0.05 * half)
