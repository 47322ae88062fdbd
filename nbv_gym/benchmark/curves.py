"""The scorecard's grids of Q over effort: Q against elapsed time and against path length.

A run's Q at effort ``x`` (seconds, or metres) follows the one rule of
:mod:`nbv_gym.metrics.effort` (Q after the last scan within ``x``; the final Q beyond the run's
end). The scorecard keeps each run's Q on the fixed grids :data:`TIME_GRID_S` and :data:`PATH_GRID_M`,
and the normalised area under Q(t) over [0, budget] computed exactly from the steps.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from nbv_gym.core.protocol import TIME_BUDGET_S
from nbv_gym.metrics.effort import q_at

#: Elapsed times (s) at which a scorecard run keeps its Q: 21 points from 0 to the time task's
#: default budget (every 30 s at 600 s).
TIME_GRID_S = tuple(float(t) for t in np.linspace(0.0, TIME_BUDGET_S, 21))
#: Elapsed times (s) at which a team protocol's run keeps its Q: 61 points from 0 to 3 × the
#: default budget (every 30 s to 1800 s), so one robot with N × the budget (N ≤ 3, the same total
#: robot time as a team of N) is on the grid to its end.
TEAM_TIME_GRID_S = tuple(float(t) for t in np.linspace(0.0, 3 * TIME_BUDGET_S, 61))
#: Path lengths (m) at which a scorecard run keeps its Q: every 5 m to 30 m, every 10 m to 100 m,
#: every 20 m to 200 m (the matched paths among them).
PATH_GRID_M = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0, 100.0,
               120.0, 140.0, 160.0, 180.0, 200.0)  # fmt: skip
#: Decimals a scorecard keeps of a curve's Q (Q is ~1e-2: five or six significant digits).
CURVE_DECIMALS = 7
#: Elapsed times (s) at which a team protocol's run keeps its Q: 61 points from 0 to 3 × the
#: default budget (every 30 s to 1800 s), so one robot with N × the budget (N ≤ 3, the same total
#: robot time as a team of N) is on the grid to its end.
TEAM_TIME_GRID_S = tuple(float(t) for t in np.linspace(0.0, 3 * TIME_BUDGET_S, 61))
#: Path lengths (m) at which scorecards compare policies (Q at matched path).
MATCHED_PATHS_M = (25.0, 50.0, 100.0, 200.0)


def grid_curve(effort: np.ndarray, q: np.ndarray, grid: tuple[float, ...]) -> list[float]:
    """:func:`~nbv_gym.metrics.effort.q_at` on ``grid`` as a list rounded to :data:`CURVE_DECIMALS` (a scorecard's)."""
    return [round(float(v), CURVE_DECIMALS) for v in q_at(effort, q, np.asarray(grid))]


def time_grid(part: Mapping[str, object]) -> tuple[float, ...]:
    """The time grid of a part's runs (a scorecard's part entry or description):
    :data:`TEAM_TIME_GRID_S` for the team protocol's (``robots`` set), else :data:`TIME_GRID_S`."""
    return TEAM_TIME_GRID_S if "robots" in part else TIME_GRID_S
