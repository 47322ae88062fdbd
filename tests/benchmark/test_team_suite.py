"""The team suite end to end on a tiny suite of its shape: score a team policy and a single-robot
policy every robot runs, check the scorecards, rank them with the one-robot N × T rows; what the
team protocol refuses, in one line each."""

from __future__ import annotations

import copy
import json
import re
import subprocess
import sys

import pytest

from nbv_gym.benchmark.curves import PATH_GRID_M, TEAM_TIME_GRID_S, TIME_GRID_S
from nbv_gym.benchmark.leaderboard import build_leaderboard
from nbv_gym.benchmark.references import REFERENCE_DIR
from nbv_gym.benchmark.scorecard import ScorecardError, dumps_strict, load_scorecard
from nbv_gym.benchmark.suiterun import ScoreError, score_policy
from nbv_gym.benchmark.suites import QUICK, STANDARD, TEAM, Part, Suite
from nbv_gym.benchmark.teamboard import TeamBoardError
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import TIME_BUDGET_S, EffortModel
from nbv_gym.env.task import TaskConfig

from .conftest import TINY_WORLD

#: The tiny suite's team budget, s (a team of 2 takes 2–3 scans each).
BUDGET_S = 40.0


TIME = TaskConfig(name="time")


@pytest.fixture(scope="module")
def tiny_team() -> Suite:
    """The team suite's shape, tiny: 2 robots for 40 s, and one robot for 2 × 40 s, on one
    generated world, noise 0, 2 repeats (4 runs)."""
    return Suite(
        "tiny-team",
        (
            Part(
                "team2-test",
                TaskConfig(name="time", time_budget_s=BUDGET_S),
                (TINY_WORLD,),
                noise=(0,),
                repeats=2,
                robots=2,
            ),
            Part(
                "solo2-test",
                TaskConfig(name="time", time_budget_s=2 * BUDGET_S),
                (TINY_WORLD,),
                noise=(0,),
                repeats=2,
                robots=1,
            ),
        ),
        seed=0,
    )


@pytest.fixture(scope="module")
def scored(tiny_team, tmp_path_factory):
    """Scorecard folders of hungarian-frontier (a team policy) and closest-frontier (every robot
    its own copy) on the tiny team suite."""
    root = tmp_path_factory.mktemp("team-scores")
    for policy in ("hungarian-frontier", "closest-frontier"):
        score_policy(
            policy, tiny_team, root / policy, workers=1, progress=False, say=lambda m: None
        )
    return root


def test_the_team_suite_runs_2_and_3_robots_on_the_test_and_shift_worlds_and_one_robot_n_t():
    parts = {part.split: part for part in TEAM.parts}
    assert set(parts) == {"team2-test", "team3-test", "team2-shift", "team3-shift",
                          "solo2-test", "solo3-test"}  # fmt: skip
    test, shift = STANDARD.part("time-test"), STANDARD.part("time-shift")
    for n in (2, 3):
        assert parts[f"team{n}-test"].world_names == test.world_names
        assert parts[f"team{n}-shift"].world_names == shift.world_names
        assert parts[f"team{n}-test"].robots == n
        solo = parts[f"solo{n}-test"]
        assert (solo.robots, solo.task.time_budget_s) == (1, n * TIME_BUDGET_S)
        assert solo.world_names == test.world_names
    assert all(
        p.noise == (0, 1, 2) and p.repeats == 3 and p.task.name == "time" for p in TEAM.parts
    )
    assert TEAM.seed == STANDARD.seed
    # the single-robot parts' descriptions (and so their hashes) do not name robots
    assert all("robots" not in p.description() for s in (STANDARD, QUICK) for p in s.parts)
    assert all(p.description()["robots"] == p.robots for p in TEAM.parts)


def test_the_team_grid_reaches_three_budgets_and_starts_as_the_single_robots():
    assert TEAM_TIME_GRID_S[: len(TIME_GRID_S)] == TIME_GRID_S
    assert TEAM_TIME_GRID_S[-1] == 3 * TIME_BUDGET_S


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Part("t", TIME, ("pp1-cuboids",), robots=0), "at least 1 robot, got 0"),
        (lambda: Part("t", TaskConfig(name="budget"), ("pp1-cuboids",), robots=2), "time task"),
        (
            lambda: Suite(
                "mixed",
                (
                    Part("a", TIME, ("pp1-cuboids",)),
                    Part("b", TIME, ("pp1-cuboids",), robots=2),
                ),
                0,
            ),
            "all of the team protocol",
        ),
    ],
)
def test_a_bad_team_part_or_suite_is_one_line(make, message):
    with pytest.raises(ConfigError, match=message):
        make()


def test_a_team_policy_on_a_single_robot_suite_is_refused_before_any_run(tmp_path):
    with pytest.raises(ScoreError, match="is a team policy; score it on the team suite"):
        score_policy("hungarian-frontier", QUICK, tmp_path / "hf", progress=False)
    assert not (tmp_path / "hf").exists()


@pytest.mark.slow
def test_a_team_scorecard_validates_and_carries_the_teams_figures(scored):
    card = load_scorecard(scored / "hungarian-frontier" / "scorecard.json")
    assert card["policy"]["class"] == "nbv_gym.team.policies:HungarianFrontier"
    assert [p["robots"] for p in card["suite"]["parts"]] == [2, 1]
    effort = EffortModel()
    for run in card["runs"]:
        robots = run["per_robot"]
        assert len(robots) == (2 if run["split"] == "team2-test" else 1)
        assert run["steps"] == sum(r["steps"] for r in robots)
        assert run["elapsed_s"] == max(effort.elapsed_s(r["path_length_m"], r["steps"])
                                       for r in robots)  # fmt: skip
        assert run["longest_path_m"] == max(r["path_length_m"] for r in robots)
        assert len(run["q_time"]) == len(TEAM_TIME_GRID_S) and len(run["q_path"]) == len(
            PATH_GRID_M
        )
        assert run["overlap_rate"] >= 0 and 0 <= run["contribution_spread"] <= 1
    solo = [r for r in card["runs"] if r["split"] == "solo2-test"]
    assert all(r["overlap_rate"] == 0 and r["contribution_spread"] == 0 for r in solo)
    assert all(BUDGET_S < r["elapsed_s"] <= 2 * BUDGET_S for r in solo)  # past a team's budget
    means = card["aggregates"]["team2-test"]["means"]
    assert {"overlap_rate", "longest_path_m", "contribution_spread", "time_to_q_s"} <= set(means)
    each = load_scorecard(scored / "closest-frontier" / "scorecard.json")
    assert each["policy"]["class"].startswith("nbv_gym.team.policies:EachRobot(")


@pytest.mark.slow
def test_a_team_run_edited_out_of_step_with_its_robots_is_refused(scored, tmp_path):
    card = json.loads((scored / "hungarian-frontier" / "scorecard.json").read_text())
    edited = copy.deepcopy(card)
    edited["runs"][0]["per_robot"][0]["path_length_m"] += 1.0
    (path := tmp_path / "scorecard.json").write_text(dumps_strict(edited))
    with pytest.raises(ScorecardError, match=r"runs\[0\].*path_length_m is .*\(per_robot\)"):
        load_scorecard(path)


@pytest.mark.slow
def test_the_team_leaderboard_ranks_teams_with_one_robot_n_t_rows(scored, tmp_path):
    cards = [scored / "hungarian-frontier", scored / "closest-frontier"]
    board = build_leaderboard(cards, False, tmp_path / "board")
    rows = board.summary.splitlines()
    assert "team2-test: IQM area under Q(t)" in rows[0] and "overlap" in rows[0]
    labels = [re.split(r"\s{2,}", line)[1] for line in rows[2:]]
    assert sorted(labels) == sorted(["hungarian-frontier", "closest-frontier",
                                     "hungarian-frontier, one robot, N × T",
                                     "closest-frontier, one robot, N × T"])  # fmt: skip
    text = board.markdown.read_text(encoding="utf-8")
    assert "# Team leaderboard" in text and "longest path (m)" in text
    assert (tmp_path / "board" / "q-time.png").is_file()


@pytest.mark.slow
def test_team_and_single_robot_scorecards_are_never_ranked_together(scored, tmp_path):
    single = REFERENCE_DIR / "quick" / "closest-frontier.json"
    with pytest.raises(TeamBoardError, match=r"Cannot rank team scorecards .* single-robot"):
        build_leaderboard([scored / "hungarian-frontier", single], False, tmp_path / "b")


def test_the_score_command_refuses_world_or_scheduler_with_the_team_suite(tmp_path):
    for extra in (["--world", "pp1-cuboids"], ["--scheduler", "local"]):
        result = subprocess.run(
            [sys.executable, "-m", "nbv_gym", "score", "hungarian-frontier", "--suite", "team",
             "--out", str(tmp_path / "x"), *extra],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        assert result.returncode == 2 and "Traceback" not in result.stderr
        assert f"{extra[0]}: suite team" in result.stderr
    assert not (tmp_path / "x").exists()
