"""The sweep report's figures: Fig. 1 (quality against viewpoint statistics) and Fig. 2 (Q
against the discovered fraction), with the binning and bands they draw."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from nbv_gym.mapping.statistics import STATISTICS
from nbv_gym.reporting.formatting import (
    asset_order,
    policy_colours,
    policy_style,
)
from nbv_gym.reporting.formatting import figure as _figure
from nbv_gym.reporting.html import save_figure
from nbv_gym.sweep.effort import bands, curves_at

STATISTIC_LABELS = {
    "n_obs": "n_obs",
    "r_min": "r_min (m)",
    "n_omega": "n_Ω",
    "sigma_theta": "σ_θ",
}


def q_bands(runs, steps, grid: np.ndarray, column: str = "q") -> dict[tuple[str, str], np.ndarray]:
    """Per (asset, policy): a (3, k) array of mean, min and max of ``column`` over the runs at
    the discovered fractions ``grid``; min and max where at least one run covers a fraction, the
    mean where at least half of the runs do (so that the mean does not jump where runs end), NaN
    elsewhere."""
    return bands(runs, curves_at(steps, "discovered", column, grid), len(grid))


def plot_fig2(
    runs, steps, policies, target: float, path: Path, title: str, column: str = "q"
) -> None:
    """Fig. 2 of the paper (``column`` against the discovered fraction) for ``runs`` to ``path``."""
    label = {"q": "Q", "q_paper": "Q_paper"}.get(column, column)
    assets = asset_order(runs["asset"])
    grid = np.linspace(0, max(target, 0.05), 141)
    drawn = q_bands(runs, steps, grid, column)
    fig = _figure(4 * len(assets), 3.6)
    axes = fig.subplots(1, len(assets), sharey=True, squeeze=False)
    colours = policy_colours(policies)
    for ax, asset in zip(axes[0], assets, strict=True):
        for policy in policies:
            if (asset, policy) not in drawn:
                continue
            mean, low, high = drawn[(asset, policy)]
            ax.plot(grid, mean, policy_style(policy), color=colours[policy], label=policy, lw=1.5)
            ax.fill_between(grid, low, high, color=colours[policy], alpha=0.12, lw=0)
        ax.set_title(asset or "(unknown asset)")
        ax.set_xlabel("discovered fraction")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel(label)
    axes[0][-1].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"{label} against discovered fraction ({title})")
    fig.tight_layout()
    save_figure(fig, path)


def statistic_bins(statistic: str, values: np.ndarray) -> np.ndarray:
    """Bin edges for Fig. 1: log-spaced for n_obs, 1 m for r_min, one per sector for n_Ω, 0.05
    for σ_θ."""
    finite = values[np.isfinite(values)]
    top = float(finite.max()) if finite.size else 1.0
    if statistic == "n_obs":
        return np.unique(np.round(np.geomspace(1, max(top, 2) + 1, 25)))
    if statistic == "r_min":
        return np.arange(0, np.ceil(max(top, 1)) + 1, 1.0)
    if statistic == "n_omega":
        return np.arange(0.5, max(top, 1) + 1.5, 1.0)
    return np.linspace(0, 1, 21)


def binned_means(values: np.ndarray, metric: np.ndarray, edges: np.ndarray, min_count: int = 5):
    """(centres, means): the mean statistic and mean metric of each bin of ``edges`` holding at
    least ``min_count`` finite pairs."""
    keep = np.isfinite(values) & np.isfinite(metric)
    values, metric = values[keep], metric[keep]
    which = np.digitize(values, edges) - 1
    inside = (which >= 0) & (which < len(edges) - 1)
    counts = np.bincount(which[inside], minlength=len(edges) - 1)
    sums_x = np.bincount(which[inside], values[inside], minlength=len(edges) - 1)
    sums_y = np.bincount(which[inside], metric[inside], minlength=len(edges) - 1)
    full = counts >= min_count
    return sums_x[full] / counts[full], sums_y[full] / counts[full]


def plot_fig1(cuboids, path: Path, title: str) -> None:
    """Fig. 1 of the paper: mean cov and L1 against each statistic, per asset type, to ``path``."""
    import matplotlib

    assets = asset_order(cuboids["asset"])
    shades = matplotlib.colormaps["Blues"](np.linspace(0.45, 1.0, max(len(assets), 1)))
    fig = _figure(15, 6.5)
    axes = fig.subplots(2, 4, squeeze=False)
    occ = cuboids["u_occ"].to_numpy(bool)
    for col, statistic in enumerate(STATISTICS):
        values = cuboids[statistic].to_numpy(float)
        edges = statistic_bins(statistic, values)
        for row, (metric, mask) in enumerate((("cov_q", occ), ("l1", ~occ))):
            ax = axes[row][col]
            for asset, shade in zip(assets, shades, strict=True):
                pick = mask & (cuboids["asset"].to_numpy() == asset)
                x, y = binned_means(values[pick], cuboids[metric].to_numpy(float)[pick], edges)
                ax.plot(x, y, "-o", ms=2.5, color=shade, label=asset or "(unknown)")
            if statistic == "n_obs":
                ax.set_xscale("log")
            ax.set_xlabel(STATISTIC_LABELS[statistic])
            ax.set_ylabel("mean cov" if metric == "cov_q" else "mean L1")
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.suptitle(f"Mean quality of reconstruction against viewpoint statistics ({title})")
    fig.tight_layout()
    save_figure(fig, path)
