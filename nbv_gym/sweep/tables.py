"""The sweep report's tables: final-Q summaries, paired comparisons, the indicator tests and
Table II, with the formatting of their intervals and p-values."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from nbv_gym.mapping.statistics import STATISTICS
from nbv_gym.reporting.formatting import (
    estimate_text,
    is_oracle_label,
    markdown_table,
    number_text,
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
from nbv_gym.reporting.verdicts import INCONCLUSIVE, count_summary
from nbv_gym.sweep.verdict import ALPHA, FRACTIONS

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
    spec = "+.4f" if signed else ".4f"
    return estimate_text(interval.mean, interval.low, interval.high, spec)


def p_text(value: float) -> str:
    """A p-value to 3 significant digits; ``—`` when undefined."""
    return number_text(value, ".3g")


def share_text(value: float) -> str:
    """A share to 2 decimals; ``—`` when undefined."""
    return number_text(value, ".2f")


def strata_of(runs) -> list[tuple]:
    """The stratum (world, noise level) of each run of a runs table: the bootstrap resamples
    runs within these."""
    return list(zip(runs["world"], runs["noise"], strict=True))


def tasks_of(wide) -> list[tuple]:
    """The task (world, noise level) of each row of a table indexed by world, noise, repeat."""
    index = wide.index
    return list(zip(index.get_level_values("world"), index.get_level_values("noise"), strict=True))


def verdict_section(table, out: Path) -> str:
    """The report's verdict section (writes ``verdict.csv``): the rules, the per-model summary
    when the NBV policies fix visibility models, the table, and a power note where the Fig. 2
    tests cannot reach significance."""
    table.to_csv(out / "verdict.csv", index=False)
    summary = count_summary(table["verdict"])
    lines = [
        "## Reproduction verdict",
        "",
        f"Each claim of the paper, computed from this sweep's tables ({summary}). Fig. 1 trends "
        "on the observed cuboids (n_obs ≥ 1) at noise level 1; Fig. 2 at noise level 0 (the "
        "paper's figure) when the sweep has it. Fig. 2 rows: one-sided Wilcoxon signed-rank "
        "tests at 50, 60 and 70 % discovered, p Holm-adjusted over the Fig. 2 family (every "
        "pair and fraction), the effect the mean difference with its 95 % bootstrap interval. "
        "A claim is *reproduced* only with the paper's sign, never *partly* with a mean effect "
        "of the wrong sign, and *inconclusive (n = …)* where the sample cannot reach p < 0.05 "
        "at all. Rules: `nbv_gym/sweep/verdict.py` (docs: verdicts). Table: `verdict.csv`.",
    ]
    note = _power_note(table)
    if note:
        lines += ["", note]
    if table["model"].replace("—", "").astype(bool).any():
        lines += ["", "### Per visibility model", "", model_summary(table)]
    lines += ["", *verdict_tables(table)]
    return "\n".join(lines)


#: The columns of the verdict tables of the report, in order.
SHOWN = ["claim", "paper", "n", "test", "p", "effect", "ours", "verdict"]


#: Columns said once above a table when every row of it has the same value.
SAID_ONCE = ("paper", "test")


def verdict_tables(table) -> list[str]:
    """The verdict rows as Markdown, one table per family of claims (the claim's figure, e.g.
    ``Fig. 1`` or ``[fov] Budget``) and test, in order of appearance: the paper's statement and
    the test, when every row of a table shares them, are said once above it instead of on every
    row; a column with nothing in it (every cell "—") is left out. Lines."""
    from nbv_gym.reporting.formatting import markdown_table

    family = table["claim"].str.split(":").str[0]
    lines: list[str] = []
    for (name, _), group in table.groupby([family, table["test"]], sort=False):
        said = [c for c in SAID_ONCE if group[c].nunique() == 1 and group[c].iloc[0] != "—"]
        lead = f"**{name}**" + "".join(f" — {c}: {group[c].iloc[0]}" for c in said)
        empty = [c for c in SHOWN if (group[c].astype(str) == "—").all()]  # nothing to show
        shown = [c for c in SHOWN if c not in said and c not in empty]
        lines += [lead, "", markdown_table(shown, group[shown].to_numpy().tolist()), ""]
    return lines[:-1]


def model_summary(table) -> str:
    """Per visibility model: how many Fig. 2 comparisons are significantly higher (Holm) at
    each fraction, and the verdicts of its Fig. 2 and budget rows, as a Markdown table."""
    from nbv_gym.reporting.formatting import markdown_table

    rows = []
    for model, group in table[table["model"] != "—"].groupby("model", sort=False):
        fig2 = group[group["claim"].str.contains("] Fig. 2: nbv-", regex=False)]
        budget = group[group["claim"].str.contains("] Budget:", regex=False)]
        higher = [
            sum(_significant(row.p, f"{f:.0%}") for row in fig2.itertuples()) for f in FRACTIONS
        ]
        rows.append(
            [
                model,
                len(fig2),
                *(f"{h}/{len(fig2)}" for h in higher),
                count_summary(fig2["verdict"]) or "—",
                count_summary(budget["verdict"]) or "—",
            ]
        )
    header = ["model", "comparisons", *(f"higher at {f:.0%} (Holm p < 0.05)" for f in FRACTIONS)]
    return markdown_table([*header, "Fig. 2 verdicts", "budget verdicts"], rows)


def _significant(p_cell: str, point: str) -> bool:
    """Whether the ``p`` cell of a comparison row gives p < α at ``point`` (``"60%: 0.012"``)."""
    for part in str(p_cell).split("; "):
        label, _, value = part.partition(": ")
        if label == point:
            if value.startswith("<"):
                return True
            try:
                return float(value) < ALPHA
            except ValueError:
                return False
    return False


def _power_note(table) -> str:
    """The power note of the Fig. 2 rows when none of them can reach significance."""
    fig2 = table[table["claim"].str.contains("Fig. 2: nbv-", regex=False)]
    if fig2.empty or not fig2["verdict"].str.startswith(INCONCLUSIVE).all():
        return ""
    n = max(int(str(v).split("–")[-1]) for v in fig2["n"] if str(v)[0].isdigit())
    family = len(fig2) // max(fig2["model"].nunique(), 1) * len(FRACTIONS)  # one per model
    return power_note(smallest_p_wilcoxon(n, "greater"), family, "one-sided Wilcoxon test")
