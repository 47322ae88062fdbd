"""The learning curve of a training run: the training episodes of ``episodes.csv``
(:class:`~nbv_gym.rl.callbacks.EpisodeLog`) drawn with the evaluations on held-out worlds as
``learning_curve.png``.

``episodes.csv`` has one row per finished training episode: ``timesteps`` (environment steps of
all environments when it ended), ``world``, ``return`` (the learner's, ``reward_scale`` · Σ ΔQ),
``length`` (steps), ``q`` (Q after the episode, in [0, 1]), ``discovered`` (fraction),
``path_length_m`` and ``end`` (why the episode ended: the environment's ``end_reason``, or
``worker lost`` when the Dask worker running it died, :mod:`nbv_gym.rl.daskvec`). A resumed run
appends to it.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

EPISODES_CSV = "episodes.csv"
CURVE_PNG = "learning_curve.png"
EVALUATIONS = Path("eval") / "evaluations.npz"
COLUMNS = ("timesteps", "world", "return", "length", "q", "discovered", "path_length_m", "end")
#: The columns that are not numbers.
TEXT_COLUMNS = ("world", "end")
#: Episodes in the moving mean of the curve.
WINDOW = 100


def plot_learning_curve(out: str | Path) -> Path:
    """Draw the run folder ``out``'s learning curve into ``out/learning_curve.png`` and return
    its path: the training episodes' return, Q after the episode and discovered fraction against
    timesteps (moving means over :data:`WINDOW` episodes), and, when the run evaluated, the mean
    return on the evaluation worlds."""
    from matplotlib.ticker import FuncFormatter, MaxNLocator

    from nbv_gym.reporting.formatting import figure

    out = Path(out)
    episodes = read_episodes(out / EPISODES_CSV)
    fig = figure(12, 3.6)
    ret, quality, discovered = fig.subplots(1, 3)
    steps = episodes["timesteps"]
    ret.plot(steps, moving_mean(episodes["return"]), label="training episodes")
    if (out / EVALUATIONS).exists():
        evaluations = np.load(out / EVALUATIONS)
        ret.plot(
            evaluations["timesteps"],
            evaluations["results"].mean(axis=1),
            "o-",
            label="evaluation worlds (mean)",
        )
    ret.set(xlabel="timesteps", title="Episode return (scaled ΔQ)")
    ret.legend(fontsize="small")
    quality.plot(steps, moving_mean(episodes["q"]))
    quality.set(xlabel="timesteps", title="Q after the episode (training)")
    discovered.plot(steps, moving_mean(episodes["discovered"]))
    discovered.set(xlabel="timesteps", title="Discovered fraction (training)")
    for axes in (ret, quality, discovered):  # "40k", at most 5 ticks: readable at any step count
        axes.xaxis.set_major_locator(MaxNLocator(5))
        axes.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1000:g}k"))
    fig.suptitle(f"{out.name}: {len(steps)} training episodes, moving means of {WINDOW}")
    fig.tight_layout()
    path = out / CURVE_PNG
    fig.savefig(path, dpi=120)
    return path


def read_episodes(path: Path) -> dict[str, np.ndarray]:
    """The numeric columns of ``episodes.csv`` as arrays (one entry per episode)."""
    with open(path, newline="", encoding="utf-8") as file:
        rows = list(csv.DictReader(file))
    return {
        column: np.array([float(row[column]) for row in rows])
        for column in COLUMNS
        if column not in TEXT_COLUMNS
    }


def moving_mean(values: np.ndarray, window: int = WINDOW) -> np.ndarray:
    """(n,) float: entry i is the mean of ``values[max(0, i - window + 1) : i + 1]``."""
    sums = np.cumsum(np.concatenate([[0.0], values]))
    ends = np.arange(1, len(values) + 1)
    starts = np.maximum(ends - window, 0)
    return (sums[ends] - sums[starts]) / (ends - starts)
