"""The smallest p-value a test can give for its sample sizes, checked against scipy's exact
tests, and the power note built on it."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import mannwhitneyu, wilcoxon

from nbv_gym.reporting.inference import (
    can_reach,
    power_note,
    smallest_p_mannwhitney,
    smallest_p_spearman,
    smallest_p_wilcoxon,
)
from nbv_gym.sweep.verdict import spearman_greater


@pytest.mark.parametrize("n", [1, 2, 5, 8, 12])
@pytest.mark.parametrize("alternative", ["two-sided", "greater"])
def test_smallest_wilcoxon_p_is_scipys_exact_p_of_all_one_sign(n, alternative):
    diff = np.arange(1.0, n + 1)  # every difference positive: the most extreme sample
    exact = wilcoxon(diff, alternative=alternative, method="exact").pvalue
    assert smallest_p_wilcoxon(n, alternative) == pytest.approx(exact)


@pytest.mark.parametrize(("n_a", "n_b"), [(1, 1), (2, 2), (3, 5), (8, 8)])
@pytest.mark.parametrize("alternative", ["two-sided", "greater"])
def test_smallest_mann_whitney_p_is_scipys_exact_p_of_separated_samples(n_a, n_b, alternative):
    a, b = np.arange(n_a) + 100.0, np.arange(n_b, dtype=float)  # every a above every b
    exact = mannwhitneyu(a, b, alternative=alternative, method="exact").pvalue
    assert smallest_p_mannwhitney(n_a, n_b, alternative) == pytest.approx(exact)


@pytest.mark.parametrize("n", [3, 4, 5])
def test_smallest_spearman_p_is_the_exact_permutation_p_of_a_perfect_order(n):
    x = np.arange(n, dtype=float)
    rho, p = spearman_greater(x, x)
    assert rho == pytest.approx(1.0) and p == pytest.approx(smallest_p_spearman(n, "greater"))


def test_empty_samples_and_bad_alternatives():
    assert smallest_p_wilcoxon(0) == smallest_p_mannwhitney(0, 3) == 1.0
    with pytest.raises(ValueError, match="alternative must be one of"):
        smallest_p_wilcoxon(3, "bigger")


def test_the_quick_sweeps_pairwise_tables_cannot_reach_significance():
    # 8 runs a side, 21 pairs of 7 policies, Holm: the smallest adjusted p is 21 · 2/2^8.
    smallest = smallest_p_wilcoxon(8)
    assert smallest * 21 == pytest.approx(0.1640625)
    assert not can_reach(smallest, 21) and can_reach(smallest, 6)
    note = power_note(smallest, 21, "two-sided Wilcoxon signed-rank test")
    assert "0.00781" in note and "smallest adjusted p 0.164" in note
    assert power_note(smallest, 6, "two-sided Wilcoxon signed-rank test") == ""
