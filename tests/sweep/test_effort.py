"""Comparisons at equal scans (travel free) and the gain calibration, on tables known by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from nbv_gym.sweep.effort import calibration_table, curves_at, q_after_scans


def _steps(key, policy, q, path):
    return [
        {"key": key, "policy": policy, "asset": "cuboids", "step": s, "q": v, "path_length_m": m}
        for s, (v, m) in enumerate(zip(q, path, strict=True))
    ]


RUNS = pd.DataFrame(
    [
        {"key": "a", "policy": "p", "asset": "cuboids"},
        {"key": "b", "policy": "p", "asset": "cuboids"},
        {"key": "c", "policy": "r", "asset": "cuboids"},
    ]
)
STEPS = pd.DataFrame(
    _steps("a", "p", [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], [0, 1, 2, 3, 4, 5])
    + _steps("b", "p", [0.0, 0.3, 0.5, 0.6, 0.7, 0.9, 1.0, 1.0], [0, 2, 4, 6, 8, 10, 12, 14])
    + _steps("c", "r", [0.0, 0.2], [0, 9])
)


def test_curves_interpolate_inside_each_run_only():
    curves = curves_at(STEPS, "path_length_m", "q", np.array([3.0, 5.0, 20.0]))
    assert curves["a"][:2] == pytest.approx([0.3, 0.5]) and np.isnan(curves["a"][2])
    assert curves["b"][:2] == pytest.approx([0.4, 0.55])  # halfway between 2/4 m and 4/6 m


def test_q_after_scans_averages_the_runs_that_took_them():
    table = q_after_scans(RUNS, STEPS, ["p", "r"], budgets=(1, 5, 7)).set_index("policy")
    assert table.loc["p", "q_after_1"] == pytest.approx(0.2) and table.loc["p", "runs_at_1"] == 2
    assert table.loc["p", "q_after_5"] == pytest.approx(0.7)  # (0.5 + 0.9) / 2
    assert table.loc["p", "q_after_7"] == pytest.approx(1.0) and table.loc["p", "runs_at_7"] == 1
    assert np.isnan(table.loc["r", "q_after_5"]) and table.loc["r", "runs_at_5"] == 0


def test_calibration_is_the_ratio_of_realised_to_predicted_gain():
    steps = pd.DataFrame(
        {
            "policy": ["nbv-nobs"] * 4 + ["closest-frontier"] * 2,
            "step": [0, 1, 2, 3, 1, 2],
            "predicted_gain": [np.nan, 10.0, 4.0, 0.0, np.nan, np.nan],
            "realised_gain": [np.nan, 20.0, 4.0, 3.0, np.nan, np.nan],
        }
    )
    table = calibration_table(steps).set_index("policy")
    assert list(table.index) == ["nbv-nobs"]  # no prediction, no row; zero predictions skipped
    assert table.loc["nbv-nobs", "median"] == pytest.approx(1.5)  # median of 2.0 and 1.0
    assert table.loc["nbv-nobs", "steps"] == 2
