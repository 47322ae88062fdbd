"""The report's statistics against hand-computed values and textbook results."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from nbv_gym.sweep.stats import (
    bootstrap_iqm,
    bootstrap_mean,
    holm,
    iqm,
    probability_of_improvement,
)


def test_bca_interval_of_a_large_normal_sample_is_the_t_interval():
    rng = np.random.default_rng(0)
    values = rng.normal(3.0, 2.0, 400)
    interval = bootstrap_mean(values, np.random.default_rng(1))
    half = stats.t.ppf(0.975, 399) * values.std(ddof=1) / np.sqrt(400)
    assert interval.mean == pytest.approx(values.mean())
    assert interval.low == pytest.approx(values.mean() - half, abs=0.03 * half + 0.01)
    assert interval.high == pytest.approx(values.mean() + half, abs=0.03 * half + 0.01)


def test_bca_corrects_the_percentile_interval_of_a_skewed_sample():
    values = np.random.default_rng(2).exponential(1.0, 30)
    ours = bootstrap_mean(values, np.random.default_rng(3))
    bca = stats.bootstrap(
        (values,), np.mean, n_resamples=10_000, method="BCa", rng=np.random.default_rng(3)
    )
    percentile = stats.bootstrap(
        (values,), np.mean, method="percentile", rng=np.random.default_rng(3)
    )
    assert (ours.low, ours.high) == pytest.approx(tuple(bca.confidence_interval))
    assert ours.high > percentile.confidence_interval.high  # BCa moves right for right skew


def test_degenerate_and_empty_samples():
    rng = np.random.default_rng(0)
    same = bootstrap_mean([2.0, 2.0], rng)
    assert (same.mean, same.low, same.high) == (2.0, 2.0, 2.0)
    one = bootstrap_mean([5.0], rng)
    assert (one.mean, one.low, one.high, one.n) == (5.0, 5.0, 5.0, 1)
    assert np.isnan(bootstrap_mean([np.nan], rng).mean)
    two = bootstrap_mean([1.0, 2.0], rng)
    assert 1.0 <= two.low <= 1.5 <= two.high <= 2.0


def test_interquartile_mean_by_hand():
    assert iqm(np.arange(1.0, 9.0)) == pytest.approx(4.5)  # mean of 3, 4, 5, 6
    assert iqm(np.array([0.0, 1.0, 1.0, 100.0])) == pytest.approx(1.0)
    interval = bootstrap_iqm(np.arange(1.0, 41.0), np.random.default_rng(0))
    assert interval.mean == pytest.approx(20.5) and interval.low < 20.5 < interval.high


def test_holm_by_hand():
    # ascending 0.005, 0.01, 0.03, 0.04 → ×4, ×3, ×2, ×1 = 0.02, 0.03, 0.06, 0.04 → running max
    adjusted = holm([0.01, 0.04, 0.03, 0.005, np.nan])
    np.testing.assert_allclose(adjusted[:4], [0.03, 0.06, 0.06, 0.02])
    assert np.isnan(adjusted[4])
    assert holm([0.6, 0.7]).tolist() == [1.0, 1.0]


def test_probability_of_improvement_by_hand():
    # task 1: a = 1, 2, 3 against b = 2, 2: pairs won 0 + ½·2 + 2 = 3 of 6 → ½; task 2: a wins → 1
    a = [1.0, 2.0, 3.0, 5.0]
    b = [2.0, 2.0, np.nan, 1.0]
    tasks = [("w", 0), ("w", 0), ("w", 0), ("v", 1)]
    assert probability_of_improvement(a, b, tasks) == pytest.approx(0.75)
    assert probability_of_improvement(b, a, tasks) == pytest.approx(0.25)


def test_pairwise_table_adds_holm_and_probability_of_improvement():
    import pandas as pd

    from nbv_gym.sweep.report import pairwise_table

    rows = []
    for world in ("w1", "w2"):
        for repeat in range(4):
            q = {"a": 0.5 + 0.01 * repeat, "b": 0.2 + 0.02 * repeat, "c": 0.3 + 0.01 * repeat}
            rows += [dict(world=world, noise=1, repeat=repeat, policy=p, q=v) for p, v in q.items()]
    table = pairwise_table(pd.DataFrame(rows), ["a", "b", "c"], "q", np.random.default_rng(0))
    table = table.set_index(["a", "b"])
    # a beats every b and c run; b (0.20–0.26) against c (0.30–0.33): b wins none → 0
    assert table.loc[("a", "b"), "p_improvement"] == 1.0
    assert table.loc[("b", "c"), "p_improvement"] == 0.0
    np.testing.assert_allclose(table["p_holm"], holm(table["p_wilcoxon"].to_numpy()))
    assert (table["p_holm"] >= table["p_wilcoxon"]).all()
