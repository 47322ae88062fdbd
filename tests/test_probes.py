"""Probes of bad input and faults, class by class, as a hostile new user would try them: each
exits 2 with one line naming the problem (no traceback) or does the right thing, and nothing
written before is lost (hashes before and after).

The classes: 1 data lost, 2 names that become paths, 3 unbounded work before the first message,
4 unusable outputs, 5 numbers outside their domain, 6 files that lie, 7 results that mix or
mislead, 8 the env's keywords, 9 unclear messages. The commands run in this process (the CLI's
own error boundary, ``nbv_gym.cli.main.app``), on a 4-cuboid world.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import Result, invoke

TINY = """
name = "tiny"
description = "4 cuboids"
ground_size_m = 24.0
[placement]
seed = 3
n_assets = 4
cluster_radius_m = 5.0
window_m = [-10.0, -10.0, 10.0, 10.0]
[assets]
mix = { cuboids = 1.0 }
"""
#: The README's example of a policy of your own.
MY_POLICY = """
import numpy as np


class Nearest:
    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        distance = np.where(info["action_mask"], observation["distance"], np.inf)
        return int(np.argmin(distance))


class Crashing(Nearest):
    def act(self, observation, info):
        raise RuntimeError("this policy crashes")


class Exiting(Nearest):
    def act(self, observation, info):
        import sys

        sys.exit(0)


class CtrlC(Nearest):
    def act(self, observation, info):
        raise KeyboardInterrupt
"""
#: stderr lines that are not messages: progress of a run, a stage bar, the sweep's defaults note.
PROGRESS = re.compile(r"^step +\d+ |\d+/\d+ stages|their defaults are used|it/s|world/s|\|")


@pytest.fixture
def cli():
    """Run ``nbv-gym ARGS`` in this process through the CLI's error boundary."""
    return invoke


def one_line(result: Result, code: int = 2) -> str:
    """The one message line of a refused command (after checking its exit code)."""
    assert result.code == code, (result.code, result.err[-2000:])
    assert "Traceback" not in result.err
    lines = [
        part
        for line in result.err.splitlines()
        for part in line.split("\r")
        if part.strip() and not PROGRESS.search(part)
    ]
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.err
    return lines[0]


def hashes(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` by relative path."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def tree(folder: Path) -> list[str]:
    """Every path under ``folder``, files and folders."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.fixture(scope="module")
def home(tmp_path_factory) -> Path:
    """A folder with tiny.toml and my_policy.py (the README's example)."""
    home = tmp_path_factory.mktemp("home")
    (home / "tiny.toml").write_text(TINY)
    (home / "my_policy.py").write_text(textwrap.dedent(MY_POLICY))
    return home


@pytest.fixture
def here(home, tmp_path, monkeypatch) -> Path:
    """A fresh working folder holding copies of tiny.toml and my_policy.py."""
    for name in ("tiny.toml", "my_policy.py"):
        shutil.copy(home / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture(scope="module")
def finished_run(home) -> Path:
    """A finished run folder (`nbv-gym run` of the README's policy, 2 steps, from ``home``)."""
    previous = os.getcwd()
    os.chdir(home)
    try:
        code = invoke("run", "--world", "tiny.toml", "--policy", "my_policy:Nearest",
                      "--noise", "0", "--max-steps", "2", "--no-animation", "--out", "run").code  # fmt: skip
    finally:
        os.chdir(previous)
    assert code == 0
    return home / "run"


SWEEP = """
worlds = ["tiny.toml"]
policies = [{policies}]
noise = [0]
repeats = 1
max_steps = 2
retries = 0
run_timeout_s = 300.0
"""


@pytest.fixture(scope="module")
def finished_sweep(home) -> Path:
    """A finished sweep of closest-frontier and the README's my_policy:Nearest (run from
    ``home``, which holds my_policy.py: the current folder, as in the README)."""
    (home / "sweep.toml").write_text(
        SWEEP.format(policies='"closest-frontier", "my_policy:Nearest"')
    )
    previous = os.getcwd()
    os.chdir(home)
    try:
        code = invoke("sweep", "sweep.toml", "--out", "results", "--workers", "1",
                      "--no-report", "--no-progress").code  # fmt: skip
    finally:
        os.chdir(previous)
    assert code == 0
    return home / "results"


def copy_of(folder: Path, where: Path) -> Path:
    target = where / folder.name
    shutil.copytree(folder, target)
    return target


# -- 1. Data lost ---------------------------------------------------------------------------------


def test_run_without_force_keeps_a_finished_run(cli, here, finished_run):
    run = copy_of(finished_run, here)
    before = hashes(run)
    line = one_line(cli("run", "--world", "tiny.toml", "--out", run, "--no-animation"))
    assert f"--out {run} holds an earlier run" in line and "--force" in line
    assert hashes(run) == before


@pytest.mark.parametrize(
    ("policy", "message"),
    [
        ("my_policy:Crashing", None),
        ("my_policy:Exiting", "called sys.exit(0) during its episode"),
    ],
    ids=["crashing-policy", "exiting-policy"],
)
def test_a_failed_rerun_with_force_leaves_the_earlier_run_intact(
    cli, here, finished_run, policy, message
):
    run = copy_of(finished_run, here)
    before = hashes(run)
    args = ("run", "--world", "tiny.toml", "--noise", "0", "--max-steps", "2", "--no-animation")
    if message is None:
        with pytest.raises(RuntimeError, match="this policy crashes"):
            cli(*args, "--policy", policy, "--out", run, "--force")
    else:
        assert message in one_line(cli(*args, "--policy", policy, "--out", run, "--force"))
    assert hashes(run) == before
    assert sorted(p.name for p in here.iterdir() if "partial" in p.name) == []


def test_run_out_on_a_sweep_folder_is_refused_and_the_sweep_unchanged(cli, here, finished_sweep):
    sweep = copy_of(finished_sweep, here)
    before = hashes(sweep)
    line = one_line(cli("run", "--world", "tiny.toml", "--out", sweep, "--force"))
    assert f"--out {sweep} is the folder of `nbv-gym sweep`" in line
    assert hashes(sweep) == before
    assert cli("report", sweep).code == 0  # the sweep's report still builds


def test_sweep_out_on_a_run_folder_is_refused_and_the_run_unchanged(cli, here, finished_run):
    run = copy_of(finished_run, here)
    before = hashes(run)
    (here / "s.toml").write_text(SWEEP.format(policies='"closest-frontier"'))
    line = one_line(cli("sweep", "s.toml", "--out", run))
    assert f"--out {run} is the folder of `nbv-gym run`" in line
    assert hashes(run) == before


def test_evaluate_out_on_a_run_folder_is_refused(cli, here, finished_run):
    run = copy_of(finished_run, here)
    before = hashes(run)
    line = one_line(cli("evaluate", "--map", run / "map.npz", "--world", "tiny.toml", "--out", run))
    assert "is the folder of `nbv-gym run`; `nbv-gym evaluate` would overwrite" in line
    assert hashes(run) == before


# -- 2. Names that become paths -------------------------------------------------------------------

BAD_NAMES = {
    "dotdot": "../../../elsewhere/x",
    "slash": "a/b",
    "backslash": "a\\\\b",
    "nul": "a\\u0000b",
    "empty": "",
    "dot": "..",
}


@pytest.mark.parametrize("name", BAD_NAMES.values(), ids=BAD_NAMES.keys())
def test_a_world_whose_name_is_not_a_safe_name_builds_nothing(cli, tmp_path, monkeypatch, name):
    root = tmp_path / "a" / "b" / "c"
    (root / "work").mkdir(parents=True)
    monkeypatch.setenv("NBV_GYM_CACHE", str(root / "cache"))
    monkeypatch.chdir(root / "work")
    (root / "work" / "bad.toml").write_text(TINY.replace('name = "tiny"', f'name = "{name}"'))
    before = tree(tmp_path)
    for args in (("worlds", "build", "bad.toml"), ("worlds", "build", "bad.toml", "--force")):
        line = one_line(cli(*args))
        assert "name" in line
    assert tree(tmp_path) == before


def test_a_safe_world_name_builds_only_inside_the_cache(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("NBV_GYM_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ok.toml").write_text(TINY.replace('name = "tiny"', 'name = "tiny_ok.v2"'))
    before = set(tree(tmp_path))
    assert cli("worlds", "build", "ok.toml").code == 0
    new = set(tree(tmp_path)) - before
    assert new and all(path.startswith("cache") for path in new), new


def test_a_world_spec_built_in_code_is_checked_too():
    from dataclasses import replace

    from nbv_gym.core.errors import ConfigError
    from nbv_gym.worlds import parse_spec

    spec = parse_spec(TINY, "tiny")
    with pytest.raises(ConfigError, match=r"name: '\.\./x' is not a valid name"):
        replace(spec, name="../x")


def test_a_sweep_name_that_is_a_path_is_refused(cli, here):
    (here / "s.toml").write_text('name = "../../x"\n' + SWEEP.format(policies='"closest-frontier"'))
    assert "name: '../../x' is not a valid name" in one_line(cli("sweep", "s.toml"))
    assert not (here / "results").exists()


@pytest.mark.parametrize("dataset_id", ["../../x/y-v0", "a/../../b-v0", "/abs/x-v0", "a//b-v0"])
def test_a_dataset_id_that_is_a_path_is_refused(cli, here, dataset_id):
    before = tree(here.parent)
    line = one_line(cli("record", "--policy", "closest-frontier", "--world", "tiny.toml",
                        "--out", "data", "--dataset-id", dataset_id))  # fmt: skip
    assert f"--dataset-id {dataset_id!r}" in line
    assert tree(here.parent) == before


# -- 3. Unbounded work before the first message ---------------------------------------------------


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("n_assets = 4", "n_assets = 10000000"), "n_assets: must be from 2 to 1000"),
        (
            ("mix =", "tree_library_size = 100000\nmix ="),
            "tree_library_size: must be from 1 to 100",
        ),
    ],
    ids=["n_assets", "tree_library"],
)
def test_world_sizes_are_bounded(cli, here, edit, message):
    (here / "big.toml").write_text(TINY.replace(*edit))
    assert message in one_line(cli("worlds", "build", "big.toml"))


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ("repeats = 1000000000", "more than 100,000; split it into several sweeps"),
        ("max_steps = 100000000", "max_steps: must be from 1 to 10,000"),
    ],
    ids=["repeats", "max_steps"],
)
def test_sweep_sizes_are_bounded(cli, here, extra, message):
    text = SWEEP.format(policies='"closest-frontier"')
    key = extra.split(" =")[0]
    text = "\n".join(line for line in text.splitlines() if not line.startswith(key))
    (here / "s.toml").write_text(text + "\n" + extra + "\n")
    assert message in one_line(cli("sweep", "s.toml", "--out", "o"))
    assert not (here / "o").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policy", "nope"], "Unknown policy 'nope'"),
        (["--runs", "EMPTY"], "EMPTY holds no run folder"),
        (["--runs", "tiny.toml"], "tiny.toml is a file; --runs takes a folder"),
        (["--worlds", "nope"], "Unknown world 'nope'"),
    ],
    ids=["policy", "empty-runs", "runs-is-a-file", "world"],
)
def test_study_wd_checks_its_arguments_before_any_work(cli, here, args, message):
    (here / "EMPTY").mkdir()
    assert message in one_line(cli("study", "wd", "--out", "study", *args))
    assert not (here / "study").exists()


# -- 4. Unusable outputs ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["report", "SWEEP", "--out", "FILE"], "--out FILE is a file; give a folder."),
        (["report", "SWEEP", "--out", "FILE/sub"], "(Not a directory: FILE is a file)"),
        (["view", "RUN", "--out", "DIR.html"], "--out DIR.html is a folder; give a file name."),
        (["view", "RUN", "--out", "FILE/v.html"], "--out FILE/v.html: cannot create the folder"),
        (["export", "RUN/map.npz", "--out", "DIR.ply"], "--out DIR.ply is a folder"),
        (["export", "RUN/map.npz", "--out", "FILE/x.ply"], "(Not a directory: FILE is a file)"),
        (["worlds", "preview", "tiny.toml", "--out", "DIR.html"], "is a folder; give a file"),
        (["study", "wd", "--out", "FILE", "--runs", "RUN"], "--out FILE is a file; give a folder"),
        (
            ["evaluate", "--map", "RUN/map.npz", "--world", "tiny.toml", "--out", "FILE"],
            "is a file",
        ),
        (["run", "--out", "FILE/run"], "cannot create the folder (Not a directory: FILE"),
        (
            ["record", "--policy", "closest-frontier", "--world", "tiny.toml", "--out", "FILE"],
            "--out FILE is a file",
        ),
    ],
    ids=lambda v: " ".join(v)[:32] if isinstance(v, list) else None,
)
def test_unusable_outputs_are_refused(cli, here, finished_run, finished_sweep, args, message):
    copy_of(finished_run, here).rename(here / "RUN")
    copy_of(finished_sweep, here).rename(here / "SWEEP")
    (here / "FILE").write_text("a file")
    (here / "DIR.html").mkdir()
    (here / "DIR.ply").mkdir()
    before = hashes(here)
    assert message in one_line(cli(*args))
    assert hashes(here) == before


def test_a_full_disk_is_one_line_naming_the_file(cli, here, finished_run):
    full = here / "full.ply"
    full.symlink_to("/dev/full")
    line = one_line(cli("export", finished_run / "map.npz", "--out", full))
    assert f"writing {full}: no space left on the device" in line


@pytest.mark.parametrize(
    ("errno_name", "message"),
    [("ENOSPC", "no space left"), ("EACCES", "permission denied"), ("EISDIR", "it is a folder")],
)
def test_a_write_failing_during_run_is_one_line_and_loses_nothing(
    cli, here, finished_run, monkeypatch, errno_name, message
):
    import errno

    import nbv_gym.episode

    run = copy_of(finished_run, here)
    before = hashes(run)

    def fail(out, *args):
        raise OSError(getattr(errno, errno_name), os.strerror(getattr(errno, errno_name)),
                      str(out / "map.npz"))  # fmt: skip

    monkeypatch.setattr(nbv_gym.episode, "write_run_folder", fail)
    line = one_line(cli("run", "--world", "tiny.toml", "--noise", "0", "--max-steps", "1",
                        "--no-animation", "--out", run, "--force"))  # fmt: skip
    assert "map.npz" in line and message in line
    assert hashes(run) == before


# -- 5. Numbers outside their domain --------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["view", "RUN", "--max-points", "-5"], "'--max-points': expected an integer ≥ 1, got -5"),
        (["view", "RUN", "--min-z", "nan"], "'--min-z': expected a finite number, got nan"),
        (["view", "RUN", "--min-p", "1.5"], "'--min-p': expected a finite number ≥ 0 and ≤ 1"),
        (
            ["evaluate", "a.ply", "b.ply", "--region", "inf"],
            "'--region': expected a finite number > 0",
        ),
        (["evaluate", "a.ply", "b.ply", "--region", "0.05"], "region_m: must be ≥ epsilon_m"),
        (
            ["train", "--config", "x.toml", "--seed", "-1"],
            "'--seed': expected an integer ≥ 0, got -1",
        ),
        (["record", "--policy", "p", "--world", "w", "--out", "o", "--seed", "-1"], "'--seed'"),
        (["run", "--max-steps", "0"], "'--max-steps': expected an integer ≥ 1, got 0"),
        (["run", "--noise", "3"], "'--noise': expected an integer ≥ 0 and ≤ 2, got 3"),
        (["study", "wd", "--resolution", "nan"], "'--resolution': expected a finite number > 0"),
        (["study", "empir3d", "--epsilon", "-0.1"], "'--epsilon': expected a finite number > 0"),
        (["export", "RUN/map.npz", "--min-p", "nan"], "'--min-p': expected a finite number"),
        (["train", "--config", "x.toml", "--time-limit", "inf"], "'--time-limit'"),
    ],
    ids=lambda v: " ".join(v)[:36] if isinstance(v, list) else None,
)
def test_numbers_outside_their_domain_are_refused(cli, here, args, message):
    (here / "RUN").mkdir()
    line = one_line(cli(*args))
    assert message in line
    assert sorted(p.name for p in here.iterdir()) == ["RUN", "my_policy.py", "tiny.toml"]


# -- 6. Files that lie ----------------------------------------------------------------------------


def _clouds(folder: Path) -> None:
    from nbv_gym.core.pointclouds import write_points

    points = np.random.default_rng(0).random((10, 3))
    ply = write_points(folder / "a.ply", points).read_bytes()
    pcd = write_points(folder / "a.pcd", points).read_bytes()
    (folder / "fewer.ply").write_bytes(ply.replace(b"element vertex 10", b"element vertex 5"))
    (folder / "negative.ply").write_bytes(ply.replace(b"element vertex 10", b"element vertex -5"))
    (folder / "fewer.pcd").write_bytes(
        pcd.replace(b"POINTS 10", b"POINTS 5").replace(b"WIDTH 10", b"WIDTH 5")
    )
    (folder / "count0.pcd").write_bytes(pcd.replace(b"COUNT 1 1 1", b"COUNT 0 1 1"))
    (folder / "width.pcd").write_bytes(pcd.replace(b"WIDTH 10", b"WIDTH 7"))
    np.save(folder / "m.npy", np.zeros((5, 3)))
    npy = (folder / "m.npy").read_bytes()
    (folder / "negative.npy").write_bytes(npy.replace(b"(5, 3)", b"(-5, 3)"))
    (folder / "longer.npy").write_bytes(npy + bytes(48))
    text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
    text += "property float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n"
    (folder / "fewer-ascii.ply").write_text(text)


@pytest.mark.parametrize(
    ("candidate", "message"),
    [
        ("fewer.ply", "the header declares a body of 5 vertices (120 bytes)"),
        ("negative.ply", "the count of element 'vertex' is '-5'; expected an integer ≥ 0"),
        ("fewer-ascii.ply", "the header declares 2 element lines"),
        ("fewer.pcd", "the header declares a body of 5 points (120 bytes)"),
        ("count0.pcd", "COUNT 0 declares a field without values"),
        ("width.pcd", "POINTS 10 differs from WIDTH · HEIGHT = 7 · 1"),
        ("negative.npy", "the length of axis 0 is -5; expected an integer ≥ 0"),
        ("longer.npy", "the file holds 168 bytes after it"),
    ],
    ids=lambda v: v if v.endswith(("ply", "pcd", "npy")) else None,
)
def test_point_cloud_headers_that_lie_are_refused(cli, here, candidate, message):
    _clouds(here)
    line = one_line(cli("evaluate", "a.ply", candidate))
    assert line.startswith(f"Error: {candidate}: ") and message in line


def test_a_negative_shape_as_a_map_is_refused(cli, here):
    _clouds(here)
    line = one_line(cli("evaluate", "--map", "negative.npy", "--world", "tiny.toml"))
    assert "negative.npy: the length of axis 0 is -5" in line


def test_a_studys_map_declaring_a_huge_array_is_refused_before_allocating(here, finished_run):
    import zipfile

    from nbv_gym.core.errors import DataFileError
    from nbv_gym.studies.runs import RunFolder, run_map

    run = copy_of(finished_run, here)
    with zipfile.ZipFile(finished_run / "map.npz") as source:
        members = {info.filename: source.read(info) for info in source.infolist()}
    header = np.lib.format.header_data_from_array_1_0(np.zeros(3))
    header["shape"] = (4_000_000_000,)  # 32 GB declared, 3 values held
    with zipfile.ZipFile(run / "map.npz", "w") as archive:
        for name, data in members.items():
            if name != "origin.npy":
                archive.writestr(name, data)
        with archive.open("origin.npy", "w") as f:
            np.lib.format.write_array_header_1_0(f, header)
            f.write(np.zeros(3).tobytes())
    with pytest.raises(DataFileError, match=r"origin.npy: truncated: a float64 array of shape"):
        run_map(RunFolder(run, "tiny", 0), 0.1)


# -- 7. Results that silently mix or mislead ------------------------------------------------------


def test_a_sweep_resumed_without_a_policy_keeps_only_what_its_config_lists(
    cli, here, finished_sweep
):
    import pandas as pd

    sweep = copy_of(finished_sweep, here)
    runs_before = hashes(sweep / "runs")
    assert set(pd.read_csv(sweep / "runs.csv")["policy"]) == {
        "closest-frontier",
        "my_policy:Nearest",
    }
    # the same sweep (its name: the folder's) with a policy dropped; another name is refused
    (here / "s.toml").write_text('name = "sweep"\n' + SWEEP.format(policies='"closest-frontier"'))
    result = cli("sweep", "s.toml", "--out", sweep, "--no-report", "--no-progress")
    assert result.code == 0, result.err
    assert "1 run(s)" in result.err and "sweep.toml no longer lists" in result.err
    assert set(pd.read_csv(sweep / "runs.csv")["policy"]) == {"closest-frontier"}
    assert set(pd.read_csv(sweep / "steps.csv")["policy"]) == {"closest-frontier"}
    assert hashes(sweep / "runs") == runs_before  # the dropped policy's files stay


def test_a_truncated_runs_csv_newer_than_the_runs_is_rebuilt(cli, here, finished_sweep):
    import pandas as pd

    sweep = copy_of(finished_sweep, here)
    full = (sweep / "runs.csv").read_text()
    (sweep / "runs.csv").write_text("\n".join(full.splitlines()[:2]) + "\n")  # 1 of 2 runs
    assert len(pd.read_csv(sweep / "runs.csv")) == 1
    assert cli("report", sweep).code == 0
    assert len(pd.read_csv(sweep / "runs.csv")) == 2


def test_evaluate_refuses_a_map_of_another_world(cli, here, finished_run):
    (here / "other.toml").write_text(TINY.replace("seed = 3", "seed = 4"))
    line = one_line(cli("evaluate", "--map", finished_run / "map.npz", "--world", "other.toml"))
    assert "is a map of world 'tiny@" in line and "not of 'other.toml'" in line


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["worlds", "build", "tiny.toml", "--all"], "name the worlds to build, or pass --all"),
        (["worlds", "build"], "name the worlds to build, or pass --all"),
        (["sweep", "s.toml", "--scheduler", ""], "--scheduler is empty"),
        (["sweep", "s.toml", "--scheduler", " "], "--scheduler is empty"),
    ],
    ids=["build-name-and-all", "build-nothing", "empty-scheduler", "blank-scheduler"],
)
def test_arguments_that_would_be_ignored_are_refused(cli, here, args, message):
    (here / "s.toml").write_text(SWEEP.format(policies='"closest-frontier"'))
    assert message in one_line(cli(*args))


def test_train_refuses_a_batch_larger_than_a_rollout(cli, here):
    (here / "t.toml").write_text("n_envs = 1\n[learning]\nn_steps = 16\nbatch_size = 64\n")
    line = one_line(cli("train", "--config", "t.toml", "--out", "t"))
    assert "learning.batch_size: must be ≤ n_steps · n_envs = 16 · 1 = 16" in line


# -- 8. The env's keywords ------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("keywords", "message"),
    [
        ({"noise": True}, "simulator.noise: expected an integer, got True"),
        ({"noise": 1.0}, "simulator.noise: expected int, got float 1.0"),
        ({"max_steps": 2.5}, "simulator.episode.max_steps: expected int, got float 2.5"),
        ({"world_pool_size": 2.5}, "world_pool_size: expected int, got float 2.5"),
        ({"episodes_per_world": "2"}, "episodes_per_world: expected int, got str"),
        ({"observation_layers": "gain_nobs"}, "got the string 'gain_nobs'; write ('gain_nobs',)"),
        ({"invalid_action": 3}, "invalid_action"),
    ],
    ids=lambda v: next(iter(v)) if isinstance(v, dict) else None,
)
def test_env_keywords_go_through_the_configs_checks(here, keywords, message):
    import gymnasium

    from nbv_gym import ENV_ID
    from nbv_gym.core.errors import ConfigError

    with pytest.raises(ConfigError, match=re.escape(message)):
        gymnasium.make(ENV_ID, world="tiny.toml", **keywords)


def test_env_keywords_of_the_right_type_apply_and_unknown_reset_options_are_refused(here):
    import gymnasium

    from nbv_gym import ENV_ID
    from nbv_gym.core.errors import ConfigError

    env = gymnasium.make(ENV_ID, world="tiny.toml", noise=0, max_steps=3)
    config = env.unwrapped.config
    assert (config.simulator.noise, config.simulator.episode.max_steps) == (0, 3)
    with pytest.raises(
        ConfigError, match=r"reset\(options=...\): unknown option\(s\) \['seed_x'\]"
    ):
        env.reset(seed=0, options={"seed_x": 1})
    _, info = env.reset(seed=0, options={})
    assert info["steps"] == 0


# -- 9. Unclear messages --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["sweep", "DIR"], "'DIR' is a folder, not a file."),
        (["train", "--config", "DIR"], "'DIR' is a folder, not a file."),
        (["evaluate", "--map", "DIR", "--world", "tiny.toml"], "DIR: the map file is a folder"),
        (["evaluate", "DIR", "a.ply"], "DIR: the point-cloud file is a folder, not a file"),
        (["run", "--world", "DIR.toml"], "World spec file 'DIR.toml' is a folder, not a file."),
        (["sweep", "s.toml", "--scheduler", "tcp://localhost:99999"], "a port from 1 to 65535"),
        (["sweep", "s.toml", "--scheduler", "inproc://x"], "unsupported address scheme 'inproc'"),
        (["sweep", "random.toml"], "'random:cuboids' is a world distribution; a sweep runs fixed"),
    ],
    ids=lambda v: " ".join(v)[:36] if isinstance(v, list) else None,
)
def test_messages_say_what_is_wrong(cli, here, args, message):
    (here / "DIR").mkdir()
    (here / "DIR.toml").mkdir()
    (here / "a.ply").write_text("ply\n")
    (here / "s.toml").write_text(SWEEP.format(policies='"closest-frontier"'))
    text = SWEEP.format(policies='"closest-frontier"').replace('"tiny.toml"', '"random:cuboids"')
    (here / "random.toml").write_text(text)
    assert message in one_line(cli(*args))


def test_ctrl_c_in_a_policy_says_so_and_exits_130(cli, here):
    result = cli("run", "--world", "tiny.toml", "--policy", "my_policy:CtrlC", "--noise", "0",
                 "--max-steps", "2", "--no-animation", "--out", "r")  # fmt: skip
    assert "interrupted (Ctrl-C)" in one_line(result, code=130)
    assert not (here / "r" / "summary.json").exists()


def test_the_readme_policy_in_the_current_folder_runs(cli, here, finished_run):
    summary = json.loads((finished_run / "summary.json").read_text())
    assert summary["policy"] == "my_policy:Nearest" and summary["n_steps"] == 2


def test_the_readme_policy_in_the_current_folder_sweeps(finished_sweep):
    import pandas as pd

    runs = pd.read_csv(finished_sweep / "runs.csv")
    assert sorted(runs["policy"]) == ["closest-frontier", "my_policy:Nearest"]
    assert set(runs["status"]) == {"ok"}


@pytest.mark.parametrize("group", [[], ["worlds"], ["study"]], ids=["nbv-gym", "worlds", "study"])
def test_a_command_group_without_a_command_prints_its_help(cli, group):
    result = cli(*group)
    assert "Usage: nbv-gym" in result.out + result.err and "Error" not in result.err


# -- class 7 (third round): folders that mix or mislead ---------------------------------------------


@pytest.mark.parametrize("folder", ["finished_run", "finished_sweep"])
def test_score_out_on_another_commands_folder_is_refused(cli, here, request, folder):
    target = copy_of(request.getfixturevalue(folder), here)
    before = hashes(target)
    line = one_line(cli("score", "closest-frontier", "--suite", "quick", "--out", target))
    assert f"--out {target} is the folder of `nbv-gym " in line and "`nbv-gym score`" in line
    assert hashes(target) == before


@pytest.mark.parametrize("folder", ["finished_run", "finished_sweep"])
def test_leaderboard_out_on_another_commands_folder_is_refused(cli, here, request, folder):
    from nbv_gym.benchmark.references import reference_path

    target = copy_of(request.getfixturevalue(folder), here)
    before = hashes(target)
    line = one_line(cli("leaderboard", reference_path("closest-frontier"), "--out", target))
    assert "is the folder of `nbv-gym " in line and hashes(target) == before


def test_run_out_on_a_score_folder_is_refused(cli, here):
    (here / "scores").mkdir()
    (here / "scores" / "scorecard.json").write_text("{}")
    line = one_line(cli("run", "--world", "tiny.toml", "--max-steps", "2", "--no-animation",
                        "--out", here / "scores"))  # fmt: skip
    assert "is the folder of `nbv-gym score`" in line


def test_sweep_into_another_sweeps_folder_is_refused_and_it_is_unchanged(cli, here, finished_sweep):
    target = copy_of(finished_sweep, here)
    before = hashes(target)
    (here / "other.toml").write_text(
        'name = "other"\n' + SWEEP.format(policies='"random-frontier"')
    )
    line = one_line(cli("sweep", "other.toml", "--out", target, "--workers", "1", "--no-report",
                        "--no-progress"))  # fmt: skip
    assert "holds the results of sweep 'sweep'; this is sweep 'other'" in line
    assert hashes(target) == before


def test_report_on_a_sweep_missing_runs_says_so_and_reproduces_nothing(cli, here, finished_sweep):
    target = copy_of(finished_sweep, here)
    for run in sorted((target / "runs").glob("*closest-frontier*"))[:2]:
        run.unlink()  # one run: its record and its cuboid table
    result = cli("report", target, "--out", here / "report")
    assert result.code == 0, result.err
    text = (here / "report" / "report.md").read_text()
    assert "Incomplete sweep: 1 of its 2 runs are missing" in text
    assert "1 finished runs, 0 failed, 1 missing of the 2 its sweep.toml lists" in text
    assert "reproduced" not in text.split("## Reproduction verdict")[-1].split("\n\n", 2)[-1]
    assert "lacks 1 of its 2 runs" in result.err


# -- class 9 (third round): tracebacks and unclear messages ----------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "--policy", "closest-frontier@x"], "closest-frontier has no variant after '@'"),
        (["run", "--policy", "random-free@2"], "the policies that do: ig-entropy, ig-unknown, nbv"),
        (["run", "--policy", "ig-unknown@1e308"], "lam: expected a number from 0 to 100"),
        (["run", "--policy", "ig-unknown@-1"], "lam: expected a number from 0 to 100"),
        (
            ["record", "--policy", "closest-frontier", "--dataset-id", "nbv/tiny"],
            "'nbv/tiny' has no version; Minari ids end in",
        ),
        (["export", "MAP", "--format", "bt", "--min-p", "0.7"], "--min-p applies to ply and pcd"),
    ],
)
def test_third_round_messages_say_what_is_wrong(cli, here, finished_run, args, message):
    args = [str(finished_run / "map.npz") if a == "MAP" else a for a in args]
    if args[0] in ("run", "record"):
        args += ["--world", "tiny.toml", "--max-steps", "1", "--out", here / "out"]
    if args[0] == "run":
        args.append("--no-animation")
    line = one_line(cli(*args))
    assert message in line, line
    assert not (here / "out").exists() or not any((here / "out").iterdir())


@pytest.mark.parametrize("options", ["world", ["world"], 3])
def test_reset_options_that_are_not_a_dict_are_named_as_such(here, options):
    import gymnasium

    from nbv_gym.core.errors import ConfigError

    env = gymnasium.make("nbv_gym/Explore-v0", world="tiny.toml", max_steps=1)
    with pytest.raises(ConfigError, match=f"expected a dict or None, got {type(options).__name__}"):
        env.reset(options=options)
    env.close()


def test_sigterm_during_run_force_leaves_the_earlier_run_and_no_partial_folder(here, finished_run):
    import signal
    import subprocess
    import sys
    import time

    target = copy_of(finished_run, here)
    before = hashes(target)
    (here / "slow.py").write_text(
        "import time\nfrom my_policy import Nearest\n\n\nclass Slow(Nearest):\n"
        "    def act(self, observation, info):\n        time.sleep(60)\n"
    )
    process = subprocess.Popen(
        [sys.executable, "-m", "nbv_gym", "run", "--world", "tiny.toml", "--policy", "slow:Slow",
         "--max-steps", "3", "--no-animation", "--out", str(target), "--force"],
        cwd=here, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    deadline = time.monotonic() + 300
    while not list(here.glob(f".{target.name}.partial-*")) and time.monotonic() < deadline:
        time.sleep(0.2)
    time.sleep(1.0)  # inside the episode
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130 and "Traceback" not in err, err
    assert hashes(target) == before
    assert not list(here.glob(f".{target.name}.partial-*"))


# -- A fourth round (re-probe of issue #39's classes) ---------------------------------------------


@pytest.mark.parametrize(
    ("name", "text", "args"),
    [
        ("scorecard.json", "[" * 100_000 + "]" * 100_000, ["leaderboard", "FILE", "--out", "b"]),
        ("sweep.toml", "a = " + "[" * 100_000 + "]" * 100_000, ["sweep", "FILE", "--out", "s"]),
    ],
    ids=["json", "toml"],
)
def test_a_file_nested_too_deep_for_the_parser_is_one_line(cli, here, name, text, args):
    (here / name).write_text(text)
    line = one_line(cli(*[name if a == "FILE" else a for a in args]))
    assert "nests arrays or tables deeper than the parser reads" in line, line


@pytest.mark.parametrize(
    "args",
    [
        ["train", "--config", "FIFO.toml"],
        ["run", "--world", "tiny.toml", "--policy", "sb3:FIFO.zip"],
    ],
    ids=["config", "model"],
)
def test_a_fifo_given_as_a_file_is_named_a_fifo_not_missing(cli, here, args):
    if args[-1].startswith("sb3:"):
        pytest.importorskip("sb3_contrib")  # without the rl extra, the missing torch is said first
    for suffix in (".toml", ".zip"):
        os.mkfifo(here / f"FIFO{suffix}")
    line = one_line(cli(*args, "--out", here / "out"))
    assert "is not a regular file (a FIFO)" in line and "does not exist" not in line, line


def test_writing_into_the_observation_changes_nothing_the_env_records(here):
    import gymnasium

    def predicted_after_a_step(write: bool) -> float:
        env = gymnasium.make("nbv_gym/Explore-v0", world="tiny.toml", noise=0, max_steps=3,
                             observation_layers=["gain_nobs"])  # fmt: skip
        observation, info = env.reset(seed=0)
        if write:  # a policy scribbling on the layer it is handed
            observation["gain_nobs"][:] = 12345.0
        _, _, _, _, info = env.step(int(np.flatnonzero(info["action_mask"])[0]))
        env.close()
        return info["predicted_gain"]["gain_nobs"]

    assert predicted_after_a_step(write=True) == predicted_after_a_step(write=False) != 12345.0


def test_an_unreadable_numba_kernel_cache_is_one_line_naming_it(cli, here, monkeypatch):
    import pickle

    def truncated_cache(*args, **kwargs):  # numba's cache reader meeting a truncated .nbc file
        where = compile("raise pickle.UnpicklingError('pickle data was truncated')",
                        "/venv/site-packages/numba/core/caching.py", "exec")  # fmt: skip
        exec(where, {"pickle": pickle})

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(here / "kernels"))
    monkeypatch.setattr("nbv_gym.episode.ExploreEnv", truncated_cache)
    line = one_line(cli("run", "--world", "tiny.toml", "--policy", "closest-frontier",
                        "--max-steps", "1", "--no-animation", "--out", here / "out"))  # fmt: skip
    assert "numba's cache of compiled kernels is unreadable (UnpicklingError" in line, line
    assert f"in {here / 'kernels'}; delete its *.nbi and *.nbc files" in line, line


# -- A fifth round (issue #47): scene ground truth, evaluate on scenes, bounds -------------------

#: Three boxes (3 × 3 × 4, 3 × 3 × 4 and 2 × 2 × 2 m) with every face on the half metre: the
#: voxels worked out alone, (a + 1)(b + 1)(h + 1) − (a − 1)(b − 1) h voxels a box of a × b × h.
HALF_METRE_BOXES = [
    (-7.5, -4.5, -1.5, 1.5, 4.0),
    (4.5, 7.5, -1.5, 1.5, 4.0),
    (-1.0, 1.0, 7.0, 9.0, 2.0),
]
HALF_METRE_VOXELS = 2 * (31 * 31 * 41 - 29 * 29 * 40) + (21 * 21 * 21 - 19 * 19 * 20)


def _box_ply(path: Path, shift=(0.0, 0.0, 0.0), kind="double", unused: str = "") -> None:
    """The half-metre boxes moved by ``shift`` as an ASCII PLY of ``kind`` coordinates, with
    the ``unused`` vertex line (if any) that no face uses."""
    vertices, faces = [], []
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    for x0, x1, y0, y1, h in HALF_METRE_BOXES:
        n = len(vertices)
        vertices += [f"{x + shift[0]!r} {y + shift[1]!r} {z + shift[2]!r}"
                     for x in (x0, x1) for y in (y0, y1) for z in (0.0, h)]  # fmt: skip
        faces += [f"3 {n + q[0]} {n + q[k]} {n + q[k + 1]}" for q in quads for k in (1, 2)]
    vertices += [unused] if unused else []
    header = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}"]
    header += [f"property {kind} {axis}" for axis in "xyz"]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    path.write_text("\n".join([*header, "end_header", *vertices, *faces]) + "\n")


@pytest.mark.parametrize(
    ("shift", "kind", "unused"),
    [
        ((0.0, 0.0, 0.0), "double", ""),  # S01/S07: every face on the lattice gave 0 voxels
        ((0.05, 0.05, 0.03), "double", ""),  # S15: 11,561 (floors and roofs by the last bit)
        ((500_000.0, 5_000_000.0, 200.03), "double", ""),  # S16: 11,200 at UTM coordinates
        ((0.05, 0.05, 0.03), "float", ""),  # S15: 13,483 from float32
        ((0.0, 0.0, 0.0), "double", "1000000.0 1000000.0 0.0"),  # S14: asked 3.64 TiB
        ((0.0, 0.0, 0.0), "double", "nan nan 0.0"),  # S13: "no free ground … up axis"
    ],
    ids=["half-metre", "lifted", "utm", "float32", "unused-far", "unused-nan"],
)
def test_boxes_on_the_lattice_import_with_their_voxels_however_written(
    cli, here, shift, kind, unused
):
    _box_ply(here / "boxes.ply", shift, kind, unused)
    result = cli("worlds", "import", "boxes.ply", "--out", "boxes.toml")
    assert result.code == 0, result.err
    # moved by 5 cm, the walls lie inside the voxel layers a face on the lattice occupies
    assert f"{HALF_METRE_VOXELS:,} ground-truth voxels → boxes.toml" in result.out, result.out


def test_a_world_without_ground_truth_where_q_is_scored_is_refused_in_one_line(cli, here):
    """S10/X01: a flat mesh (0 voxels) and a slab 0.1 m thick (voxels below G's 0.2 m only) ran
    with Q nan and made a scorecard its own leaderboard refused."""
    (here / "flat.obj").write_text("v 0 0 1\nv 10 0 1\nv 10 10 1\nv 0 10 1\nf 1 2 3\nf 1 3 4\n")
    line = one_line(cli("worlds", "import", "flat.obj", "--out", "flat.toml"))
    assert "flat.obj: the scene has no ground truth" in line and not (here / "flat.toml").exists()
    slab = "".join(
        f"v {x} {y} {z}\n" for z in (0, 0.1) for x, y in ((0, 0), (9, 0), (9, 9), (0, 9))
    )
    slab += "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\n"
    (here / "slab.obj").write_text(slab + "f 3 8 7\nf 4 1 5\nf 4 5 8\n")
    (here / "slab.toml").write_text(
        'name = "slab"\n[scene]\nfile = "slab.obj"\nclear_radius_m = 1.0\n'
    )
    for args in (["run", "--world", "slab.toml", "--no-animation", "--out", "r"],
                 ["score", "closest-frontier", "--suite", "quick", "--world", "slab.toml", "--out", "s"]):  # fmt: skip
        line = one_line(cli(*args))
        assert "world slab has no ground-truth voxel in the box where map quality is scored" in line
    assert not (here / "s").exists()


def test_evaluate_refuses_a_grid_beyond_its_bound_in_one_line(cli, here):
    """V09: a map and a scan 10 km apart asked 373 GiB."""
    header = "ply\nformat ascii 1.0\nelement vertex 2\n" + "".join(
        f"property float {a}\n" for a in ("x", "y", "z", "probability")
    )
    (here / "far.ply").write_text(
        header + "end_header\n0.05 0.05 0.25 0.9\n10000.05 10000.05 0.25 0.9\n"
    )
    (here / "far.xyz").write_text("0.05 0.05 0.25\n10000.05 10000.05 0.25\n")
    line = one_line(cli("evaluate", "--map", "far.ply", "--ground-truth", "far.xyz"))
    assert "the grid to score is 100010 × 100010 × 10 voxels" in line and "MAX_GRID_VOXELS" in line


def test_a_beam_pattern_without_bound_is_refused_in_one_line(cli, here):
    """L07: 200,000 × 200,000 beams failed with a 298 GiB MemoryError in every run."""
    (here / "beams.toml").write_text(SWEEP.format(policies='"closest-frontier"')
                                     + "[env.simulator.lidar]\nn_channels = 200000\nn_azimuth = 200000\n")  # fmt: skip
    line = one_line(cli("sweep", "beams.toml", "--out", "b", "--workers", "1"))
    assert "env.simulator.lidar: n_channels: n_channels × n_azimuth" in line and "MAX_RAYS" in line
