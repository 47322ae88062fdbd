"""The report of a sweep folder: the paper's Fig. 1, Fig. 2 and Table II, final-Q and AUC tables
with bootstrap intervals and paired comparisons, in ``report/report.md`` with its PNGs and CSVs.

Built from the consolidated tables alone (``runs.csv``, ``steps.csv``, ``cuboids.parquet``, and
``sweep.toml`` for the discovered target when present), so a report can be rebuilt from a folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.core.inputs import MAX_TABLE_BYTES, open_input
from nbv_gym.mapping.statistics import STATISTICS
from nbv_gym.policies import PAPER_POLICIES
from nbv_gym.reporting.formatting import (
    asset_order,
    is_oracle_label,
    markdown_table,
    oracle_label,
    ranked_apart,
)
from nbv_gym.reporting.html import write_html
from nbv_gym.reporting.inference import (
    Interval,
    q_auc,
)
from nbv_gym.sweep.effort import equal_scans_section, time_section
from nbv_gym.sweep.figures import (
    STATISTIC_LABELS,
    plot_fig1,
    plot_fig2,
)
from nbv_gym.sweep.folder import ResultStore, SweepError
from nbv_gym.sweep.tables import (
    ci_text,
    final_table,
    indicator_tests_table,
    pairwise_table,
    pairwise_text,
    share_text,
    table2,
)

#: Policies whose runs Table II is computed on (paper §IV-C: no bias from the statistics).
UNBIASED_POLICIES = ("random-frontier", "random-free")
FIG1_NOISE = 1  # the paper shows Fig. 1 for noise level 1


@dataclass
class Results:
    """The tables of a sweep folder: ``runs`` and ``steps`` DataFrames, the cuboids table's path,
    the discovered target and the policy order."""

    runs: Any
    steps: Any
    cuboids_path: Path
    target: float
    policies: list[str]
    #: Runs the folder's sweep.toml lists (None without one).
    expected: int | None = None
    #: The time task's budget (s) when sweep.toml sets ``task = "time"``, else None.
    time_budget_s: float | None = None

    @property
    def missing(self) -> int:
        """Runs sweep.toml lists that the tables lack (neither finished nor failed)."""
        return max(self.expected - len(self.runs), 0) if self.expected is not None else 0


def build_report(results: str | Path, out: str | Path | None = None, seed: int = 0) -> Path:
    """Write figures, CSV tables and ``report.md`` for the sweep folder ``results`` into ``out``
    (default ``results/report``); the path of report.md. ``seed`` seeds the bootstrap."""
    results = Path(results)
    out = Path(out) if out else results / "report"
    out.mkdir(parents=True, exist_ok=True)
    data = load_results(results)
    if data.missing:
        import warnings

        warnings.warn(
            f"{results} lacks {data.missing} of its {data.expected} runs; the report says so "
            "and marks no claim reproduced (rerun `nbv-gym sweep` to complete it)",
            stacklevel=2,
        )
    rng = np.random.default_rng(seed)
    ok = data.runs[data.runs["status"] == "ok"].copy()
    ok["auc"] = run_aucs(ok, data.steps, data.target)
    sections = [_header(results, data, ok)]
    if len(ok):
        sections += [
            _fig2_section(ok, data, out),
            _final_section(ok, data, rng, out),
            equal_scans_section(ok, data.steps, data.policies, out),
            _time_section(ok, data, out),
            _indicator_section(ok, data, out),
            _verdict_section(ok, data, out, rng),
        ]
    sections.append(_failures_section(data.runs))
    path = out / "report.md"
    path.write_text("\n\n".join(s for s in sections if s) + "\n", encoding="utf-8")
    write_html(path)
    return path


# -- loading --------------------------------------------------------------------------------------


def load_results(results: Path) -> Results:
    """The consolidated tables of ``results`` (consolidated first if only per-run files exist)."""
    import pandas as pd

    if not (results / "runs.csv").exists():
        if not (results / "runs").is_dir():
            raise SweepError(
                f"{results} holds no sweep results (no runs.csv, no runs/). Run "
                "`nbv-gym sweep CONFIG --out DIR` first, then `nbv-gym report DIR`."
            )
        ResultStore(results).consolidate()
    with open_input(results / "runs.csv", "Sweep table", MAX_TABLE_BYTES) as file:
        runs = pd.read_csv(file, dtype={"asset": str})
    with open_input(results / "steps.csv", "Sweep table", MAX_TABLE_BYTES) as file:
        steps = pd.read_csv(file)
    runs["asset"] = runs["asset"].fillna("")
    target, order, expected = _config_facts(results / "sweep.toml")
    labels = oracle_labels(runs)
    runs["policy"], steps["policy"] = (
        runs["policy"].replace(labels),
        steps["policy"].replace(labels),
    )
    order = [labels.get(p, p) for p in order]
    present = list(dict.fromkeys(runs["policy"]))
    policies = [p for p in (*order, *PAPER_POLICIES, *present) if p in present]
    policies = sorted(dict.fromkeys(policies), key=is_oracle_label)  # oracles last, stable
    budget = _time_budget(results / "sweep.toml")
    return Results(runs, steps, results / "cuboids.parquet", target, policies, expected, budget)


def oracle_labels(runs) -> dict[str, str]:
    """Policy name → its label marked as an oracle, for the policies whose runs ``runs.csv``
    records as oracles (column ``oracle``; absent in folders of older versions)."""
    if "oracle" not in runs.columns:
        return {}
    flagged = runs["oracle"].astype(str).str.lower().isin(("true", "1", "1.0"))
    return {p: oracle_label(p) for p in dict.fromkeys(runs.loc[flagged, "policy"])}


def _config_facts(path: Path) -> tuple[float, list[str], int | None]:
    """The discovered target, policy order and number of runs of the folder's sweep.toml
    (defaults and None if absent)."""
    from nbv_gym.core.config import read_toml
    from nbv_gym.core.protocol import DISCOVERED_TARGET

    target = DISCOVERED_TARGET
    if not path.exists():
        return target, [], None
    data = read_toml(path, "sweep.toml")
    episode = data.get("env", {}).get("simulator", {}).get("episode", {})
    counts = [len(data.get(key, [])) for key in ("worlds", "noise", "policies")]
    expected = int(np.prod(counts)) * int(data.get("repeats", 1))
    return float(episode.get("discovered_target", target)), list(data.get("policies", [])), expected


def _time_budget(path: Path) -> float | None:
    """The time budget (s) of the folder's sweep.toml when its task is the time task, else
    None (no sweep.toml: None)."""
    from nbv_gym.core.config import read_toml
    from nbv_gym.core.protocol import TIME_BUDGET_S

    if not path.exists():
        return None
    data = read_toml(path, "sweep.toml")
    return float(data.get("time_budget_s", TIME_BUDGET_S)) if data.get("task") == "time" else None


def run_aucs(runs, steps, target: float) -> np.ndarray:
    """(n,) area under each run's Q-vs-discovered curve (:func:`~nbv_gym.reporting.inference.q_auc`)."""
    groups = {key: group for key, group in steps.groupby("key", sort=False)}
    aucs = []
    for key in runs["key"]:
        group = groups.get(key)
        if group is None or group.empty:
            aucs.append(np.nan)
            continue
        group = group.sort_values("step")
        aucs.append(q_auc(group["discovered"].to_numpy(), group["q"].to_numpy(), target))
    return np.asarray(aucs, float)


def _time_section(ok, data: Results, out: Path) -> str:
    """Q against the robot's time for a time-task sweep; "" for the other tasks (and for a
    folder whose steps table records no ``elapsed_s``)."""
    if data.time_budget_s is None or "elapsed_s" not in data.steps.columns:
        return ""
    return time_section(ok, data.steps, data.policies, out, data.time_budget_s)


# -- header and failures ---------------------------------------------------------------------------


def _header(results: Path, data: Results, ok) -> str:
    runs = data.runs
    failed = int((runs["status"] != "ok").sum())
    lines = [
        f"# nbv-gym sweep report: `{results.name}`",
        "",
        *_incomplete(data),
        f"{len(ok)} finished runs, {failed} failed"
        + (
            f", {data.missing} missing of the {data.expected} its sweep.toml lists. "
            if data.missing
            else ". "
        )
        + f"Worlds: {', '.join(sorted(runs['world'].unique()))}. "
        f"Noise levels: {', '.join(str(n) for n in sorted(runs['noise'].unique()))}. "
        f"Policies: {', '.join(data.policies)}. "
        f"Repeats: {runs['repeat'].nunique()}. Discovered target: {data.target:.0%}.",
        "",
        "Tables: `runs.csv` (one row per run), `steps.csv` (one row per step), "
        "`cuboids.parquet` (per-cuboid end-of-run statistics and quality). Resolved config: "
        "`sweep.toml`; versions: `versions.json`.",
    ]
    if len(ok):
        lines += [
            "",
            f"Total compute: {ok['total_time_s'].sum() / 3600:.2f} h of run time; "
            f"median {ok['total_time_s'].median():.1f} s per run, "
            f"median {ok['steps'].median():.0f} steps per run.",
        ]
    return "\n".join(lines)


def _incomplete(data: Results) -> list[str]:
    """The warning that heads the report of a sweep whose tables lack runs."""
    if not data.missing:
        return []
    return [
        f"**Incomplete sweep: {data.missing} of its {data.expected} runs are missing** (not run "
        "yet, or their files were removed). Figures below use the runs present; no claim is "
        "marked reproduced until every run is there. Rerun the same `nbv-gym sweep` command to "
        "complete it.",
        "",
    ]


def _failures_section(runs) -> str:
    failed = runs[runs["status"] != "ok"]
    if failed.empty:
        return "## Failed runs\n\nNone."
    rows = [[r.key, int(r.attempts), str(r.error)[:200]] for r in failed.itertuples()]
    return (
        "## Failed runs\n\nTracebacks of every attempt are in `failures/`. Rerun the same "
        "`nbv-gym sweep` command to retry them.\n\n"
        + markdown_table(["run", "attempts", "last error"], rows)
    )


# -- Fig. 2: Q against discovered fraction ---------------------------------------------------------


def _fig2_section(ok, data: Results, out: Path) -> str:
    lines = [
        "## Map quality during exploration (paper Fig. 2)",
        "",
        "Quality against the discovered fraction of the ground plane, per policy: the line is the "
        "mean of the runs (drawn where at least half of them reach that fraction), the band spans "
        "their min and max. One panel per asset type (harder to the right); per noise level "
        "(the paper shows noise 0) first Q_paper (eq. 3, what the paper's Fig. 2 draws), then Q "
        "(fixed bounds, the reward). Both over the comparison volume (docs/protocol.md#comparison-volume).",
    ]
    for noise in sorted(ok["noise"].unique()):
        runs = ok[ok["noise"] == noise]
        lines += ["", f"### Noise level {noise} ({len(runs)} runs)"]
        for column, label in (("q_paper", "Q_paper"), ("q", "Q")):
            name = f"fig2_{column}_vs_discovered_noise{noise}.png"
            plot_fig2(runs, data.steps, data.policies, data.target, out / name,
                      f"noise {noise}", column)  # fmt: skip
            lines += ["", f"![Fig. 2, {label}]({name})"]
    return "\n".join(lines)


# -- final Q, AUC and pairwise comparisons -----------------------------------------------------------


def _final_section(ok, data: Results, rng, out: Path) -> str:
    table = final_table(ok, data.policies, rng)
    table.to_csv(out / "final_q.csv", index=False)
    rows = [
        [
            r.policy,
            r.runs,
            ci_text(Interval(r.q_mean, r.q_low, r.q_high, r.runs)),
            ci_text(Interval(r.q_iqm, r.q_iqm_low, r.q_iqm_high, r.runs)),
            ci_text(Interval(r.auc_mean, r.auc_low, r.auc_high, r.runs)),
            f"{r.q_paper_mean:.4f}",
            f"{r.discovered_mean:.1%}",
            f"{r.steps_mean:.1f}",
            f"{r.path_length_m_mean:.0f}",
        ]
        for r in table.itertuples()
    ]
    header = ["policy", "runs", "final Q [95% CI]", "final Q IQM [95% CI]", "AUC [95% CI]"]
    header += ["final Q_paper"]
    header += ["discovered", "steps", "path (m)"]
    by_asset = ok.pivot_table(index="policy", columns="asset", values="q", aggfunc="mean")
    by_asset = by_asset.reindex([p for p in data.policies if p in by_asset.index])
    by_asset = by_asset[asset_order(by_asset.columns)]
    by_asset.to_csv(out / "final_q_by_asset.csv")
    asset_rows = [[p, *(f"{v:.4f}" for v in row)] for p, row in by_asset.iterrows()]
    lines = [
        "## Final quality and area under the Q-vs-discovered curve",
        "",
        "Final Q: Q at the end of each run. AUC: area under the run's Q-vs-discovered curve from "
        f"0 (through Q = 0) to min(its last discovered fraction, {data.target:.0%}) — higher "
        "means better maps earlier; a run that stops short of the target gets less area. "
        "Means over runs, and the interquartile mean (IQM: the mean of the middle 50 % of the "
        "runs) of final Q, with 95 % intervals of a stratified bootstrap (10 000 resamples of "
        "the runs, each drawn within its world × noise level, so the interval reflects the "
        "spread between repeats, not the chosen spread between worlds; percentile method, as "
        "rliable). "
        "Table: `final_q.csv`.",
        "",
        markdown_table(header, ranked_apart(rows)),
        "",
        "### Final Q per asset type (mean)",
        "",
        markdown_table(["policy", *by_asset.columns], ranked_apart(asset_rows)),
    ]
    for metric, label in (("q", "final Q"), ("auc", "AUC")):
        pairs = pairwise_table(ok, data.policies, metric, rng)
        pairs.to_csv(out / f"pairwise_{metric}.csv", index=False)
        lines += ["", f"### Pairwise comparisons: {label}", "", pairwise_text(pairs, label)]
    return "\n".join(lines)


# -- Fig. 1 and Table II: viewpoint statistics as quality indicators ---------------------------------


def _read_cuboids(path: Path, filters, columns=None):
    import pyarrow.parquet as pq

    if not path.exists():
        return None
    with open_input(path, "Cuboid table", MAX_TABLE_BYTES) as file:
        table = pq.read_table(file, filters=filters or None, columns=columns)
    return table.to_pandas() if table.num_rows else None


def _indicator_section(ok, data: Results, out: Path) -> str:
    lines = [
        "## Viewpoint statistics as quality indicators (paper Fig. 1, Table II)",
    ]
    lines += _fig1_lines(ok, data, out)
    lines += _table2_lines(ok, data, out)
    return "\n".join(lines)


def _verdict_section(ok, data: Results, out: Path, rng: np.random.Generator) -> str:
    from nbv_gym.reporting.verdicts import INCOMPLETE, NO_DATA
    from nbv_gym.sweep.tables import verdict_section
    from nbv_gym.sweep.verdict import verdict_table

    ok = ok[~ok["policy"].map(is_oracle_label)]  # the paper's claims concern its policies
    levels = sorted(ok["noise"].unique())
    noise = FIG1_NOISE if FIG1_NOISE in levels else levels[0]
    columns = ["key", "asset", "u_occ", "cov_q", "l1", *STATISTICS]  # key: the run-level test
    cuboids = _read_cuboids(data.cuboids_path, [("noise", "=", int(noise))], columns)
    shares_path = out / "table2.csv"
    shares = _read_table2(shares_path) if shares_path.exists() else None
    table = verdict_table(ok, data.steps, cuboids, shares, rng)
    if data.missing:  # a verdict on part of the runs is no verdict
        table["verdict"] = table["verdict"].where(
            table["verdict"].str.startswith(NO_DATA), f"{INCOMPLETE} ({data.missing} runs missing)"
        )
    return verdict_section(table, out)


def _read_table2(path: Path):
    import pandas as pd

    with open_input(path, "Table", MAX_TABLE_BYTES) as file:
        return pd.read_csv(file, index_col=0)


def _fig1_lines(ok, data: Results, out: Path) -> list[str]:
    levels = sorted(ok["noise"].unique())
    noise = FIG1_NOISE if FIG1_NOISE in levels else levels[0]
    columns = ["key", "asset", "u_occ", "cov_q", "l1", *STATISTICS]  # key: the run-level test
    cuboids = _read_cuboids(data.cuboids_path, [("noise", "=", int(noise))], columns)
    if cuboids is None:
        return ["", "No per-cuboid table (`cuboids.parquet`): Fig. 1 skipped."]
    name = f"fig1_quality_vs_statistics_noise{noise}.png"
    plot_fig1(cuboids, out / name, f"noise {noise}, all policies")
    return [
        "",
        f"### Mean quality against each viewpoint statistic (noise level {noise})",
        "",
        "Mean cov (at Q's setting p = 0.7, d = 0.15 m; U_occ cuboids) and mean L1 (U_empty "
        "cuboids) per bin of each statistic, over the observed cuboids of all runs at this "
        "noise level; one line per asset type, darker = harder.",
        "",
        f"![Fig. 1]({name})",
    ]


def _table2_lines(ok, data: Results, out: Path) -> list[str]:
    chosen = [p for p in UNBIASED_POLICIES if p in set(ok["policy"])]
    note = "the random-frontier and random-free runs, as in the paper"
    if not chosen:
        chosen = sorted(p for p in set(ok["policy"]) if not is_oracle_label(p))
        note = "all runs but oracles' (no random-frontier/random-free run)"
    columns = ["key", "world", "asset", "noise", "policy", "repeat", "u_occ", "cov_q", "l1"]
    cuboids = _read_cuboids(data.cuboids_path, [("policy", "in", chosen)], [*columns, *STATISTICS])
    if cuboids is None:
        return ["", "No per-cuboid table (`cuboids.parquet`): Table II skipped."]
    tests = indicator_tests_table(cuboids)
    tests.to_csv(out / "indicator_tests.csv", index=False)
    overall = table2(tests)
    overall.to_csv(out / "table2.csv")
    n_runs = tests["key"].nunique()
    rows = [[STATISTIC_LABELS[s], *(share_text(v) for v in overall.loc[s])] for s in overall.index]
    grouped = table2(tests, ("asset", "noise"))
    grouped.to_csv(out / "table2_by_asset_noise.csv")
    flat = grouped.unstack("statistic")
    group_rows = [
        [
            asset,
            noise,
            *(
                share_text(flat.loc[(asset, noise)].get((m, s), np.nan))
                for m in ("cov", "l1")
                for s in STATISTICS
            ),
        ]
        for asset, noise in flat.index
    ]
    group_header = ["asset", "noise"] + [
        f"{m} {STATISTIC_LABELS[s]}" for m in ("cov", "l1") for s in STATISTICS
    ]
    return [
        "",
        "### Share of Mann–Whitney tests with p < 0.05 (paper Table II)",
        "",
        f"One-sided Mann–Whitney U tests of Table I, split at the statistic's median, one per "
        f"run, statistic and metric, on {note} ({n_runs} runs). cov at Q's setting on U_occ, "
        "L1 on U_empty; observed cuboids only. Paper (simulation, 162 runs), cov / L1: n_obs "
        "0.74 / 0.90, r_min 0.89 / 1.00, n_Ω 0.74 / 0.87, σ_θ 0.88 (one value legible). "
        "Per-test p-values: `indicator_tests.csv`.",
        "",
        markdown_table(["statistic", *overall.columns], rows),
        "",
        "Per asset type and noise level:",
        "",
        markdown_table(group_header, group_rows),
    ]


# -- formatting ------------------------------------------------------------------------------------
