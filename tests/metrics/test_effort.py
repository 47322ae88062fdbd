"""Q over effort as a step function (nbv_gym.metrics.effort), against hand-worked cases."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.metrics.effort import area_under, q_at

#: Three scans: Q 0.1 at 0 s, 0.3 after 20 s, 0.4 after 50 s.
EFFORT, Q = np.array([0.0, 20.0, 50.0]), np.array([0.1, 0.3, 0.4])


def test_q_at_holds_the_last_q_reached_and_the_final_q_beyond_the_end():
    grid = np.array([0.0, 19.9, 20.0, 49.0, 50.0, 80.0])
    np.testing.assert_array_equal(q_at(EFFORT, Q, grid), [0.1, 0.1, 0.3, 0.3, 0.4, 0.4])


def test_q_at_takes_the_last_of_steps_that_cost_nothing_more():
    np.testing.assert_array_equal(q_at([0.0, 0.0, 10.0], [0.1, 0.2, 0.3], [0.0, 5.0]), [0.2, 0.2])


def test_the_area_is_the_mean_q_held_over_the_budget():
    # 0.1 for 20 s, 0.3 for 30 s, 0.4 for the last 50 s of 100 s
    assert area_under(EFFORT, Q, 100.0) == pytest.approx((0.1 * 20 + 0.3 * 30 + 0.4 * 50) / 100)
    # a budget that ends between scans cuts the last interval
    assert area_under(EFFORT, Q, 30.0) == pytest.approx((0.1 * 20 + 0.3 * 10) / 30)
