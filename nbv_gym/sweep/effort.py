"""Q over effort in the sweep report: comparisons at equal scans with travel free
(docs/protocol.md#tasks, the budget protocol), Q against path length, Q against the robot's
time in a time-task sweep, and the calibration of the NBV gain prediction.

The paper compares policies at equal discovered fraction, which rewards scanning more per
discovered area. Here Q and the discovered fraction are drawn against the robot's effort — the
number of scans, the path length driven, and (time task) its elapsed time under the effort
model — per policy and asset type (mean line, min–max band), with a table of Q after a few
fixed numbers of scans. Every curve follows the one rule of :mod:`nbv_gym.metrics.effort`, the
benchmark's: Q after the last scan within that effort, and a run that ended before (it reached
the discovered target, or its budget bought no further goal) holds its final Q.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from nbv_gym.metrics.effort import q_at

#: Numbers of scans after which Q is tabulated.
SCAN_BUDGETS = (5, 10, 20)


def curves_at(steps, x: str, y: str, grid: np.ndarray) -> dict[str, np.ndarray]:
    """Per run key: ``y`` interpolated at the values ``grid`` (k,) of the non-decreasing column
    ``x`` (the discovered fraction: progress, not effort); NaN outside the range the run
    covered. Against effort use :func:`effort_curves`."""
    out = {}
    for key, run in steps.groupby("key", sort=False):
        run = run.sort_values("step")
        xs, ys = np.maximum.accumulate(run[x].to_numpy(float)), run[y].to_numpy(float)
        last = np.append(xs[1:] != xs[:-1], True)  # one value per x: the last one
        xs, ys = xs[last], ys[last]
        values = np.interp(grid, xs, ys)
        out[key] = np.where((grid >= xs[0]) & (grid <= xs[-1]), values, np.nan)
    return out


def effort_curves(steps, x: str, grid: np.ndarray, y: str = "q") -> dict[str, np.ndarray]:
    """Per run key: (k,) ``y`` at the efforts ``grid`` of the cumulative column ``x`` (``step``,
    ``path_length_m`` or ``elapsed_s``), by :func:`~nbv_gym.metrics.effort.q_at`: the value
    after the last step within the effort, the final value beyond the run's end."""
    out = {}
    for key, run in steps.groupby("key", sort=False):
        run = run.sort_values("step")
        effort = np.maximum.accumulate(run[x].to_numpy(float))
        out[key] = q_at(effort, run[y].to_numpy(float), grid)
    return out


def bands(runs, curves: dict[str, np.ndarray], width: int) -> dict[tuple[str, str], np.ndarray]:
    """Per (asset, policy): (3, width) mean, min and max over its runs' curves; the mean where at
    least half of the runs cover the point, NaN elsewhere."""
    out = {}
    for (asset, policy), group in runs.groupby(["asset", "policy"], sort=False):
        rows = [curves[k] for k in group["key"] if k in curves]
        if not rows:
            continue
        stack = np.vstack(rows)
        covered = np.isfinite(stack).sum(axis=0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # points no run covers
            mean, low, high = np.nanmean(stack, 0), np.nanmin(stack, 0), np.nanmax(stack, 0)
        mean[covered * 2 < len(stack)] = np.nan
        out[(asset, policy)] = np.vstack([mean, low, high])
    return out


#: Axis label and title words of each effort column.
EFFORT_LABELS = {
    "step": ("scans", "scans"),
    "path_length_m": ("path length (m)", "path length"),
    "elapsed_s": ("robot time (s)", "robot time"),
}


def plot_q_over(runs, steps, policies, x: str, path: Path, end: float | None = None) -> None:
    """Q (top) and discovered fraction (bottom) against the effort ``x`` (a key of
    :data:`EFFORT_LABELS`) from 0 to ``end`` (default: the longest run's), one column per asset
    type, to ``path``."""
    from nbv_gym.reporting.formatting import asset_order, policy_colours, policy_style
    from nbv_gym.reporting.formatting import figure as _figure
    from nbv_gym.reporting.html import save_figure

    top = end if end is not None else float(steps[x].max()) if len(steps) else 1.0
    grid = np.arange(0, top + 1) if x == "step" else np.linspace(0, max(top, 1.0), 121)
    axis_label, title = EFFORT_LABELS[x]
    assets = asset_order(runs["asset"])
    fig = _figure(4 * len(assets), 6.4)
    axes = fig.subplots(2, len(assets), sharex=True, sharey="row", squeeze=False)
    colours = policy_colours(policies)
    for row, y in enumerate(("q", "discovered")):
        drawn = bands(runs, effort_curves(steps, x, grid, y), len(grid))
        for col, asset in enumerate(assets):
            ax = axes[row][col]
            for policy in policies:
                if (asset, policy) in drawn:
                    mean, low, high = drawn[(asset, policy)]
                    ax.plot(grid, mean, policy_style(policy), color=colours[policy],
                            label=policy, lw=1.4)  # fmt: skip
                    ax.fill_between(grid, low, high, color=colours[policy], alpha=0.10, lw=0)
            ax.grid(alpha=0.3)
            ax.set_xlim(0, float(grid[-1]))
            if row == 0:
                ax.set_title(asset or "(unknown asset)")
            else:
                ax.set_xlabel(axis_label)
        axes[row][0].set_ylabel("Q" if y == "q" else "discovered fraction")
    axes[0][-1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Q and discovered fraction against {title}")
    fig.tight_layout()
    save_figure(fig, path)


def q_after_scans(runs, steps, scans):
    """Per run: Q after each number of ``scans`` (:func:`effort_curves` on ``step``: a run that
    ended before holds its final Q; NaN for a run without steps). A DataFrame indexed like
    ``runs``, one column per number of scans."""
    import pandas as pd

    curves = effort_curves(steps, "step", np.asarray(scans, float))
    empty = np.full(len(scans), np.nan)
    values = [curves.get(k, empty) for k in runs["key"]]
    table = np.vstack(values) if values else np.empty((0, len(scans)))  # no runs: no rows
    return pd.DataFrame(table, index=runs.index, columns=list(scans))


def scans_table(runs, steps, policies, budgets=SCAN_BUDGETS):
    """Per policy and asset type: mean Q after each number of scans in ``budgets`` over its
    runs (:func:`q_after_scans`: a run that ended before holds its final Q), and how many of
    them took that many scans. A DataFrame."""
    import pandas as pd

    at = q_after_scans(runs, steps, budgets)
    took = runs["key"].map(steps.groupby("key")["step"].max()).fillna(-1)
    rows = []
    for (asset, policy), group in runs.groupby(["asset", "policy"], sort=False):
        values = at.loc[group.index]
        if values.isna().to_numpy().all():
            continue
        row = {"policy": policy, "asset": asset}
        for b in budgets:
            row[f"q_after_{b}"] = float(values[b].mean())
            row[f"runs_at_{b}"] = int((took[group.index] >= b).sum())
        rows.append(row)
    table = pd.DataFrame(rows)
    if table.empty:
        return table
    order = {p: i for i, p in enumerate(policies)}
    return table.sort_values(
        ["policy", "asset"], key=lambda c: c.map(order) if c.name == "policy" else c
    )


def calibration_table(steps):
    """Per policy with a gain prediction (``predicted_gain`` recorded): the median, 25th and
    75th percentile of realised / predicted gain over its steps with a positive prediction, and
    the number of such steps. A DataFrame (empty if no policy predicts)."""
    import pandas as pd

    if "predicted_gain" not in steps.columns:
        return pd.DataFrame()
    rows = steps[(steps["step"] > 0) & (steps["predicted_gain"] > 0)]
    ratio = rows["realised_gain"] / rows["predicted_gain"]
    grouped = ratio.groupby(rows["policy"], sort=True)
    return pd.DataFrame(
        {
            "median": grouped.median(),
            "q25": grouped.quantile(0.25),
            "q75": grouped.quantile(0.75),
            "steps": grouped.size(),
        }
    ).reset_index()


def equal_scans_section(ok, steps, policies, out: Path) -> str:
    """The report's equal-scans section: figures against scans and path length, Q after fixed
    numbers of scans, and the gain calibration table."""
    from nbv_gym.reporting.formatting import markdown_table, ranked_apart

    steps = steps[steps["key"].isin(set(ok["key"]))]
    plot_q_over(ok, steps, policies, "step", out / "q_vs_scans.png")
    plot_q_over(ok, steps, policies, "path_length_m", out / "q_vs_path.png")
    table = scans_table(ok, steps, policies)
    table.to_csv(out / "q_after_scans.csv", index=False)
    rows = [
        [r["policy"], r["asset"], *(_cell(r, b) for b in SCAN_BUDGETS)] for _, r in table.iterrows()
    ]
    lines = [
        "## Comparison at equal scans, travel free (budget protocol)",
        "",
        "The paper's Fig. 2 compares policies at equal discovered fraction, which rewards "
        "scanning more per discovered area. Here Q and the discovered fraction are drawn against "
        "the number of scans and against the path length driven (mean line, min–max band). A "
        "run that ended before a point (runs of the paper protocol stop at the discovered "
        "target) holds its final Q there, as in the benchmark's scorecards; a sweep of the "
        'budget task (`task = "budget"`) runs every policy for the same number of scans.',
        "",
        "![Q and discovered fraction against scans](q_vs_scans.png)",
        "",
        "![Q and discovered fraction against path length](q_vs_path.png)",
        "",
        "### Q after 5, 10 and 20 scans",
        "",
        "Mean Q over the runs, a run that stopped earlier holding its final Q; in brackets how "
        "many runs took that many scans. Table: `q_after_scans.csv`.",
        "",
        markdown_table(
            ["policy", "asset", *(f"Q after {b}" for b in SCAN_BUDGETS)], ranked_apart(rows)
        ),
    ]
    return "\n".join(lines + _calibration_lines(steps, out))


def time_section(ok, steps, policies, out: Path, budget_s: float) -> str:
    """The report's section of a time-task sweep: Q and the discovered fraction against the
    robot's elapsed time over [0, ``budget_s``] (``q_vs_time.png``)."""
    steps = steps[steps["key"].isin(set(ok["key"]))]
    plot_q_over(ok, steps, policies, "elapsed_s", out / "q_vs_time.png", end=budget_s)
    return "\n".join(
        [
            "## Q against the robot's time (time task)",
            "",
            f"Q(t) and the discovered fraction against the robot's elapsed time over the "
            f"{budget_s:g} s budget, travel and scans charged by the effort model (path / speed "
            "+ scans × scan time; mean line, min–max band). Q(t) is Q after the last scan "
            "within t; a run whose budget bought no further goal holds its final Q to the "
            "budget. The benchmark's time task ranks by the area under this curve.",
            "",
            "![Q and discovered fraction against the robot's time](q_vs_time.png)",
        ]
    )


def _calibration_lines(steps, out: Path) -> list[str]:
    from nbv_gym.reporting.formatting import markdown_table, ranked_apart

    table = calibration_table(steps)
    if table.empty:
        return []
    table.to_csv(out / "gain_calibration.csv", index=False)
    rows = [
        [r.policy, f"{r.median:.3g}", f"{r.q25:.3g} – {r.q75:.3g}", int(r.steps)]
        for r in table.itertuples()
    ]
    return [
        "",
        "### Calibration of the NBV gain prediction",
        "",
        "Per step of an `nbv-*` policy: the gain its visibility model predicted for the goal it "
        "chose, against the gain the scan from there realised (the same per-cell formulas on "
        "the statistics before and after the scan). A ratio near 1 means the policy chooses on "
        "what the lidar will really observe; `@model` names the visibility model when the "
        "policy fixes one. Table: `gain_calibration.csv`.",
        "",
        markdown_table(
            ["policy", "median realised / predicted", "25–75 %", "steps"], ranked_apart(rows)
        ),
    ]


def _cell(row, budget: int) -> str:
    value, count = row[f"q_after_{budget}"], row[f"runs_at_{budget}"]
    return "—" if not np.isfinite(value) else f"{value:.4f} ({count})"
