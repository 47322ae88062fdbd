"""The reproduction verdict's rules on hand-made tables."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from nbv_gym.reporting.verdicts import NOT_REPRODUCED
from nbv_gym.sweep.tables import verdict_section
from nbv_gym.sweep.verdict import (
    comparison_rows,
    harder_row,
    paired_at_fractions,
    table2_rows,
    trend_rows,
    verdict,
    verdict_table,
)
from nbv_gym.worlds import ASSET_TYPES


def test_verdict_words():
    assert [verdict(3, 3), verdict(1, 3), verdict(0, 3), verdict(0, 0)] == [
        "reproduced", "partly", "not reproduced", "no data",
    ]  # fmt: skip


def _cuboids(asset, cov_sign):
    i = np.arange(1, 61, dtype=float)
    occ = np.arange(60) % 2 == 0
    cov = (i if cov_sign > 0 else -i) / 60
    return pd.DataFrame(
        {
            "asset": asset, "u_occ": occ, "n_obs": i, "r_min": 61 - i, "n_omega": i,
            "sigma_theta": i / 60, "cov_q": np.where(occ, cov, np.nan),
            "l1": np.where(occ, np.nan, 500 - i),
        }
    )  # fmt: skip


def test_trends_need_the_expected_sign_in_every_asset_type():
    def rows(*signs):
        cuboids = pd.concat([_cuboids(a, s) for a, s in zip(ASSET_TYPES, signs, strict=False)])
        return {r["claim"]: r for r in trend_rows(cuboids)}

    # cov rises with n_obs in two asset types but falls in trees: partly (mean ρ +1/3) …
    mixed = rows(1, 1, -1)
    assert mixed["Fig. 1: cov rises with n_obs"]["verdict"] == "partly"
    assert mixed["Fig. 1: L1 falls with n_obs"]["verdict"] == "reproduced"
    assert mixed["Fig. 1: L1 rises with r_min"]["verdict"] == "reproduced"
    assert "cuboids +1.00" in mixed["Fig. 1: cov rises with n_obs"]["ours"]
    # … but never with a mean ρ that is not of the expected sign (here 0).
    assert rows(1, -1)["Fig. 1: cov rises with n_obs"]["verdict"] == NOT_REPRODUCED


def test_table2_rows_compare_with_the_paper():
    shares = pd.DataFrame(
        {"cov": [0.74, 0.50, 0.70, 1.0], "l1": [0.5, 1.0, 0.87, 1.0]},
        index=["n_obs", "r_min", "n_omega", "sigma_theta"],
    )
    rows = {r["claim"]: r["verdict"] for r in table2_rows(shares)}
    assert rows["Table II: n_obs indicates cov"] == "reproduced"  # equal
    assert rows["Table II: n_obs indicates l1"] == NOT_REPRODUCED  # 0.90 → 0.50
    assert rows["Table II: r_min indicates cov"] == NOT_REPRODUCED  # 0.89 → 0.50
    assert rows["Table II: n_omega indicates cov"] == "reproduced"  # 0.04 below
    assert rows["Table II: sigma_theta indicates l1"] == "no paper value"  # not legible there
    missing = table2_rows(shares.drop(index="r_min"))
    assert {r["claim"]: r["verdict"] for r in missing}["Table II: r_min indicates cov"] == "no data"


def _sweep(slopes: dict[tuple[str, str], list[float]]):
    """runs and steps of runs whose Q_paper is ``slope · discovered`` (0.2 → 0.8 discovered in
    one step, 10 scans): ``slopes[(asset, policy)]`` gives one slope per repeat (a world per
    asset type, noise 0)."""
    runs, steps = [], []
    for (asset, policy), values in slopes.items():
        for repeat, slope in enumerate(values):
            key = f"w-{asset}/{policy}/{repeat}"
            runs.append({"key": key, "world": f"w-{asset}", "noise": 0, "repeat": repeat,
                         "asset": asset, "policy": policy})  # fmt: skip
            steps += [
                {"key": key, "step": s, "discovered": d, "q_paper": slope * d, "q": slope * d}
                for s, d in ((0, 0.2), (10, 0.8))
            ]
    return pd.DataFrame(runs), pd.DataFrame(steps)


def _fig2(runs, steps):
    rows, advantage = comparison_rows(
        runs, paired_at_fractions(runs, steps), "fig2", np.random.default_rng(0)
    )
    return rows[0], advantage


def test_nbv_higher_everywhere_with_enough_pairs_is_reproduced():
    runs, steps = _sweep(
        {("cuboids", "nbv-nobs"): [0.2 + 0.01 * r for r in range(8)],
         ("cuboids", "closest-frontier"): [0.1] * 8}
    )  # fmt: skip
    row, advantage = _fig2(runs, steps)
    assert row["claim"] == "Fig. 2: nbv-nobs above closest-frontier"
    assert row["verdict"] == "reproduced" and row["n"] == "8"
    # 8 pairs, all higher: one-sided p = 2^-8 each, Holm over the 3 fractions: 3 / 256.
    assert row["p"] == "50%: 0.0117; 60%: 0.0117; 70%: 0.0117"
    assert row["effect"].startswith("50%: +0.0")  # the interval follows
    assert "higher (p < 0.05, uncorrected) 3/3, lower 0/3" in row["ours"]
    assert advantage["cuboids"] > 0


def test_two_runs_per_cell_are_inconclusive_not_not():
    runs, steps = _sweep(
        {("cuboids", "nbv-nobs"): [0.05, 0.06], ("cuboids", "random-free"): [0.1, 0.1]}
    )
    row, _ = _fig2(runs, steps)
    assert row["verdict"] == "inconclusive (n = 2)"  # smallest p: 3 · 2^-2 ≥ 0.05


def test_a_mean_effect_of_the_wrong_sign_is_never_partly():
    # Slightly higher on all 8 cuboids pairs (that cell alone is significant), far lower on trees.
    runs, steps = _sweep(
        {("cuboids", "nbv-nobs"): [0.11 + 0.001 * r for r in range(8)],
         ("cuboids", "closest-frontier"): [0.1] * 8,
         ("trees", "nbv-nobs"): [0.01] * 8, ("trees", "closest-frontier"): [0.1] * 8}
    )  # fmt: skip
    row, _ = _fig2(runs, steps)
    assert "higher (p < 0.05, uncorrected) 3/6, lower 3/6" in row["ours"]
    assert row["verdict"] == NOT_REPRODUCED  # the old rule read "partly" (some cells higher)
    assert "over all pairs -0.0" in row["ours"]


def _units(advantages: dict[str, list[float]]) -> pd.DataFrame:
    return pd.DataFrame(
        [{"asset": a, "advantage": v} for a, values in advantages.items() for v in values]
    )


def test_negative_advantages_that_grow_with_difficulty_are_not_reproduced():
    growing = {"cuboids": -0.03, "crosses": -0.02, "helicoids": -0.01, "trees": -0.005}
    row = harder_row(_units({a: [v, v + 0.001, v - 0.001] for a, v in growing.items()}))
    assert float(row["effect"].split()[1]) > 0.8 and float(row["p"]) < 0.05  # it grows…
    assert row["verdict"] == NOT_REPRODUCED  # …but the advantage has the wrong sign
    positive = {a: [-v, -v + 0.001, -v - 0.001] for a, v in growing.items()}
    assert harder_row(_units(positive))["verdict"] == NOT_REPRODUCED  # shrinks with difficulty
    flipped = {a: [v + 0.04, v + 0.041, v + 0.039] for a, v in growing.items()}
    assert harder_row(_units(flipped))["verdict"] == "reproduced"


def test_harder_worlds_with_too_few_units_are_inconclusive():
    row = harder_row(_units({"cuboids": [0.01], "crosses": [0.02], "trees": [0.03]}))
    assert row["verdict"] == "inconclusive (n = 3)"  # exact permutation p ≥ 1/3! > 0.05


def test_ordering_of_runs_that_never_reach_the_fractions_has_no_data():
    runs = pd.DataFrame(
        [
            {"key": p, "world": "w", "noise": 0, "repeat": 0, "asset": "trees", "policy": p}
            for p in ("nbv-nobs", "random-free")
        ]
    )
    steps = pd.DataFrame(
        [
            {"key": p, "step": s, "discovered": 0.1 * (s + 1), "q_paper": 0.1}
            for p in runs["key"]
            for s in range(3)
        ]
    )
    row, advantage = _fig2(runs, steps)
    assert row["verdict"] == "no data" and advantage == {}


def test_each_visibility_model_gets_its_own_verdict_and_power_note(tmp_path):
    slopes = {("cuboids", "closest-frontier"): [0.1, 0.1]}
    for model, slope in (("fov", 0.2), ("sphere", 0.05)):
        slopes[("cuboids", f"nbv-nobs@{model}")] = [slope, slope + 0.01]
    runs, steps = _sweep(slopes)
    table = verdict_table(runs, steps, None, None)
    fig2 = table[table["claim"].str.contains("Fig. 2: nbv-")]
    assert list(fig2["claim"]) == [
        "[fov] Fig. 2: nbv-nobs@fov above closest-frontier",
        "[sphere] Fig. 2: nbv-nobs@sphere above closest-frontier",
    ]
    assert (fig2["verdict"] == "inconclusive (n = 2)").all()
    budget = table[table["claim"].str.contains("Budget:")]
    assert list(budget["model"]) == ["fov", "sphere"]
    text = verdict_section(table, tmp_path)
    assert "### Per visibility model" in text and "| fov | 1 | 0/1 | 0/1 | 0/1 |" in text
    assert (
        "**Power note:**" in text
        and "smallest p a one-sided Wilcoxon test can give is 0.25" in (text)
    )
    assert (tmp_path / "verdict.csv").exists()


def test_fig1_trends_add_a_run_level_test_beside_the_cuboid_level_one():
    """Cuboids of 6 runs per asset type, each run a perfect trend: the pooled (cuboid-level)
    test gives p < 1e-16, the run-level one (the runs' ρ, Wilcoxon) only what 6 runs can give
    (two-sided exact: 2/64 = 0.031). The verdict follows the cuboid-level test."""
    from nbv_gym.sweep.verdict import run_level_p

    frames = []
    for asset in ASSET_TYPES:
        for run in range(6):
            frames.append(_cuboids(asset, 1).assign(key=f"{asset}/{run}"))
    cuboids = pd.concat(frames)
    row = {r["claim"]: r for r in trend_rows(cuboids)}["Fig. 1: cov rises with n_obs"]
    assert row["verdict"] == "reproduced"
    assert row["p"] == "cuboids: largest < 1e-16; runs: largest 0.0312"
    assert "cuboid-level" in row["test"] and "run-level" in row["test"]
    assert row["n"].endswith(", 24 runs")
    one = cuboids[cuboids["asset"] == ASSET_TYPES[0]]
    assert run_level_p(one[one["u_occ"]], "n_obs", "cov_q") == pytest.approx(2 / 64)


def test_the_verdict_tables_say_a_shared_description_once():
    """Rows of one test that share the paper's statement and the test show them once above
    their table, not on every row; a column that varies stays in the table."""
    from nbv_gym.sweep.tables import verdict_tables
    from nbv_gym.sweep.verdict import COLUMNS

    rows = [
        {"claim": f"Fig. 1: c{i}", "paper": "same claim", "n": "3", "test": "test A", "p": "0.1",
         "effect": "—", "ours": "—", "verdict": "not", "model": "—"}
        for i in range(3)
    ] + [
        {"claim": f"Table II: d{i}", "paper": f"paper {i}", "n": "3", "test": "test B", "p": "0.2",
         "effect": "—", "ours": "—", "verdict": "not", "model": "—"}
        for i in range(2)
    ]  # fmt: skip
    text = "\n".join(verdict_tables(pd.DataFrame(rows, columns=COLUMNS)))
    assert text.count("same claim") == 1 and text.count("test A") == 1
    assert text.count("test B") == 1 and "paper 0" in text and "paper 1" in text
    assert "**Fig. 1** — paper: same claim — test: test A" in text
    assert "| claim | n | p | verdict |" in text  # test A's table: effect and ours all "—"
    assert "| claim | paper | n | p | verdict |" in text  # test B's
