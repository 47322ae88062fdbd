"""``nbv-gym run --robots N``: a team episode into a run folder (its figures, the scans, an
animation and every robot's path in its own colour), and bad team input in one line."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from PIL import Image

from nbv_gym.team import TeamEnv, load_team_policy, run_team_episode
from nbv_gym.team.render import ROBOT_COLOURS
from nbv_gym.team.runfolder import TEAM_RUN_FILES
from tests.cli.test_errors import one_line_error
from tests.helpers import run_cli

WORLD = "pp1-cuboids"
#: A short budget: a few scans per robot.
BUDGET_S = 40.0


def test_a_team_run_writes_its_figures_scans_animation_and_paths(tmp_path):
    out = tmp_path / "team"
    done = run_cli("run", "--robots", 2, "--policy", "hungarian-frontier", "--world", WORLD,
                   "--time-budget-s", BUDGET_S, "--seed", 3, "--out", out, "--json")  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert {p.name for p in out.iterdir()} >= set(TEAM_RUN_FILES)
    env = TeamEnv(world=WORLD, n_robots=2, time_budget_s=BUDGET_S)
    expected = run_team_episode(env, load_team_policy("hungarian-frontier", 2), seed=3)
    assert summary["figures"] == json.loads(json.dumps(expected.figures))  # as the library's
    assert (summary["robots"], summary["task"], len(summary["per_robot"])) == (2, "time", 2)
    with open(out / "scans.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["robot"]) for r in rows] == [s["robot"] for s in expected.scans]
    assert [float(r["q"]) for r in rows] == [s["q"] for s in expected.scans]
    gif = Image.open(out / "exploration.gif")
    assert gif.n_frames == len(rows) - 2 + 1  # the reset, then a frame per decision
    paths = np.asarray(Image.open(out / "paths.png").convert("RGB"))
    for colour in ROBOT_COLOURS[:2]:  # each robot drawn in its own colour
        rgb = np.round(np.array(to_rgb(colour)) * 255)
        assert (np.abs(paths - rgb).max(axis=-1) <= 2).sum() > 50, colour


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--robots", "0"], "Invalid value for '--robots': expected an integer ≥ 1, got 0"),
        (["--robots", "10"], "10 robots, but world pp1-cuboids has 9 free start points"),
        (["--robots", "2", "--task", "budget"], "--task budget: --robots 2 runs the team task"),
        (["--robots", "3", "--budget-scans", "5"], "--budget-scans 5: --robots 3 runs the team"),
        (["--robots", "2", "--policy", "oracle-greedy"], "is an oracle; teams run agent policies"),
        (["--robots", "2", "--policy", "hungarian"], "Did you mean 'hungarian-frontier'?"),
    ],
    ids=["zero", "ten", "task", "budget-scans", "oracle", "unknown"],
)
def test_bad_team_input_gives_one_line_and_writes_nothing(tmp_path, args, message):
    done = run_cli("run", "--world", WORLD, "--out", tmp_path / "team", *args)
    assert message in one_line_error(done)
    assert not (tmp_path / "team").exists()
