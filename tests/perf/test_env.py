"""The env bench suite's figures in raw casts: a step and its parts divided by the raw cast of
the step's own scan, the lidar's part less the cast, the rest of the step as Python's."""

from __future__ import annotations

import numpy as np

from nbv_gym.perf.env import CPU, PARTS, _raw_shares, _time_parts, _untime_parts


def test_a_step_and_its_parts_in_raw_casts_add_up():
    # two steps of 10 ms and 8 ms CPU, raw casts of 2 ms and 1 ms
    parts = [
        {key + CPU: 1e-3 for key in PARTS} | {"env_lidar_ms" + CPU: 3e-3},
        {key + CPU: 0.5e-3 for key in PARTS} | {"env_lidar_ms" + CPU: 1.5e-3},
    ]
    shares = _raw_shares([10e-3, 8e-3], parts, [2e-3, 1e-3])
    np.testing.assert_allclose(shares["env_step_raw"], [5.0, 8.0])
    np.testing.assert_allclose(shares["env_postprocess_raw"], [0.5, 0.5])  # 3 ms lidar, 2 ms cast
    np.testing.assert_allclose(shares["env_insert_raw"], [0.5, 0.5])
    others = len(PARTS) - 1
    np.testing.assert_allclose(
        shares["env_python_raw"], [(10 - 3 - others) / 2, (8 - 1.5 - 0.5 * others)]
    )
    total = sum(shares[key] for key in shares if key not in ("env_step_raw",)) + 1  # + the cast
    np.testing.assert_allclose(total, shares["env_step_raw"])
    assert set(shares) == {
        "env_step_raw", "env_postprocess_raw", "env_insert_raw", "env_statistics_raw",
        "env_navigation_raw", "env_quality_raw", "env_observation_raw", "env_python_raw",
    }  # fmt: skip


def test_a_method_counts_in_every_part_naming_it_and_its_timers_come_off():
    class Lidar:
        def scan(self) -> int:
            return 7

    class Env:
        sim = type("Sim", (), {})()

    env = Env()
    env.sim.lidar = Lidar()
    parts = {"env_a_ms": (("sim.lidar", "scan"),), "env_b_ms": (("sim.lidar", "scan"),)}
    spent = _time_parts(env, parts=parts)
    assert env.sim.lidar.scan() == 7
    assert set(spent) == {"env_a_ms", "env_a_ms" + CPU, "env_b_ms", "env_b_ms" + CPU}
    _untime_parts(env, parts)
    assert "scan" not in vars(env.sim.lidar)
