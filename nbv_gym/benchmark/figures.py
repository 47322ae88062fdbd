"""The leaderboard's figures: mean Q against elapsed time per policy with its interquartile
band, and performance profiles per split."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from nbv_gym.benchmark.ranking import Entry, ranked, split_metric
from nbv_gym.benchmark.suites import SPLIT_LABELS, SplitLabels
from nbv_gym.reporting.formatting import printable


def save_q_time(entries: list[Entry], path: Path) -> Path:
    """Draw mean Q against elapsed time on the ranking split per entry, with the interquartile
    band (the scorecards' ``effort.q_time``), to ``path`` (PNG) and its SVG twin."""
    from nbv_gym.reporting.formatting import figure, policy_colours
    from nbv_gym.reporting.html import save_figure

    players, oracles = ranked(entries)
    ordered = [*players, *oracles]
    colours = policy_colours([e.label for e in ordered])
    fig = figure(6.4, 4.4)
    ax = fig.subplots()
    for entry in ordered:
        effort = entry.effort()
        curve = effort["q_time"] if effort else None
        if not curve:
            continue
        colour, style = colours[entry.label], "--" if entry.oracle else "-"
        grid = _time_grid(entry)
        ax.plot(grid, curve["mean"], style, color=colour, label=printable(entry.label), lw=1.4)
        ax.fill_between(grid, curve["low"], curve["high"], color=colour, alpha=0.12, lw=0)
    ax.set_xlabel("elapsed time (s): path / speed + scans × scan time")
    ax.set_ylabel(f"Q ({ordered[0].rank_split} split, mean and interquartile band)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")  # the curves rise from the lower left
    fig.tight_layout()
    return save_figure(fig, path)


def _time_grid(entry: Entry) -> tuple[float, ...]:
    """The time grid of the entry's curves on its ranking split (a team part's is longer)."""
    from nbv_gym.benchmark.curves import time_grid

    parts = entry.card["suite"]["parts"]
    return time_grid(next(p for p in parts if p["split"] == entry.rank_split))


def save_profiles(
    entries: list[Entry], path: Path, splits: Mapping[str, SplitLabels] = SPLIT_LABELS
) -> Path:
    """Draw the performance profiles of every entry (one panel per split of ``splits``, by
    default :data:`~nbv_gym.benchmark.suites.SPLIT_LABELS`) to ``path`` (PNG) and its SVG twin."""
    from nbv_gym.reporting.formatting import figure, policy_colours
    from nbv_gym.reporting.html import save_figure
    from nbv_gym.reporting.inference import performance_profile

    players, oracles = ranked(entries)
    ordered = [*players, *oracles]
    colours = policy_colours([e.label for e in ordered])
    fig = figure(5.0 * len(splits), 4.4)
    axes = fig.subplots(1, len(splits), squeeze=False)[0]
    for ax, (split, labels) in zip(axes, splits.items(), strict=True):
        metric = split_metric(entries, split)
        data = {e.label: e.runs(split, metric) for e in ordered}
        finite = np.concatenate([v[np.isfinite(v)] for v, _ in data.values()] + [np.zeros(1)])
        tau = np.linspace(0.0, finite.max() * 1.05 or 1.0, 200)
        for entry in ordered:
            values, tasks = data[entry.label]
            if not np.isfinite(values).any():
                continue
            rng = np.random.default_rng(0)
            fraction, low, high = performance_profile(values, tasks, tau, rng)
            style = "--" if entry.oracle else "-"
            colour = colours[entry.label]
            ax.plot(tau, fraction, style, color=colour, label=printable(entry.label), lw=1.4)
            ax.fill_between(tau, low, high, color=colour, alpha=0.15, linewidth=0)
        ax.set_xlabel(f"τ ({labels.score})")
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("fraction of runs with score > τ")
    handles = {}  # every policy once, from whichever panel drew it (a split may lack its runs)
    for ax in axes:
        handles.update({label: h for h, label in zip(*ax.get_legend_handles_labels(), strict=True)})
    if handles:
        axes[-1].legend(handles.values(), handles.keys(), fontsize=7, loc="upper right")
    fig.tight_layout()
    return save_figure(fig, path)
