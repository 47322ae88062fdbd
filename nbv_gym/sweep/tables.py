"""The sweep report's tables: final-Q summaries, paired comparisons, the indicator tests and
Table II, with the formatting of their intervals and p-values."""

from __future__ import annotations

import itertools

import numpy as np

from nbv_gym.mapping.statistics import STATISTICS
from nbv_gym.reporting.formatting import (
    is_oracle_label,
    markdown_table,
    ranked_apart,
)
from nbv_gym.reporting.inference import (
    Interval,
    compare_paired,
    holm,
    iqm,
    power_note,
    probability_of_improvement_interval,
    share_significant,
    smallest_p_wilcoxon,
    stratified_interval,
)

UNIT_COLUMNS = ("world", "noise", "repeat")  # what pairs runs of two policies


def final_table(ok, policies: list[str], rng: np.random.Generator):
    """Per policy: runs, final Q and AUC (mean with 95 % stratified bootstrap interval: runs
    resampled within each world × noise level), mean Q_paper, discovered fraction, steps and path
    length. A DataFrame, one row per policy."""
    import pandas as pd

    rows = []
    for policy in policies:
        group = ok[ok["policy"] == policy]
        if group.empty:
            continue
        strata = strata_of(group)
        q = stratified_interval(group["q"], strata, np.mean, rng)
        auc = stratified_interval(group["auc"], strata, np.mean, rng)
        q_iqm = stratified_interval(group["q"], strata, iqm, rng)
        rows.append(
            {
                "policy": policy,
                "runs": len(group),
                "q_mean": q.mean,
                "q_low": q.low,
                "q_high": q.high,
                "q_iqm": q_iqm.mean,
                "q_iqm_low": q_iqm.low,
                "q_iqm_high": q_iqm.high,
                "auc_mean": auc.mean,
                "auc_low": auc.low,
                "auc_high": auc.high,
                "q_paper_mean": group["q_paper"].mean(),
                "discovered_mean": group["discovered"].mean(),
                "steps_mean": group["steps"].mean(),
                "path_length_m_mean": group["path_length_m"].mean(),
            }
        )
    return pd.DataFrame(rows)


def pairwise_table(ok, policies: list[str], metric: str, rng: np.random.Generator):
    """Every pair of policies (A, B) compared on ``metric`` (``q`` or ``auc``) over the runs they
    share a world, noise level and repeat with: mean A − B with its 95 % stratified bootstrap
    interval, share of pairs where A is higher, the probability of improvement with its 95 %
    stratified bootstrap interval, two-sided Wilcoxon signed-rank p. A DataFrame."""
    import pandas as pd

    wide = ok.pivot_table(index=list(UNIT_COLUMNS), columns="policy", values=metric)
    tasks = tasks_of(wide)
    rows = []
    for a, b in itertools.combinations([p for p in policies if p in wide.columns], 2):
        paired = wide[[a, b]].dropna()
        result = compare_paired(paired[a].to_numpy(), paired[b].to_numpy(), rng, tasks_of(paired))
        improvement = probability_of_improvement_interval(wide[a], tasks, wide[b], tasks, rng)
        rows.append(
            {
                "a": a,
                "b": b,
                "pairs": result.difference.n,
                "diff_mean": result.difference.mean,
                "diff_low": result.difference.low,
                "diff_high": result.difference.high,
                "a_better": result.a_better,
                "p_improvement": improvement.mean,
                "p_improvement_low": improvement.low,
                "p_improvement_high": improvement.high,
                "p_wilcoxon": result.p_value,
            }
        )
    table = pd.DataFrame(rows)
    if len(table):
        # oracle pairs after the others, each group its own Holm family
        oracle = table["a"].map(is_oracle_label) | table["b"].map(is_oracle_label)
        table = table.assign(oracle_pair=oracle)
        table = table.sort_values("oracle_pair", kind="stable", ignore_index=True)
        table["p_holm"] = table.groupby("oracle_pair")["p_wilcoxon"].transform(holm)
        table = table.drop(columns="oracle_pair")
    return table


def pairwise_text(pairs, label: str) -> str:
    """The Markdown table of the policy pairs ``pairs`` (differences, intervals, p-values) under the
    quantity ``label``, with a power note."""
    if pairs.empty:
        return "Fewer than two policies."
    rows = [
        [
            f"{r.a} − {r.b}",
            r.pairs,
            ci_text(Interval(r.diff_mean, r.diff_low, r.diff_high, r.pairs), signed=True),
            f"{r.a_better:.0%}",
            f"{r.p_improvement:.2f} [{r.p_improvement_low:.2f}, {r.p_improvement_high:.2f}]",
            p_text(r.p_wilcoxon),
            p_text(r.p_holm),
        ]
        for r in pairs.itertuples()
    ]
    others = pairs[~(pairs["a"].map(is_oracle_label) | pairs["b"].map(is_oracle_label))]
    tested = others[np.isfinite(others["p_wilcoxon"])]
    note = power_note(
        smallest_p_wilcoxon(int(tested["pairs"].max()) if len(tested) else 0),
        len(tested),
        "two-sided Wilcoxon signed-rank test",
    )
    return (
        (note + "\n\n" if note else "")
        + f"Runs paired by world, noise level and repeat (same seed). Difference of {label}, "
        "share of pairs where the first policy is higher, probability of improvement P(A > B) "
        "(per world and noise level, the chance that a run of A scores higher than a run of B, ties ½; "
        "averaged; 95 % interval: runs of A and B resampled within each world and noise level), "
        "two-sided Wilcoxon signed-rank p, and that p Holm-adjusted over all the "
        "pairs of this table (reject at α = 0.05 where the Holm p < 0.05).\n\n"
        + markdown_table(
            [
                "A − B",
                "pairs",
                "mean difference [95% CI]",
                "A higher",
                "P(A > B) [95% CI]",
                "p",
                "p (Holm)",
            ],
            ranked_apart(rows),
        )
    )


def indicator_tests_table(cuboids):
    """Per run, metric and statistic: the one-sided Mann–Whitney test of Table I. ``cov`` (at
    Q's setting, column ``cov_q``) on U_occ cuboids and ``l1`` on U_empty cuboids. A DataFrame
    with the run's identity, metric, statistic, threshold, U, p, population sizes."""
    import pandas as pd

    from nbv_gym.metrics.indicators import indicator_tests

    rows = []
    cuboids = cuboids[cuboids["n_obs"] >= 1]  # the paper's tests: observed from at least once
    for key, run in cuboids.groupby("key", sort=False):
        occ = run["u_occ"].to_numpy(bool)
        metrics = {
            "cov": np.where(occ, run["cov_q"].to_numpy(float), np.nan),
            "l1": np.where(~occ, run["l1"].to_numpy(float), np.nan),
        }
        stats = {s: run[s].to_numpy(float) for s in STATISTICS}
        first = run.iloc[0]
        identity = {c: first[c] for c in ("world", "asset", "noise", "policy", "repeat")}
        for test in indicator_tests(metrics, stats):
            rows.append(
                {
                    "key": key,
                    **identity,
                    "metric": test.metric,
                    "statistic": test.statistic,
                    "threshold": test.threshold,
                    "u_statistic": test.u_statistic,
                    "p_value": test.p_value,
                    "n_at_or_above": test.n_at_or_above,
                    "n_below": test.n_below,
                }
            )
    return pd.DataFrame(rows)


def table2(tests, by: tuple[str, ...] = ()):
    """Share of tests with p < 0.05 per statistic (rows) and metric (columns), optionally per
    group ``by`` (e.g. ``("asset", "noise")``): the paper's Table II. A DataFrame."""
    keys = [*by, "statistic", "metric"]
    shares = tests.groupby(keys, sort=False)["p_value"].agg(share_significant)
    table = shares.unstack("metric")
    if not by:
        table = table.reindex([s for s in STATISTICS if s in table.index])
    return table[[m for m in ("cov", "l1") if m in table.columns]]


def ci_text(interval: Interval, signed: bool = False) -> str:
    """``mean [low, high]`` of ``interval`` (signed with ``signed``); ``—`` when undefined."""
    sign = "+" if signed else ""
    if not np.isfinite(interval.mean):
        return "—"
    return f"{interval.mean:{sign}.4f} [{interval.low:{sign}.4f}, {interval.high:{sign}.4f}]"


def p_text(value: float) -> str:
    """A p-value to 3 significant digits; ``—`` when undefined."""
    return "—" if not np.isfinite(value) else f"{value:.3g}"


def share_text(value: float) -> str:
    """A share to 2 decimals; ``—`` when undefined."""
    return "—" if not np.isfinite(value) else f"{value:.2f}"


def strata_of(runs) -> list[tuple]:
    """The stratum (world, noise level) of each run of a runs table: the bootstrap resamples
    runs within these."""
    return list(zip(runs["world"], runs["noise"], strict=True))


def tasks_of(wide) -> list[tuple]:
    """The task (world, noise level) of each row of a table indexed by world, noise, repeat."""
    index = wide.index
    return list(zip(index.get_level_values("world"), index.get_level_values("noise"), strict=True))
