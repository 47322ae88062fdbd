"""Comparisons at equal scans with travel free (docs/protocol.md#tasks, the budget protocol),
beside Q against path length, and the calibration of the NBV gain prediction, for the sweep
report.

The paper compares policies at equal discovered fraction, which rewards scanning more per
discovered area. Here Q and the discovered fraction are drawn against the number of scans and
against the path length driven, per policy and asset type (mean line, min–max band), with a table
of Q after a few fixed numbers of scans. A run that ended before a number of scans (it reached
the discovered target) has no value there: each table cell says how many runs it averages.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

#: Numbers of scans after which Q is tabulated.
SCAN_BUDGETS = (5, 10, 20)


def curves_at(steps, x: str, y: str, grid: np.ndarray) -> dict[str, np.ndarray]:
    """Per run key: ``y`` interpolated at the values ``grid`` (k,) of the non-decreasing column
    ``x`` (``step`` or ``path_length_m``); NaN outside the range the run covered."""
    out = {}
    for key, run in steps.groupby("key", sort=False):
        run = run.sort_values("step")
        xs, ys = np.maximum.accumulate(run[x].to_numpy(float)), run[y].to_numpy(float)
        last = np.append(xs[1:] != xs[:-1], True)  # one value per x: the last one
        xs, ys = xs[last], ys[last]
        values = np.interp(grid, xs, ys)
        out[key] = np.where((grid >= xs[0]) & (grid <= xs[-1]), values, np.nan)
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


def plot_effort(runs, steps, policies, x: str, path: Path) -> None:
    """Q (top) and discovered fraction (bottom) against ``x`` (``step`` or ``path_length_m``),
    one column per asset type, to ``path``."""
    from nbv_gym.reporting.formatting import asset_order, policy_colours, policy_style
    from nbv_gym.reporting.formatting import figure as _figure
    from nbv_gym.reporting.html import save_figure

    top = float(steps[x].max()) if len(steps) else 1.0
    grid = np.arange(0, top + 1) if x == "step" else np.linspace(0, max(top, 1.0), 121)
    assets = asset_order(runs["asset"])
    fig = _figure(4 * len(assets), 6.4)
    axes = fig.subplots(2, len(assets), sharex=True, sharey="row", squeeze=False)
    colours = policy_colours(policies)
    for row, y in enumerate(("q", "discovered")):
        drawn = bands(runs, curves_at(steps, x, y, grid), len(grid))
        for col, asset in enumerate(assets):
            ax = axes[row][col]
            for policy in policies:
                if (asset, policy) in drawn:
                    mean, low, high = drawn[(asset, policy)]
                    ax.plot(grid, mean, policy_style(policy), color=colours[policy],
                            label=policy, lw=1.4)  # fmt: skip
                    ax.fill_between(grid, low, high, color=colours[policy], alpha=0.10, lw=0)
            ax.grid(alpha=0.3)
            ax.set_xlim(0, _last_mean(drawn, grid))
            if row == 0:
                ax.set_title(asset or "(unknown asset)")
            else:
                ax.set_xlabel("scans" if x == "step" else "path length (m)")
        axes[row][0].set_ylabel("Q" if y == "q" else "discovered fraction")
    axes[0][-1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"Q and discovered fraction against {'scans' if x == 'step' else 'path length'}")
    fig.tight_layout()
    save_figure(fig, path)


def _last_mean(drawn: dict[tuple[str, str], np.ndarray], grid: np.ndarray) -> float:
    """The largest grid value where some policy's mean is drawn (the x range worth showing)."""
    finite = [grid[np.isfinite(b[0])] for b in drawn.values()]
    tops = [f.max() for f in finite if f.size]
    return float(max(tops)) if tops else float(grid[-1])


def q_after_scans(runs, steps, policies, budgets=SCAN_BUDGETS):
    """Per policy and asset type: mean Q after each number of scans in ``budgets`` over the runs
    that took that many scans, and how many did. A DataFrame."""
    import pandas as pd

    grid = np.asarray(budgets, float)
    curves = curves_at(steps, "step", "q", grid)
    rows = []
    for (asset, policy), group in runs.groupby(["asset", "policy"], sort=False):
        stack = np.vstack([curves[k] for k in group["key"] if k in curves])
        row = {"policy": policy, "asset": asset}
        for b, column in zip(budgets, stack.T, strict=True):
            finite = column[np.isfinite(column)]
            row[f"q_after_{b}"] = float(finite.mean()) if finite.size else np.nan
            row[f"runs_at_{b}"] = int(finite.size)
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


def effort_section(ok, steps, policies, out: Path) -> str:
    """The report's equal-scans section: figures against scans and path length, Q after fixed
    numbers of scans, and the gain calibration table."""
    from nbv_gym.reporting.formatting import markdown_table, ranked_apart

    steps = steps[steps["key"].isin(set(ok["key"]))]
    plot_effort(ok, steps, policies, "step", out / "q_vs_scans.png")
    plot_effort(ok, steps, policies, "path_length_m", out / "q_vs_path.png")
    table = q_after_scans(ok, steps, policies)
    table.to_csv(out / "q_after_scans.csv", index=False)
    rows = [
        [r["policy"], r["asset"], *(_cell(r, b) for b in SCAN_BUDGETS)] for _, r in table.iterrows()
    ]
    lines = [
        "## Comparison at equal scans, travel free (budget protocol)",
        "",
        "The paper's Fig. 2 compares policies at equal discovered fraction, which rewards "
        "scanning more per discovered area. Here Q and the discovered fraction are drawn against "
        "the number of scans and against the path length driven (mean line, min–max band; the "
        "mean where at least half of the runs reach that point). Runs of the paper protocol stop "
        "at the discovered target, so later points average fewer runs; a sweep of the budget "
        'task (`task = "budget"`) compares every policy over the same number of scans.',
        "",
        "![Q and discovered fraction against scans](q_vs_scans.png)",
        "",
        "![Q and discovered fraction against path length](q_vs_path.png)",
        "",
        "### Q after 5, 10 and 20 scans",
        "",
        "Mean Q over the runs that took at least that many scans (their number in brackets). "
        "Table: `q_after_scans.csv`.",
        "",
        markdown_table(
            ["policy", "asset", *(f"Q after {b}" for b in SCAN_BUDGETS)], ranked_apart(rows)
        ),
    ]
    return "\n".join(lines + _calibration_lines(steps, out))


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
