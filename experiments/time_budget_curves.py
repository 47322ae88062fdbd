"""Q(t) curves of a time-task sweep (experiments/time-budget.toml) and Q at several budgets:
the evidence behind the time task's default budget (docs/protocol.md#effort).

    nbv-gym sweep experiments/time-budget.toml --out results/time-budget --workers 1
    python experiments/time_budget_curves.py results/time-budget docs/images/time-budget-q-t.png
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from nbv_gym.metrics.effort import area_under, q_at

BUDGETS_S = (120, 240, 360, 480, 600, 900, 1200)


def main(results: Path, figure: Path) -> None:
    steps = pd.read_csv(results / "steps.csv")
    grid = np.linspace(0, BUDGETS_S[-1], 241)
    curves: dict[str, list[np.ndarray]] = {}
    rows = []
    for (policy, world), run in steps.groupby(["policy", "world"], sort=False):
        run = run.sort_values("step")
        t, q = run["elapsed_s"].to_numpy(), run["q"].to_numpy()
        curves.setdefault(policy, []).append(q_at(t, q, grid))
        row = {"policy": policy, "world": world}
        row |= {f"Q@{b}": q_at(t, q, [b])[0] for b in BUDGETS_S}
        row |= {f"AUC@{b}": area_under(t, q, b) for b in BUDGETS_S}
        rows.append(row)
    table = pd.DataFrame(rows).groupby("policy", sort=False).mean(numeric_only=True)
    pd.set_option("display.width", 200)
    print(table[[f"Q@{b}" for b in BUDGETS_S]].round(4).to_string())
    print()
    print(table[[f"AUC@{b}" for b in BUDGETS_S]].round(4).to_string())
    print()
    # growth of Q over the last third of each budget: a saturated policy gains ~nothing
    for b in BUDGETS_S:
        late = {p: np.mean([c[np.searchsorted(grid, b)] - c[np.searchsorted(grid, 2 * b / 3)]
                            for c in cs]) for p, cs in curves.items()}  # fmt: skip
        print(f"ΔQ over [{2 * b / 3:.0f}, {b}] s:", {p: round(v, 4) for p, v in late.items()})
    plot(grid, curves, figure)


def plot(grid: np.ndarray, curves: dict[str, list[np.ndarray]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.4))
    for policy, runs in curves.items():
        stack = np.vstack(runs)
        (line,) = ax.plot(grid, stack.mean(0), label=policy, lw=1.5)
        ax.fill_between(grid, stack.min(0), stack.max(0), color=line.get_color(), alpha=0.12, lw=0)
    for b in BUDGETS_S[:-1]:
        ax.axvline(b, color="0.85", lw=0.8, zorder=0)
    ax.axvline(600, color="0.4", lw=1.0, ls="--", zorder=0)
    ax.set_xlabel("elapsed time (s) = path / 1 m/s + scans × 10 s")
    ax.set_ylabel("Q (mean of 4 benchmark worlds, min–max band)")
    ax.set_title("Time task, noise 1: Q(t) of six references")
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
