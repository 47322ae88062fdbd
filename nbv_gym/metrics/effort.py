"""Q over effort: a run's Q as a step function of what the robot has spent.

Effort is the robot's cost: its path (m) and its scans, which the effort model
(:class:`~nbv_gym.core.protocol.EffortModel`) turns into elapsed time (s). A curve takes any
one of them as its x: the elapsed time, the path length, or the number of scans (travel free).

The rule, one for every caller (the benchmark's scorecards, the sweep report, the verdict):
a run's Q at effort ``x`` is its Q after the last scan whose cumulative effort is ≤ ``x`` —
what the robot holds once it has spent ``x``. The first scan is at effort 0, so a curve starts
at Q after the first scan. **After the run's end the curve holds the final Q**: a run that
stopped before ``x`` (it spent its budget, reached the discovered target or found no goal) keeps
the map it made; it never becomes missing.
"""

from __future__ import annotations

import numpy as np


def q_at(effort: np.ndarray, q: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(k,) float64 Q at each of the (k,) efforts ``grid``: Q after the last step whose
    cumulative ``effort`` ((n,) non-decreasing, the first 0; seconds, metres or scans) is ≤ the
    grid value; the first Q before it, the final Q beyond the run's end."""
    effort, q = np.asarray(effort, float), np.asarray(q, float)
    index = np.searchsorted(effort, np.asarray(grid, float), side="right") - 1
    return q[np.maximum(index, 0)]


def area_under(effort: np.ndarray, q: np.ndarray, end: float) -> float:
    """The area under the step function Q(effort) of :func:`q_at` over [0, ``end``], divided by
    ``end``: the mean Q the run held over the budget (in [0, 1] as Q is)."""
    effort, q = np.asarray(effort, float), np.asarray(q, float)
    starts = np.minimum(effort, end)
    stops = np.append(starts[1:], end)
    return float(np.sum(q * (stops - starts)) / end)
