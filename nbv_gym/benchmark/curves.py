"""Q against effort: a run's Q as a step function of its elapsed time or its path length.

A run's Q at effort ``x`` (seconds, or metres) is its Q after the last scan whose cumulative
effort is ≤ ``x``: what the robot holds once it has spent ``x``. Beyond the run's end it stays at
the final Q (the run spent its budget — scans, time or discovery — before ``x``). The first scan
is at effort 0, so a curve starts at Q after the first scan.

The scorecard keeps each run's Q on the fixed grids :data:`TIME_GRID_S` and :data:`PATH_GRID_M`,
and the normalised area under Q(t) over [0, budget] computed exactly from the steps.
"""

from __future__ import annotations

import numpy as np

from nbv_gym.core.protocol import TIME_BUDGET_S

#: Elapsed times (s) at which a scorecard run keeps its Q: 21 points from 0 to the time task's
#: default budget (every 30 s at 600 s).
TIME_GRID_S = tuple(float(t) for t in np.linspace(0.0, TIME_BUDGET_S, 21))
#: Path lengths (m) at which a scorecard run keeps its Q: every 5 m to 30 m, every 10 m to 100 m,
#: every 20 m to 200 m (the matched paths among them).
PATH_GRID_M = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0,
               120.0, 140.0, 160.0, 180.0, 200.0)  # fmt: skip
#: Decimals a scorecard keeps of a curve's Q (Q is ~1e-2: five or six significant digits).
CURVE_DECIMALS = 7
#: Path lengths (m) at which scorecards compare policies (Q at matched path).
MATCHED_PATHS_M = (25.0, 50.0, 100.0, 200.0)


def q_at(effort: np.ndarray, q: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """(k,) Q at each of the (k,) efforts ``grid``: Q after the last step whose cumulative
    ``effort`` ((n,) non-decreasing, the first 0) is ≤ the grid value; the first Q before it."""
    effort, q = np.asarray(effort, float), np.asarray(q, float)
    index = np.searchsorted(effort, np.asarray(grid, float), side="right") - 1
    return q[np.maximum(index, 0)]


def grid_curve(effort: np.ndarray, q: np.ndarray, grid: tuple[float, ...]) -> list[float]:
    """:func:`q_at` on ``grid`` as a list rounded to :data:`CURVE_DECIMALS` (a scorecard's)."""
    return [round(float(v), CURVE_DECIMALS) for v in q_at(effort, q, np.asarray(grid))]


def area_under(effort: np.ndarray, q: np.ndarray, end: float) -> float:
    """The area under the step function Q(effort) over [0, ``end``], divided by ``end``: the
    mean Q the run held over the budget (in [0, 1] as Q is)."""
    effort, q = np.asarray(effort, float), np.asarray(q, float)
    starts = np.minimum(effort, end)
    stops = np.append(starts[1:], end)
    return float(np.sum(q * (stops - starts)) / end)
