"""One shape of a task's settings (:class:`~nbv_gym.env.task.TaskConfig`): declared once in the
package, checked once, and the same settings give the same run through every entry point."""

from __future__ import annotations

import ast
import csv
from dataclasses import replace
from pathlib import Path

import pytest
from typer.testing import CliRunner

from nbv_gym.cli.main import app
from nbv_gym.core.errors import ConfigError
from nbv_gym.env.task import TaskConfig

ROOT = Path(__file__).resolve().parents[2]
#: The task settings: each must be a field of one dataclass only.
SETTINGS = ("budget_scans", "time_budget_s", "speed_mps", "scan_time_s", "lidar", "max_steps",
            "observation_layers", "noise")  # fmt: skip
#: Dataclasses that declare a setting's name for another thing: the environment's own resolved
#: config (what TaskConfig builds: the simulator's noise, lidar beam pattern and episode, whose
#: shape the suites' content hashes are of) and the effort model; the grids of a sweep and a
#: suite part (their ``noise`` is a list of levels to run); records of runs already made (a
#: sweep's run, a study's run folder, a report's results); the wd study's scans per run.
ELSEWHERE = {
    ("EpisodeConfig", "max_steps"), ("EpisodeConfig", "time_budget_s"),
    ("EpisodeConfig", "speed_mps"), ("EpisodeConfig", "scan_time_s"),
    ("EffortModel", "speed_mps"), ("EffortModel", "scan_time_s"),
    ("SimulatorConfig", "noise"), ("SimulatorConfig", "lidar"),
    ("EnvConfig", "observation_layers"),
    ("SweepConfig", "noise"), ("Part", "noise"),
    ("RunSpec", "noise"), ("RunFolder", "noise"), ("Results", "time_budget_s"),
    ("WdStudyConfig", "max_steps"),
}  # fmt: skip
#: Not converted yet: ``nbv-gym tune``'s config (a time task on a pool, its own noise and budget).
NOT_YET = {("TuningConfig", "noise"), ("TuningConfig", "time_budget_s")}


def declarations() -> dict[str, list[str]]:
    """Setting name → the dataclasses of nbv_gym/ that declare a field of that name."""
    found: dict[str, list[str]] = {name: [] for name in SETTINGS}
    for path in sorted((ROOT / "nbv_gym").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            is_dataclass = isinstance(node, ast.ClassDef) and any(
                "dataclass" in ast.unparse(d) for d in node.decorator_list
            )
            if not is_dataclass:
                continue
            for item in node.body:  # type: ignore[attr-defined]
                if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    name = item.target.id
                    if name in found and (node.name, name) not in ELSEWHERE | NOT_YET:  # type: ignore[attr-defined]
                        found[name].append(f"{path.relative_to(ROOT)}:{node.name}")  # type: ignore[attr-defined]
    return found


def test_each_task_setting_is_declared_once_in_one_dataclass():
    found = declarations()
    assert found == {name: ["nbv_gym/env/task.py:TaskConfig"] for name in SETTINGS}


def test_a_task_config_checks_its_settings_naming_the_key():
    with pytest.raises(ConfigError, match=r"^lidar: Unknown lidar 'os-64'"):
        TaskConfig(lidar="os-64")
    with pytest.raises(ConfigError, match=r"^budget_scans: must be from 1 to 10,000, got 0"):
        TaskConfig(name="budget", budget_scans=0)
    with pytest.raises(ConfigError, match=r"^noise: expected one of 0, 1, 2, got 3"):
        TaskConfig(noise=3)
    with pytest.raises(ConfigError, match=r"^speed_mps: must be from 0.01 to 100 m/s"):
        TaskConfig(speed_mps=0.0)


def test_a_budget_tasks_old_max_steps_is_one_line_naming_budget_scans():
    with pytest.raises(ConfigError, match=r"max_steps: .* write budget_scans = 20$"):
        TaskConfig.from_flat({"task": "budget", "max_steps": 20})
    with pytest.raises(ConfigError, match=r"give budget_scans=20$"):
        from nbv_gym.env.explore import ExploreEnv

        ExploreEnv(task="budget", world="pp1-cuboids", max_steps=20)
    settings = TaskConfig(name="time", noise=2, lidar="vlp-16", time_budget_s=90.0)
    assert TaskConfig.from_flat(settings.flat()) == settings


#: Non-default settings of every kind: the time task, noise 2, another lidar, another clock.
SETTINGS_GIVEN = TaskConfig(name="time", noise=2, lidar="vlp-16", time_budget_s=20.0,
                            speed_mps=0.8, scan_time_s=3.0)  # fmt: skip
WORLD, POLICY, SEED = "pp1-cuboids", "closest-frontier", 3


def _episode(config, seed: int = SEED) -> list[tuple[int, float]]:
    """(goal, Q) of each step of ``closest-frontier`` in an env of the EnvConfig ``config``."""
    from nbv_gym.episode import make_env, run_episode
    from nbv_gym.policies import load_policy

    policy = load_policy(POLICY)
    result = run_episode(make_env(config, policy), policy, seed)
    return [(int(row["goal"]), float(row["q"])) for row in result.steps]


def test_the_same_settings_give_the_same_run_through_every_entry_point(tmp_path):
    from nbv_gym.benchmark.suites import Part
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.rl.config import TrainConfig
    from nbv_gym.sweep.config import load_sweep_config

    expected = _episode(SETTINGS_GIVEN.env_config(WORLD))
    assert 2 <= len(expected) <= 10  # a short run: some goals, the budget spent

    options = ["--world", WORLD, "--policy", POLICY, "--noise", "2", "--seed", str(SEED),
               "--task", "time", "--time-budget-s", "20", "--speed-mps", "0.8",
               "--scan-time-s", "3", "--lidar", "vlp-16"]  # fmt: skip
    result = CliRunner().invoke(app, ["run", *options, "--no-animation", "--out", tmp_path / "r"])
    assert result.exit_code == 0, result.output
    with open(tmp_path / "r" / "steps.csv", encoding="utf-8") as file:
        rows = list(csv.DictReader(file))
    assert [(int(r["goal"]), float(r["q"])) for r in rows] == expected  # nbv-gym run

    train = TrainConfig(task=SETTINGS_GIVEN, train_worlds=(WORLD,), eval_worlds=())
    env = ExploreEnv(world=WORLD, **train.env_kwargs())  # what train's environments are made of
    assert _episode(env.config) == expected
    kwargs = {"task": "time", "noise": 2, "lidar": "vlp-16", "time_budget_s": 20.0,
              "speed_mps": 0.8, "scan_time_s": 3.0}  # fmt: skip
    assert _episode(ExploreEnv(world=WORLD, **kwargs).config) == expected  # ExploreEnv(**kw)

    sweep_file = tmp_path / "sweep.toml"
    sweep_file.write_text(
        f'worlds = ["{WORLD}"]\npolicies = ["{POLICY}"]\nnoise = [2]\nrepeats = 1\n'
        'task = "time"\ntime_budget_s = 20.0\nspeed_mps = 0.8\nscan_time_s = 3.0\n'
        'lidar = "vlp-16"\n',
        encoding="utf-8",
    )
    sweep = load_sweep_config(sweep_file)
    assert _episode(sweep.env_config(WORLD, 2)) == expected  # nbv-gym sweep's runs

    part = Part("mine", replace(SETTINGS_GIVEN, noise=2), (WORLD,), noise=(2,))
    assert _episode(replace(part.env_config(), simulator=replace(
        part.env_config().simulator, world=WORLD, noise=2))) == expected  # fmt: skip

    pytest.importorskip("minari")
    out = tmp_path / "data"
    result = CliRunner().invoke(app, ["record", *options, "--out", out])
    assert result.exit_code == 0, result.output
    from nbv_gym.rl.dataset import load_recording

    (episode,) = load_recording(out, f"nbv-gym/{WORLD}/{POLICY}-v0").iterate_episodes()
    assert [int(a) for a in episode.actions] == [goal for goal, _ in expected[1:]]
    assert [float(q) for q in episode.infos["q"]] == [q for _, q in expected]  # nbv-gym record
