"""The training environments: one simulator cycles over its worlds or draws from a distribution;
unmasked learners' environments snap invalid goals."""

from __future__ import annotations

import numpy as np

from nbv_gym.env.task import TaskConfig
from nbv_gym.rl.envs import WorldCycleEnv

BORDER_GOAL = 0  # never valid: within 1 m of the window border


def test_world_cycle_switches_worlds_in_one_simulator(world):
    env = WorldCycleEnv(worlds=(world, "pp1-cuboids"), max_steps=2, reward_scale=100.0)
    simulator = env.env.sim
    names = [env.reset(seed=k)[1]["world"] for k in range(3)]
    assert names == ["tiny-cuboids", "pp1-cuboids", "tiny-cuboids"]
    assert env.env.sim is simulator


def test_distribution_draws_and_snapping_reaches_the_learner():
    env = WorldCycleEnv(
        worlds=("random:cuboids",), max_steps=2, invalid_action="snap", world_pool_size=4
    )
    drawn = {env.reset(seed=seed)[1]["world"] for seed in range(6)}
    assert len(drawn) > 1 and all(name.startswith("random-cuboids-") for name in drawn)
    *_, info = env.step(np.int64(BORDER_GOAL))
    assert info["snapped"] and info["goal"] != BORDER_GOAL


def test_the_time_task_trains_under_its_budget_and_effort_model():
    from nbv_gym.rl.config import TrainConfig

    config = TrainConfig(
        task=TaskConfig(name="time", time_budget_s=120.0, speed_mps=0.5, scan_time_s=5.0)
    )
    kwargs = config.env_kwargs()
    assert {k: kwargs[k] for k in ("speed_mps", "scan_time_s", "time_budget_s")} == {
        "speed_mps": 0.5, "scan_time_s": 5.0, "time_budget_s": 120.0}  # fmt: skip
    assert "max_steps" not in kwargs  # the time task caps scans itself
    budget = TrainConfig().env_kwargs()
    assert "time_budget_s" not in budget and budget["budget_scans"] == 12  # no time budget
    env = WorldCycleEnv(("pp1-cuboids",), **kwargs)
    episode = env.env.config.simulator.episode
    assert (episode.time_budget_s, episode.speed_mps, episode.scan_time_s) == (120.0, 0.5, 5.0)
    assert episode.max_steps == 25  # 120 s / 5 s per scan, + 1
    _, info = env.reset(seed=0)
    assert info["remaining_s"] == 120.0
