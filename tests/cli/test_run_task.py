"""``nbv-gym run`` and ``record`` choose the task: --task, --budget-scans, and a trained agent's
own task (read from the training config beside its model) when none is given."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from nbv_gym.cli.options import task_of
from nbv_gym.core.errors import ConfigError
from nbv_gym.policies import episode_task, model_path, trained_task


def test_a_shipped_agent_runs_its_own_task_and_budget_unless_told_otherwise():
    assert trained_task("ppo-budget") == ("budget", 12)  # models/ppo-budget.toml
    assert episode_task("ppo-budget") == ("budget", 12)
    assert episode_task("ppo-budget", budget_scans=20) == ("budget", 20)
    assert episode_task("ppo-budget", "explore") == ("explore", None)
    assert episode_task("closest-frontier") == ("explore", None)
    assert episode_task("closest-frontier", "budget") == ("budget", None)


def test_an_sb3_model_reads_the_config_of_its_training_run(tmp_path):
    (tmp_path / "best_model.zip").write_bytes(model_path("ppo-budget").read_bytes())
    assert trained_task(f"sb3:{tmp_path / 'best_model.zip'}") is None  # no config.toml beside
    (tmp_path / "config.toml").write_text('task = "budget"\nbudget_scans = 7\n')
    assert episode_task(f"sb3:{tmp_path / 'best_model.zip'}") == ("budget", 7)


def test_options_the_task_does_not_read_are_refused():
    with pytest.raises(
        ConfigError, match=r"task: expected one of explore, budget, time, got 'bugdet'"
    ):
        task_of("closest-frontier", "bugdet", None, None)
    with pytest.raises(ConfigError, match=r"--max-steps truncates the explore task"):
        task_of("ppo-budget", None, None, 30)
    with pytest.raises(ConfigError, match=r"--budget-scans is the budget task's"):
        task_of("closest-frontier", None, 5, None)
    with pytest.raises(ConfigError, match=r"--budget-scans is the budget task's"):
        task_of("closest-frontier", "time", 5, None)
    with pytest.raises(ConfigError, match=r"--max-steps .* give --time-budget-s instead"):
        task_of("closest-frontier", "time", None, 30)
    with pytest.raises(ConfigError, match=r"--time-budget-s is the time task's"):
        task_of("closest-frontier", "budget", None, None, 300.0)


@pytest.mark.parametrize("task", [[], ["--task", "budget"]], ids=["own-task", "--task budget"])
def test_run_of_the_shipped_agent_takes_twelve_scans(tmp_path, task):
    pytest.importorskip("sb3_contrib")
    done = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "run", "--policy", "ppo-budget", "--world",
         "pp1-cuboids", "--no-animation", "--out", str(tmp_path), "--json", *task],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["task"] == "budget" and summary["n_steps"] == 12
    assert summary["config"]["simulator"]["episode"]["discovered_target"] is None
    assert json.loads(Path(tmp_path, "summary.json").read_text())["n_steps"] == 12


def test_run_help_shows_the_simulator_defaults_it_uses():
    import typer.main

    from nbv_gym.cli.main import app
    from nbv_gym.simulator import SimulatorConfig

    command = typer.main.get_command(app).commands["run"]
    defaults = {p.name: p.default for p in command.params}
    assert (defaults["world"], defaults["noise"]) == (
        SimulatorConfig().world,
        SimulatorConfig().noise,
    )
    assert "the config's" not in command.get_help(typer.Context(command))


def test_run_of_the_time_task_spends_its_budget_and_writes_the_robots_clock(tmp_path):
    done = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "run", "--policy", "closest-frontier", "--world",
         "pp1-cuboids", "--no-animation", "--out", str(tmp_path), "--json", "--task", "time",
         "--time-budget-s", "90", "--speed-mps", "0.5", "--scan-time-s", "5"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["task"] == "time" and summary["end_reason"].startswith("time budget spent")
    episode = summary["config"]["simulator"]["episode"]
    assert (episode["time_budget_s"], episode["speed_mps"], episode["scan_time_s"]) == (90, 0.5, 5)
    with open(tmp_path / "steps.csv") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        expected = float(row["path_length_m"]) / 0.5 + int(row["step"]) * 5.0
        assert float(row["elapsed_s"]) == pytest.approx(expected, abs=1e-9)
    assert 60 < float(rows[-1]["elapsed_s"]) <= 90  # spent: no goal fitted in what was left


TIME_AGENT = (
    'task = "time"\nlidar = "vlp-16"\ntime_budget_s = 60.0\nspeed_mps = 0.5\nscan_time_s = 5.0\n'
    "max_steps = 12\n"
)
OWN = {"lidar": "vlp-16", "time_budget_s": 60.0, "speed_mps": 0.5, "scan_time_s": 5.0}
NOTHING = dict.fromkeys(OWN)


@pytest.mark.parametrize("where", ["final_model.zip", "checkpoints/model_32_steps.zip"])
def test_a_trained_agents_lidar_and_clock_are_its_defaults(tmp_path, where):
    """The round-4 probe R08: `run --policy sb3:MODEL` took the agent's task, not its lidar or
    time budget. A checkpoint's config is its run folder's."""
    from nbv_gym.cli.options import agent_options

    (tmp_path / "config.toml").write_text(TIME_AGENT)
    policy = f"sb3:{tmp_path / where}"
    assert episode_task(policy) == ("time", None)
    assert agent_options(policy, "time", **NOTHING) == OWN
    assert agent_options(policy, "time", **{**NOTHING, "lidar": "vlp-16"}) == OWN  # the same
    # under another task the agent keeps its lidar and clock; a budget is that task's own
    assert agent_options(policy, "budget", **NOTHING) == {**OWN, "time_budget_s": None}
    assert agent_options("closest-frontier", "time", **NOTHING) == NOTHING


@pytest.mark.parametrize(
    ("option", "value"),
    [("lidar", "os1-16"), ("time_budget_s", 600.0), ("speed_mps", 1.0), ("scan_time_s", 10.0)],
)
def test_an_option_that_contradicts_a_trained_agent_is_refused_naming_both(tmp_path, option, value):
    from nbv_gym.cli.options import AGENT_OPTIONS, agent_options

    (tmp_path / "config.toml").write_text(TIME_AGENT)
    policy = f"sb3:{tmp_path / 'final_model.zip'}"
    with pytest.raises(ConfigError) as error:
        agent_options(policy, "time", **{**NOTHING, option: value})
    message = str(error.value)
    assert message.startswith(f"{AGENT_OPTIONS[option]} {value}: {policy} was trained with")
    assert f"{option} = {OWN[option]!r} ({tmp_path / 'config.toml'})" in message


def test_a_budget_agent_leaves_the_clock_free():
    """ppo-budget learned with travel free: its speed and scan time are no contract."""
    from nbv_gym.cli.options import agent_options

    given = {**NOTHING, "speed_mps": 0.5, "time_budget_s": 300.0}
    assert agent_options("ppo-budget", "time", **given) == {**given, "lidar": "os1-16"}


def test_run_of_a_time_agent_uses_its_own_lidar_and_budget_and_refuses_another(tmp_path):
    pytest.importorskip("sb3_contrib")
    from tests.helpers import invoke, write_tiny_world

    world = write_tiny_world(tmp_path)
    (tmp_path / "t").mkdir()
    (tmp_path / "t" / "final_model.zip").write_bytes(model_path("ppo-time").read_bytes())
    (tmp_path / "t" / "config.toml").write_text(TIME_AGENT)
    run = ["run", "--policy", f"sb3:{tmp_path / 't' / 'final_model.zip'}", "--world", world,
           "--no-animation", "--noise", "0"]  # fmt: skip
    refused = invoke(*run, "--lidar", "os1-16", "--out", tmp_path / "r1")
    assert refused.code == 2 and "--lidar os1-16: sb3:" in refused.err
    assert not (tmp_path / "r1").exists()
    done = invoke(*run, "--out", tmp_path / "r2", "--json")
    assert done.code == 0, done.err
    summary = json.loads(done.out)
    episode = summary["config"]["simulator"]["episode"]
    assert (summary["task"], summary["lidar"]) == ("time", "vlp-16")
    assert (episode["time_budget_s"], episode["speed_mps"], episode["scan_time_s"]) == (60, 0.5, 5)
