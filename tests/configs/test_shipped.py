"""The shipped configs: found by name (also from an installed wheel), listed, shown, copied."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from nbv_gym.configs import KINDS, config_file, shipped_configs
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.rl.config import load_train_config
from nbv_gym.sweep.config import load_sweep_config, read_sweep_config

SWEEPS = {"quick", "paper", "rl-eval", "nbv-visibility", "references"}


def nbv_gym(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "nbv_gym", *args], capture_output=True, text=True, cwd=cwd
    )


def test_every_shipped_config_has_a_kind_and_loads_as_one():
    shipped = shipped_configs()
    assert {n for n, c in shipped.items() if c.kind == "sweep"} == SWEEPS
    assert shipped["ppo"].kind == "train" and shipped["rl-zoo3-ppo"].kind == "rl-zoo3"
    assert {c.kind for c in shipped.values()} == set(KINDS)
    for name in SWEEPS:
        assert load_sweep_config(config_file(name, "sweep")).name == name
    assert load_train_config(config_file("ppo", "train")).task.name == "budget"


def test_a_shipped_sweep_sets_every_key_its_task_reads_so_it_prints_no_defaults(tmp_path):
    for name in SWEEPS:  # the README's first command prints no note about left-out keys
        assert read_sweep_config(config_file(name, "sweep"))[1] == {}, name
    spec = tmp_path / "b.toml"  # a budget sweep leaves the other tasks' lengths unmentioned
    spec.write_text('worlds = ["pp1-trees"]\npolicies = ["random-free"]\ntask = "budget"\n')
    assert set(read_sweep_config(spec)[1]) == {
        "noise", "repeats", "seed", "budget_scans", "retries", "run_timeout_s"
    }  # fmt: skip


def test_a_path_is_taken_as_a_path_and_a_missing_one_is_named(tmp_path):
    own = tmp_path / "quick.toml"
    own.write_text('worlds = ["pp1-trees"]\npolicies = ["closest-frontier"]\n')
    assert config_file(own) == own and config_file(str(own), "sweep") == own
    with pytest.raises(ConfigError, match=r"Config file 'nope.toml' does not exist"):
        config_file("nope.toml")


def test_an_unknown_name_suggests_the_near_miss_of_its_kind():
    with pytest.raises(
        UnknownNameError, match=r"Unknown sweep config 'quik'. Did you mean 'quick'"
    ):
        config_file("quik", "sweep")
    with pytest.raises(
        UnknownNameError,
        match=r"Valid train configs: imitation-time, ppo, ppo-time, ppo-time-wide, ppo-wide, team-ppo\.$",
    ):
        config_file("quick", "train")


def test_configs_list_show_and_copy_from_another_folder(tmp_path):
    listed = nbv_gym("configs", "list", cwd=tmp_path)
    rows = {line.split()[0]: line.split()[1] for line in listed.stdout.splitlines()}
    assert listed.returncode == 0 and rows["quick"] == "sweep" and rows["ppo"] == "train"
    shown = nbv_gym("configs", "show", "quick", cwd=tmp_path)
    assert shown.stdout == config_file("quick").read_text()
    assert nbv_gym("configs", "copy", "quick", "mine.toml", cwd=tmp_path).returncode == 0
    assert (tmp_path / "mine.toml").read_text() == shown.stdout
    again = nbv_gym("configs", "copy", "quick", "mine.toml", cwd=tmp_path)
    assert again.returncode == 2 and "exists; pass --force" in again.stderr


def test_sweep_and_train_take_a_name_and_refuse_a_wrong_one(tmp_path):
    sweep = nbv_gym("sweep", "ppo", cwd=tmp_path)
    assert sweep.returncode == 2 and "Unknown sweep config 'ppo'" in sweep.stderr
    train = nbv_gym("train", "--config", "quick", cwd=tmp_path)
    assert train.returncode == 2 and "Unknown train config 'quick'" in train.stderr
