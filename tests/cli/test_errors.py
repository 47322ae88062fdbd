"""Bad input on the command line: each gives one line on stderr, exit code 2, no traceback, and
leaves nothing half-written."""

from __future__ import annotations

import os
import re
import subprocess
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import run_cli

#: Lines besides the error: the sweep's note on defaults, evaluate's progress bar.
NOTE = re.compile(r"their defaults are used|\d+/\d+ stages \[")
AS_ROOT = os.geteuid() == 0  # root writes into read-only folders: those cases cannot fail


def one_line_error(result: subprocess.CompletedProcess) -> str:
    """The error line of a failed command, after checking that it is the only output line."""
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip() and not NOTE.search(line)]
    assert len(lines) == 1 and lines[0].startswith("Error: "), result.stderr
    return lines[0]


POLICIES = """
class RaisingConstructor:
    observation_layers = ()

    def __init__(self):
        raise RuntimeError("no model file")


class Fractional:
    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        import numpy as np

        return int(np.flatnonzero(info["action_mask"])[0]) + 0.9
"""


@pytest.fixture
def policies(tmp_path) -> Path:
    """A folder with policy modules: good_and_bad.py, broken_syntax.py, raising_import.py."""
    (tmp_path / "good_and_bad.py").write_text(textwrap.dedent(POLICIES))
    (tmp_path / "broken_syntax.py").write_text("class Policy(:\n    pass\n")
    (tmp_path / "raising_import.py").write_text("raise ImportError('a missing C library')\n")
    (tmp_path / "failing_import.py").write_text("1 / 0\n")
    return tmp_path


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "--seed", "-1"], "Invalid value for '--seed': expected an integer ≥ 0, got -1"),
        (["run", "--world", ""], "Error: The world name is empty;"),
        (["sweep", "CONFIG", "--workers", "0"], "'--workers': expected an integer ≥ 1, got 0"),
        (
            ["run", "--policy", "closest-fronteer"],
            "Did you mean 'closest-frontier'? Valid policies: closest-frontier,",
        ),
        (
            ["run", "--policy", "good_and_bad:RaisingConstructor"],
            "Policy 'good_and_bad:RaisingConstructor': its constructor raised RuntimeError: "
            "no model file",
        ),
        (
            ["run", "--policy", "broken_syntax:Policy"],
            "importing module 'broken_syntax' failed: SyntaxError: invalid syntax",
        ),
        (
            ["run", "--policy", "raising_import:Policy"],
            "cannot import module 'raising_import': a missing C library",
        ),
        (
            ["run", "--policy", "failing_import:Policy"],
            "importing module 'failing_import' failed: ZeroDivisionError: division by zero",
        ),
        (
            ["sweep", "CONFIG", "--scheduler", "garbage", "--out", "OUT"],
            "--scheduler 'garbage': unsupported address scheme",
        ),
        (["report", "FILE"], "FILE is a file; give the results folder of a sweep."),
        (["evaluate", "--map", "X.ply", "--world", "pp1-cuboids"], "not a .ply file"),
        (["evaluate", "--map", "EMPTY.npz", "--world", "pp1-cuboids"], "not a readable .npz file"),
        (["sweep", "CONFIG", "--out", "FILE"], "--out FILE is a file; give a folder"),
        (["run", "--out", "FILE"], "--out FILE is a file; give a folder."),
        (
            ["run", "--out", "FILE/run"],
            "cannot create the folder (Not a directory: FILE is a file)",
        ),
        (
            ["worlds", "preview", "pp1-cuboids", "--out", "FILE/x.png"],
            "(Not a directory: FILE is a file)",
        ),
    ],
    ids=lambda v: " ".join(v)[:40] if isinstance(v, list) else None,
)
def test_bad_input_gives_one_line_and_exit_code_2(tmp_path, policies, args, message):
    (tmp_path / "FILE").write_text("a file")
    (tmp_path / "EMPTY.npz").write_bytes(b"")
    (tmp_path / "X.ply").write_text("ply\n")
    (tmp_path / "CONFIG").write_text(
        'worlds = ["pp1-cuboids"]\npolicies = ["closest-frontier"]\nnoise = [0]\n'
        "repeats = 1\nseed = 0\nmax_steps = 2\nretries = 0\nrun_timeout_s = 60.0\n"
    )
    before = sorted(p.name for p in tmp_path.iterdir())
    line = one_line_error(run_cli(*args, cwd=tmp_path))
    assert message in line
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert (tmp_path / "FILE").read_text() == "a file"


@pytest.mark.skipif(AS_ROOT, reason="root can write into a read-only folder")
@pytest.mark.parametrize(
    "args",
    [["run", "--out", "RO/run"], ["worlds", "preview", "pp1-cuboids", "--out", "RO/x.png"]],
    ids=["run", "preview"],
)
def test_a_read_only_output_folder_is_refused_before_any_work(tmp_path, args):
    (tmp_path / "RO").mkdir(mode=0o555)
    line = one_line_error(run_cli(*args, cwd=tmp_path))
    assert "RO" in line and ("not writable" in line or "Permission denied" in line)


def test_sweep_prints_the_defaults_it_filled_in(tmp_path):
    (tmp_path / "c.toml").write_text('worlds = ["pp1-cuboids"]\npolicies = ["random-free"]\n')
    result = run_cli("sweep", "c.toml", "--scheduler", "x:y", cwd=tmp_path)
    assert result.returncode == 2
    note = "c.toml leaves out some keys; their defaults are used: noise = [0, 1, 2], repeats = 3"
    assert note in result.stderr and "run_timeout_s = 1800.0" in result.stderr


def test_a_policy_returning_a_fractional_goal_is_refused_naming_the_policy(tmp_path, policies):
    result = run_cli(
        "run", "--policy", "good_and_bad:Fractional", "--world", "pp1-cuboids",
        "--noise", "0", "--max-steps", "2", "--no-animation", "--out", "r", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 2 and "Traceback" not in result.stderr
    line = result.stderr.splitlines()[-1]  # after the progress line of the first scan
    assert (
        "Error: Policy good_and_bad:Fractional at step 1: A goal is an integer index in [0, 3600)"
        in line
    )
    assert "got float " in line and ".9." in line


def test_run_into_an_existing_run_folder_leaves_no_stale_file(tmp_path):
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "exploration.gif").write_bytes(b"GIF89a stale")
    (tmp_path / "r" / "notes.txt").write_text("mine")
    result = run_cli(
        "run", "--world", "pp1-cuboids", "--noise", "0", "--max-steps", "1", "--no-animation",
        "--out", "r", "--force", cwd=tmp_path,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert not (tmp_path / "r" / "exploration.gif").exists()
    assert (tmp_path / "r" / "notes.txt").read_text() == "mine"
    assert (tmp_path / "r" / "summary.json").exists()


def test_report_of_a_folder_of_run_outputs_is_refused(tmp_path):
    (tmp_path / "episode").mkdir()
    (tmp_path / "episode" / "summary.json").write_text("{}")
    line = one_line_error(run_cli("report", tmp_path))
    assert "holds no sweep results" in line and "folder of `nbv-gym run`" in line
    assert not (tmp_path / "report").exists()


@pytest.mark.parametrize(
    ("values", "message"),
    [(np.nan, "1 value(s) do not (e.g. nan)"), (7.0, "1 value(s) do not (e.g. 7.0)")],
    ids=["nan", "seven"],
)
def test_a_probability_grid_outside_0_1_is_refused(tmp_path, values, message):
    from types import SimpleNamespace

    from nbv_gym.metrics import MetricInputError
    from nbv_gym.metrics.evaluation import load_probability

    prob = np.full((4, 4, 2), 0.5, np.float32)
    prob[1, 2, 1] = values
    np.save(tmp_path / "p.npy", prob)
    with pytest.raises(MetricInputError, match=r"probabilities must lie in \[0, 1\]") as caught:
        load_probability(tmp_path / "p.npy", SimpleNamespace(shape=prob.shape))
    assert message in str(caught.value)
