"""Sweep configs: the shipped experiments, run keys and seeds, and malformed configs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from nbv_gym.configs import config_file
from nbv_gym.core.config import parse_toml
from nbv_gym.core.errors import ConfigError
from nbv_gym.policies import PAPER_POLICIES
from nbv_gym.sweep.config import (
    SweepConfig,
    dumps_toml,
    load_sweep_config,
    sweep_config,
)

REQUIRED = ('worlds = ["pp1-cuboids"]\n', 'policies = ["closest-frontier"]\n')


def test_paper_config_is_the_756_runs_of_the_paper():
    config = load_sweep_config(config_file("paper"))
    runs = config.runs()
    assert len(runs) == 12 * 3 * 7 * 3 == 756
    assert len({r.key for r in runs}) == 756 and len({r.file_stem for r in runs}) == 756
    assert set(config.policies) == set(PAPER_POLICIES) and config.noise == (0, 1, 2)
    assert runs[0].key == "pp1-cuboids/noise0/random-frontier/rep0"


def test_quick_config_exercises_every_policy():
    config = load_sweep_config(config_file("quick"))
    assert set(config.policies) == set(PAPER_POLICIES)
    assert len(config.runs()) <= 60


def test_seeds_come_from_the_key_and_pair_the_policies():
    config = SweepConfig(
        worlds=("pp1-cuboids", "pp1-trees"), policies=PAPER_POLICIES, noise=(0, 1), repeats=2
    )
    seeds = {r.key: r.seed for r in config.runs()}
    again = {r.key: r.seed for r in SweepConfig(**{**vars(config)}).runs()}
    assert seeds == again
    assert seeds["pp1-trees/noise1/nbv-nobs/rep1"] == seeds["pp1-trees/noise1/random-free/rep1"]
    distinct = {
        seeds[f"{w}/noise{n}/nbv-nobs/rep{r}"]
        for w in config.worlds
        for n in (0, 1)
        for r in (0, 1)
    }
    assert len(distinct) == 8
    other_base = {r.key: r.seed for r in SweepConfig(**{**vars(config), "seed": 1}).runs()}
    assert all(other_base[k] != seeds[k] for k in seeds)


def test_resolved_config_round_trips_through_toml():
    config = SweepConfig(
        worlds=("pp1-cuboids",),
        policies=("closest-frontier", "my_module:MyPolicy"),
        env={"simulator": {"episode": {"discovered_target": 0.5}}, "nbv": {"alpha": 1.5}},
    )
    text = dumps_toml(config.file_dict())
    assert sweep_config(parse_toml(text, "test")) == config
    assert config.env_config("pp1-cuboids", 2).simulator.episode.discovered_target == 0.5


def test_file_names_are_safe_for_any_policy_name():
    (run,) = SweepConfig(
        worlds=("pp1-cuboids",), noise=(1,), policies=("a.b:C/D",), repeats=1
    ).runs()
    assert "/" not in run.file_stem and ":" not in run.file_stem
    assert run.key == "pp1-cuboids/noise1/a.b:C/D/rep0"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('polices = ["closest-frontier"]', r"Unknown key polices"),
        ('repeats = "3"', r"repeats: expected int"),
        ("repeats = 0", r"repeats: must be ≥ 1"),
        ("noise = [0, 3]", r"noise\[1\]: expected one of 0, 1, 2"),
        ('noise = "1"', r"noise: expected a list"),
        (
            'policies = ["closest-frontier", "closest-fronteer"]',
            r"policies\[1\]: Unknown policy 'closest-fronteer'. Did you mean 'closest-frontier'",
        ),
        ('worlds = ["pp9-trees"]', r"worlds\[0\]: Unknown world 'pp9-trees'"),
        ('worlds = ["pp1-trees", "pp1-trees"]', r"worlds: lists pp1-trees more than once"),
        ("max_steps = -1", r"max_steps: must be from 1 to 10,000, got -1"),
        ("[env.simulator.lidar]\nbogus = 1", r"env\.simulator\.lidar\.bogus"),
        ("[env.simulator]\nnoise = 2", r"env\.simulator\.noise: set by the sweep"),
        (
            "[env.simulator.episode]\ndiscovered_target = 2.0",
            r"env\.simulator\.episode: discovered_target",
        ),
        ("retries = -1", r"retries: must be ≥ 0"),
        ("worlds = [", r"not valid TOML"),
        ("run_timeout_s = 0", r"run_timeout_s: must be a number of seconds > 0"),
        ('worlds = ["pp1-cuboids"]', r"missing required key\(s\) policies"),
        ('policies = ["random-free"]', r"missing required key\(s\) worlds"),
        ('worlds = ["pp1-cuboids"]\npolicies = [""]', r"policies\[0\]: Unknown policy ''"),
        (
            'worlds = ["pp1-cuboids"]\npolicies = ["closest-frontier"]\nrun_timeout_s = inf',
            r"run_timeout_s: must be a number of seconds > 0, got inf",
        ),
    ],
    ids=lambda v: v.split("\n")[0][:30] if isinstance(v, str) else v,
)
def test_malformed_configs_are_rejected_naming_the_key(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    required = [line for line in REQUIRED if line.split(" =")[0] not in text]
    path.write_text("".join(required if "missing" not in message else []) + text + "\n")
    with pytest.raises(ConfigError, match=message):
        load_sweep_config(path)


def test_world_spec_files_are_relative_to_the_config(tmp_path):
    spec = (
        Path(__file__).parents[2] / "nbv_gym" / "worlds" / "benchmark" / "pp2-crosses.toml"
    ).read_text()
    (tmp_path / "specs").mkdir()
    (tmp_path / "specs" / "mine.toml").write_text(
        spec.replace('name = "pp2-crosses"', 'name = "mine"')
    )
    path = tmp_path / "sweep.toml"
    path.write_text('worlds = ["specs/mine.toml"]\npolicies = ["random-free"]\n')
    (run, *_) = load_sweep_config(path).runs()
    assert run.world == "mine" and Path(run.world_source).is_file()


def test_cli_rejects_a_malformed_config_with_exit_code_2(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('worlds = ["pp1-cuboids"]\npolicies = ["random-free"]\nrepeat = 2\n')
    result = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "sweep", str(path), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    assert "Unknown key repeat" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_rl_eval_config_is_the_budget_comparison_of_issue_14():
    config = load_sweep_config(config_file("rl-eval"))
    assert len(config.runs()) == 12 * 1 * 8 * 3
    assert config.task.name == "budget" and config.noise == (1,)
    assert set(config.policies) == {*PAPER_POLICIES, "ppo-budget"}
