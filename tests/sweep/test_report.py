"""The report, built from a small synthetic results folder whose tables are known by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from nbv_gym.reporting.inference import bootstrap_mean, q_auc, q_curve, share_significant
from nbv_gym.sweep.folder import CUBOID_COLUMNS, RUN_COLUMNS, SweepError
from nbv_gym.sweep.report import build_report

# (policy, repeat) → the run's (discovered, Q) steps and whether its cuboids follow Table I's H1.
RUNS = {
    ("random-frontier", 0): ([0.2, 0.7], [0.1, 0.3], True),
    ("random-frontier", 1): ([0.2, 0.5], [0.1, 0.2], False),
    ("closest-frontier", 0): ([0.2, 0.8], [0.1, 0.4], True),
    ("closest-frontier", 1): ([0.2, 0.8], [0.1, 0.4], True),
}
# By hand: area through (0, 0), trapezoids, cut at 0.7.
AUC = {
    ("random-frontier", 0): 0.5 * 0.2 * 0.1 + 0.5 * (0.1 + 0.3) * 0.5,  # 0.11
    ("random-frontier", 1): 0.5 * 0.2 * 0.1 + 0.5 * (0.1 + 0.2) * 0.3,  # 0.055
    ("closest-frontier", 0): 0.5 * 0.2 * 0.1 + 0.5 * (0.1 + 0.35) * 0.5,  # Q(0.7) = 0.35
    ("closest-frontier", 1): 0.5 * 0.2 * 0.1 + 0.5 * (0.1 + 0.35) * 0.5,
}


def _cuboids(identity: dict, follows_h1: bool) -> pd.DataFrame:
    """40 U_occ and 40 U_empty cuboids whose quality rises with n_obs, n_Ω, σ_θ and falls with
    r_min (every Table I test clearly significant) — or the reverse (none significant)."""
    i = np.tile(np.arange(1, 41), 2)
    occ = np.repeat([True, False], 40)
    good = i / 40 if follows_h1 else (41 - i) / 40
    table = {
        "cuboid": np.arange(80),
        "ix": i,
        "iy": i,
        "iz": np.zeros(80, int),
        "u_occ": occ,
        "observed": np.ones(80, bool),
        "n_obs": i,
        "r_min": (41 - i).astype(float),
        "n_omega": i,
        "sigma_theta": i / 40,
        "l1": np.where(occ, np.nan, 500 - 200 * good),
        "quality": good,
    }
    for name in CUBOID_COLUMNS:
        if name.startswith("cov_"):
            table[name] = np.where(occ, good, np.nan)
    frame = pd.DataFrame({**{k: [v] * 80 for k, v in identity.items()}, **table})
    return frame[list(CUBOID_COLUMNS)]


@pytest.fixture
def results(tmp_path):
    """A results folder with the runs of :data:`RUNS` on one world at noise 0."""
    runs, steps, cuboids = [], [], []
    for (policy, repeat), (discovered, q, follows_h1) in RUNS.items():
        identity = {
            "key": f"pp1-cuboids/noise0/{policy}/rep{repeat}",
            "world": "pp1-cuboids",
            "asset": "cuboids",
            "noise": 0,
            "policy": policy,
            "repeat": repeat,
        }
        runs.append(
            {
                **identity,
                "status": "ok",
                "steps": 1,
                "discovered": discovered[-1],
                "q": q[-1],
                "q_paper": q[-1],
                "path_length_m": 10.0,
                "wall_time_s": 1.0,
                "total_time_s": 1.0,
                "attempts": 1,
                "seed": 7,
            }
        )
        steps += [
            {
                **identity,
                "step": s,
                "discovered": d,
                "q": v,
                "q_paper": v,
                "path_length_m": 10.0 * s,
            }
            for s, (d, v) in enumerate(zip(discovered, q, strict=True))
        ]
        cuboids.append(_cuboids(identity, follows_h1))
    failed = {
        "key": "pp1-cuboids/noise0/nbv-nobs/rep0",
        "world": "pp1-cuboids",
        "noise": 0,
        "policy": "nbv-nobs",
        "repeat": 0,
        "status": "failed",
        "attempts": 3,
        "error": "RuntimeError: boom",
    }
    pd.DataFrame([*runs, failed], columns=list(RUN_COLUMNS)).to_csv(
        tmp_path / "runs.csv", index=False
    )
    pd.DataFrame(steps).to_csv(tmp_path / "steps.csv", index=False)
    pd.concat(cuboids).to_parquet(tmp_path / "cuboids.parquet")
    return tmp_path


def test_report_tables_hold_the_hand_computed_values(results):
    page = build_report(results)
    report = results / "report"
    final = pd.read_csv(report / "final_q.csv").set_index("policy")
    assert final.loc["random-frontier", "q_mean"] == pytest.approx(0.25)
    assert final.loc["random-frontier", "auc_mean"] == pytest.approx(0.0825)
    assert final.loc["closest-frontier", ["q_mean", "q_low", "q_high"]].tolist() == pytest.approx(
        [0.4] * 3
    )
    assert final.loc["closest-frontier", "auc_mean"] == pytest.approx(0.1225)
    assert (
        final.loc["random-frontier", "q_low"] >= 0.2
        and final.loc["random-frontier", "q_high"] <= 0.3
    )
    assert final.loc["random-frontier", "runs"] == 2 and "nbv-nobs" not in final.index

    pairs = pd.read_csv(report / "pairwise_q.csv").iloc[0]
    assert (pairs["a"], pairs["b"], pairs["pairs"]) == ("random-frontier", "closest-frontier", 2)
    assert pairs["diff_mean"] == pytest.approx(-0.15) and pairs["a_better"] == 0
    assert pairs["diff_low"] == pytest.approx(-0.2) and pairs["diff_high"] == pytest.approx(-0.1)

    # Table II on the random-frontier runs only: one follows H1 everywhere, one never → 0.5.
    table2 = pd.read_csv(report / "table2.csv", index_col=0)
    assert list(table2.index) == ["n_obs", "r_min", "n_omega", "sigma_theta"]
    assert list(table2.columns) == ["cov", "l1"]
    assert np.allclose(table2.to_numpy(), 0.5)
    tests = pd.read_csv(report / "indicator_tests.csv")
    assert set(tests["policy"]) == {"random-frontier"} and len(tests) == 2 * 8

    text = page.read_text()
    figures = ("fig2_q_paper_vs_discovered_noise0.png", "fig2_q_vs_discovered_noise0.png",
               "fig1_quality_vs_statistics_noise0.png", "q_vs_scans.png", "q_vs_path.png")  # fmt: skip
    for name in figures:
        assert (report / name).stat().st_size > 10_000 and f"]({name})" in text
    assert "| n_obs | 0.50 | 0.50 |" in text
    assert "pp1-cuboids/noise0/nbv-nobs/rep0 | 3 | RuntimeError: boom" in text
    assert "4 finished runs, 1 failed" in text
    # 2 pairs: the smallest two-sided Wilcoxon p is 2/2² = 0.5, so each pairwise table says so.
    assert text.count("smallest p a two-sided Wilcoxon signed-rank test can give is 0.5") == 2
    verdict = pd.read_csv(report / "verdict.csv")
    assert list(verdict.columns) == [
        "claim", "paper", "n", "test", "p", "effect", "ours", "verdict", "model",
    ]  # fmt: skip
    assert "Fig. 1: cov rises with n_obs" in set(verdict["claim"])
    assert "q_vs_time" not in text and not (report / "q_vs_time.png").exists()  # not time task


def test_the_report_of_a_time_task_sweep_draws_q_against_the_robots_time(results, make_config):
    steps = pd.read_csv(results / "steps.csv")
    steps.assign(elapsed_s=40.0 * steps["step"]).to_csv(results / "steps.csv", index=False)
    policies = ["random-frontier", "closest-frontier"]
    make_config(results, "sweep", task="time", time_budget_s=300.0, policies=policies, repeats=2)
    text = build_report(results).read_text()
    assert "## Q against the robot's time (time task)" in text and "300 s budget" in text
    assert "](q_vs_time.png)" in text
    assert (results / "report" / "q_vs_time.png").stat().st_size > 10_000
    html = (results / "report" / "report.html").read_text()
    assert "<h2>Q against the robot's time (time task)" in html


def test_report_of_a_folder_without_results_says_what_to_run(tmp_path):
    with pytest.raises(SweepError, match="Run `nbv-gym sweep CONFIG"):
        build_report(tmp_path)


def test_auc_and_curves_by_hand():
    assert q_auc([0.2, 0.7], [0.1, 0.3], 0.7) == pytest.approx(0.11)
    assert q_auc([0.2, 0.8], [0.1, 0.4], 0.7) == pytest.approx(0.1225)
    assert q_auc([0.2, 0.2, 0.4], [0.1, 0.15, 0.3], 0.7) == pytest.approx(0.015 + 0.045)
    curve = q_curve([0.2, 0.2, 0.4], [0.1, 0.15, 0.3], np.array([0.1, 0.2, 0.3, 0.5]))
    assert np.isnan(curve[[0, 3]]).all() and curve[1:3] == pytest.approx([0.15, 0.225])


def test_bootstrap_and_shares():
    rng = np.random.default_rng(0)
    constant = bootstrap_mean([2.0, 2.0, 2.0], rng)
    assert (constant.mean, constant.low, constant.high, constant.n) == (2.0, 2.0, 2.0, 3)
    interval = bootstrap_mean(np.arange(100.0), rng)
    assert interval.mean == 49.5 and 40 < interval.low < 49.5 < interval.high < 59
    assert share_significant([0.01, 0.2, np.nan, 0.04]) == pytest.approx(2 / 3)
