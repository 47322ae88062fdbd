"""The scorecard's grids of Q over effort (nbv_gym.benchmark.curves)."""

from __future__ import annotations

from nbv_gym.benchmark.curves import CURVE_DECIMALS, MATCHED_PATHS_M, PATH_GRID_M, grid_curve


def test_the_matched_paths_lie_on_the_path_grid():
    assert set(MATCHED_PATHS_M) <= set(PATH_GRID_M)


def test_a_grid_curve_is_q_at_rounded_and_holds_the_final_q():
    curve = grid_curve([0.0, 20.0], [0.123456789, 0.2], (0.0, 10.0, 30.0))
    assert curve == [round(0.123456789, CURVE_DECIMALS), round(0.123456789, CURVE_DECIMALS), 0.2]
