"""A team of one is the single-robot time task: it reproduces stored reference runs of the
shipped scorecards bit for bit: the decisions, the clock and every figure of the run."""

from __future__ import annotations

import pytest

from nbv_gym.benchmark.curves import TIME_GRID_S, grid_curve
from nbv_gym.benchmark.references import REFERENCE_SUITE, reference_path
from nbv_gym.benchmark.scorecard import load_scorecard
from nbv_gym.benchmark.suiterun import part_config, write_world_specs
from nbv_gym.metrics.effort import area_under
from nbv_gym.team import EachRobot, TeamEnv, run_team_episode

#: Stored runs of closest-frontier on the standard suite: (split, world, noise, repeat).
RUNS = (("time-benchmark", "pp1-cuboids", 1, 0), ("time-test", "test-03", 2, 1))


@pytest.mark.parametrize(("split", "world", "noise", "repeat"), RUNS)
def test_a_team_of_one_reproduces_a_stored_single_robot_run(split, world, noise, repeat, tmp_path):
    name = "closest-frontier"
    card = load_scorecard(reference_path(name, REFERENCE_SUITE.name))
    stored = next(
        r
        for r in card["runs"]
        if (r["split"], r["world"], r["noise"], r["repeat"]) == (split, world, noise, repeat)
    )
    part = REFERENCE_SUITE.part(split)
    sources = write_world_specs(REFERENCE_SUITE, tmp_path)  # the test split's generated worlds
    config = part_config(REFERENCE_SUITE, part, name, sources)
    spec = next(s for s in config.runs() if (s.world, s.noise, s.repeat) == (world, noise, repeat))
    assert spec.seed == stored["seed"]
    env = TeamEnv(config.env_config(sources[world], noise), n_robots=1)
    result = run_team_episode(env, EachRobot.of(name, 1), spec.seed)
    figures, rows = result.figures, result.scans
    assert (figures["steps"], figures["end_reason"]) == (stored["steps"], stored["end_reason"])
    for key in ("path_length_m", "elapsed_s", "q", "discovered", "q_time_auc"):
        assert figures[key] == stored[key], key
    times = [row["time_s"] for row in rows]
    q = [row["q"] for row in rows]
    assert grid_curve(times, q, TIME_GRID_S) == stored["q_time"]
    # the team's mean Q is the benchmark's area under Q(t)
    assert figures["q_time_auc"] == area_under(times, q, part.task.time_budget_s)
