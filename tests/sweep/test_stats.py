"""The report's statistics against hand-computed values and textbook results."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from nbv_gym.reporting.inference import (
    bootstrap_iqm,
    bootstrap_mean,
    holm,
    iqm,
    optimality_gap,
    performance_profile,
    probability_of_improvement,
    probability_of_improvement_interval,
    stratified_interval,
    stratified_resamples,
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

    from nbv_gym.sweep.tables import pairwise_table

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


# -- stratified bootstrap, IQM, probability of improvement with its interval ----------------------


def test_stratified_interval_of_two_worlds_stays_within_what_resampling_within_them_reaches():
    # world a: 1, 2, 3 (mean 2); world b: 10, 20, 30 (mean 20). Resampling within each world,
    # the mean of six runs lies between (3·1 + 3·10)/6 = 5.5 and (3·3 + 3·30)/6 = 16.5.
    values = [1.0, 2.0, 3.0, 10.0, 20.0, 30.0]
    strata = [("a", 0)] * 3 + [("b", 0)] * 3
    ours = stratified_interval(values, strata, np.mean, np.random.default_rng(0))
    assert ours.mean == pytest.approx(11.0) and ours.n == 6
    assert 5.5 <= ours.low < 11.0 < ours.high <= 16.5
    # pooling the worlds (plain bootstrap) mixes their spread into the interval: wider
    pooled = stratified_interval(values, ["all"] * 6, np.mean, np.random.default_rng(0))
    assert pooled.high - pooled.low > ours.high - ours.low


def test_stratified_interval_matches_scipys_independent_resampling_of_each_stratum():
    rng = np.random.default_rng(5)
    groups = [rng.normal(m, 1.0, 6) for m in (0.0, 3.0, 10.0)]
    values = np.concatenate(groups)
    strata = np.repeat([0, 1, 2], 6)

    def pooled_mean(*samples, axis=-1):
        return np.mean(np.concatenate(samples, axis=axis), axis=axis)

    reference = stats.bootstrap(
        groups, pooled_mean, n_resamples=20_000, method="percentile", rng=np.random.default_rng(6)
    ).confidence_interval
    ours = stratified_interval(values, strata, np.mean, np.random.default_rng(7), 20_000)
    half = (reference.high - reference.low) / 2
    assert ours.low == pytest.approx(reference.low, abs=0.05 * half)
    assert ours.high == pytest.approx(reference.high, abs=0.05 * half)


def test_stratified_interval_collapses_with_one_run_per_stratum():
    interval = stratified_interval(
        [0.3, 0.1, 0.9, 0.5], list("abcd"), iqm, np.random.default_rng(0)
    )
    assert interval.mean == interval.low == interval.high == pytest.approx(0.4)  # mean of .3, .5
    assert np.isnan(stratified_interval([np.nan], ["a"], np.mean, np.random.default_rng(0)).mean)


def test_stratified_resamples_never_cross_a_stratum():
    strata = ["a", "b", "a", "c", "b", "a"]
    draws = stratified_resamples(strata, 500, np.random.default_rng(0))
    labels = np.array(strata)
    assert draws.shape == (500, 6) and (labels[draws] == labels).all()
    assert set(np.unique(draws[:, 0])) == {0, 2, 5}  # every run of stratum a is drawn


def test_iqm_and_optimality_gap_by_hand():
    assert iqm(np.array([5.0, 1.0, 3.0, 100.0, 2.0, 4.0, 0.0, 6.0])) == pytest.approx(3.5)
    assert optimality_gap([0.2, 0.5, 1.0]) == pytest.approx((0.8 + 0.5 + 0.0) / 3)
    assert optimality_gap([0.2, 0.9], target=0.5) == pytest.approx(0.15)  # above target: 0


def test_probability_of_improvement_interval_by_hand():
    # task 1: A = 1, 3 against B = 2 → ½; task 2: A = 5 against B = 5, 4 → (½ + 1)/2 = ¾;
    # the mean ⅝. Resampled: task 1 gives 0, ½ or 1, task 2 ½, ¾ or 1 → the mean in [¼, 1].
    a, tasks_a = [1.0, 3.0, 5.0], ["t1", "t1", "t2"]
    b, tasks_b = [2.0, 5.0, 4.0], ["t1", "t2", "t2"]
    interval = probability_of_improvement_interval(a, tasks_a, b, tasks_b, np.random.default_rng(0))
    assert interval.mean == pytest.approx(0.625) and interval.n == 2
    assert 0.25 <= interval.low < 0.625 < interval.high <= 1.0
    # the same figure as the Mann–Whitney estimate of probability_of_improvement, paired by task
    assert probability_of_improvement([1.0, 3.0, 5.0, np.nan], [2.0, np.nan, 5.0, 4.0],
                                      ["t1", "t1", "t2", "t2"]) == pytest.approx(0.625)  # fmt: skip


def test_probability_of_improvement_interval_collapses_with_one_run_per_task():
    interval = probability_of_improvement_interval(
        [1.0, 2.0, 3.0], ["x", "y", "z"], [0.0, 2.0, 4.0], ["x", "y", "z"], np.random.default_rng(0)
    )
    assert interval.mean == interval.low == interval.high == pytest.approx(0.5)  # 1, ½, 0


def test_performance_profile_by_hand():
    values = [0.1, 0.2, 0.3, 0.4]
    fraction, low, high = performance_profile(
        values, ["a", "a", "b", "b"], [0.0, 0.15, 0.35, 0.5], np.random.default_rng(0)
    )
    np.testing.assert_allclose(fraction, [1.0, 0.75, 0.25, 0.0])
    assert (low <= fraction).all() and (fraction <= high).all()
    assert low[0] == high[0] == 1.0 and low[-1] == high[-1] == 0.0
    # within stratum a (0.1, 0.2) the share above 0.15 ranges over 0, ½, 1 → overall ½ … 1
    assert 0.5 <= low[1] and high[1] <= 1.0


def test_report_intervals_resample_within_world_and_noise():
    import pandas as pd

    from nbv_gym.sweep.tables import final_table, pairwise_table

    # repeats of a (world, noise) agree; worlds differ: a stratified interval has nothing to
    # resample, while pooling the runs would mix the worlds' spread into it
    rows = [
        dict(
            world=w,
            noise=0,
            repeat=r,
            policy=p,
            q=q + (0.1 if p == "a" else 0.0),
            auc=q,
            q_paper=q,
            discovered=0.7,
            steps=9,
            path_length_m=50.0,
        )
        for w, q in (("w1", 0.2), ("w2", 0.6))
        for r in range(3)
        for p in ("a", "b")
    ]
    runs = pd.DataFrame(rows)
    table = final_table(runs, ["a", "b"], np.random.default_rng(0)).set_index("policy")
    assert table.loc["a", "q_low"] == pytest.approx(0.5) == table.loc["a", "q_high"]
    assert table.loc["a", "q_iqm_low"] == table.loc["a", "q_iqm_high"]
    pairs = pairwise_table(runs, ["a", "b"], "q", np.random.default_rng(0)).iloc[0]
    assert pairs["diff_low"] == pytest.approx(0.1) == pairs["diff_high"]
    assert pairs["p_improvement"] == pairs["p_improvement_low"] == pairs["p_improvement_high"] == 1
