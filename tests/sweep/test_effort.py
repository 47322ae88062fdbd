"""Q over effort in the sweep report (equal scans, path, the robot's time) and the gain
calibration, on tables known by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from nbv_gym.benchmark.curves import TIME_GRID_S, grid_curve
from nbv_gym.sweep.effort import (
    calibration_table,
    curves_at,
    effort_curves,
    q_after_scans,
    scans_table,
)


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


def test_curves_against_the_discovered_fraction_interpolate_inside_each_run_only():
    steps = STEPS.assign(discovered=STEPS["path_length_m"] / 100)
    curves = curves_at(steps, "discovered", "q", np.array([0.03, 0.05, 0.2]))
    assert curves["a"][:2] == pytest.approx([0.3, 0.5]) and np.isnan(curves["a"][2])
    assert curves["b"][:2] == pytest.approx([0.4, 0.55])  # halfway between 2/4 m and 4/6 m


def test_q_over_path_is_the_last_scan_within_it_and_holds_the_final_q():
    curves = effort_curves(STEPS, "path_length_m", np.array([3.0, 5.0, 20.0]))
    assert curves["a"].tolist() == [0.3, 0.5, 0.5]  # a drove 5 m: its final Q beyond
    assert curves["b"].tolist() == [0.3, 0.5, 1.0]  # the scan at 2 m, at 4 m, the last


def test_q_after_scans_holds_the_final_q_of_runs_that_stopped_and_counts_those_that_took_them():
    per_run = q_after_scans(RUNS, STEPS, (1, 5, 7))
    assert per_run.loc[0].tolist() == [0.1, 0.5, 0.5] and per_run.loc[2].tolist() == [0.2] * 3
    table = scans_table(RUNS, STEPS, ["p", "r"], budgets=(1, 5, 7)).set_index("policy")
    assert table.loc["p", "q_after_1"] == pytest.approx(0.2) and table.loc["p", "runs_at_1"] == 2
    assert table.loc["p", "q_after_5"] == pytest.approx(0.7)  # (0.5 + 0.9) / 2
    assert table.loc["p", "q_after_7"] == pytest.approx(0.75)  # (0.5 held + 1.0) / 2
    assert table.loc["p", "runs_at_7"] == 1
    assert table.loc["r", "q_after_5"] == pytest.approx(0.2) and table.loc["r", "runs_at_5"] == 0


def test_the_sweep_and_the_scorecard_give_one_q_at_the_same_time_for_a_run_that_ends_early():
    # a time-task run whose budget bought no goal after 410 s of the 600 s
    elapsed = [0.0, 35.0, 35.0, 120.5, 300.0, 410.0]
    q = [0.011, 0.0234567891, 0.025, 0.031, 0.0377, 0.04]
    steps = pd.DataFrame(
        {"key": "t", "step": range(6), "elapsed_s": elapsed, "q": q, "path_length_m": 0.0}
    )
    sweep = effort_curves(steps, "elapsed_s", np.asarray(TIME_GRID_S))["t"]
    scorecard = grid_curve(np.asarray(elapsed), np.asarray(q), TIME_GRID_S)
    assert [round(float(v), 7) for v in sweep] == scorecard
    assert sweep[TIME_GRID_S.index(420.0) :].tolist() == [0.04] * 7  # held to the budget
    assert sweep[TIME_GRID_S.index(30.0)] == 0.011 and sweep[TIME_GRID_S.index(60.0)] == 0.025


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
