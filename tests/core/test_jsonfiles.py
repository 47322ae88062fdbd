"""Every JSON nbv-gym writes is strict JSON: NaN and Infinity become null, which any parser reads
(Python's own json module would write the bare words NaN and Infinity, which are not JSON)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nbv_gym.core.jsonfiles import dumps_json


def strict_loads(text: str):
    """``json.loads`` that refuses NaN, Infinity and -Infinity, as JSON.parse and jq do."""

    def refuse(word: str):
        raise ValueError(f"not JSON: {word}")

    return json.loads(text, parse_constant=refuse)


def strict_folder(folder: Path) -> list[Path]:
    """Every ``.json`` file under ``folder``, each parsed strictly (raises on the first bad one)."""
    files = sorted(folder.rglob("*.json"))
    for path in files:
        strict_loads(path.read_text())
    return files


def nbv_gym(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "nbv_gym", *args], capture_output=True, text=True, cwd=cwd
    )


def test_nan_and_infinity_become_null_at_any_depth_and_numpy_becomes_plain():
    value = {
        "nan": math.nan,
        "inf": -math.inf,
        "f32": np.float32("nan"),
        "array": np.array([1.5, np.nan]),
        "nested": ({"i": np.int64(3)}, [math.inf]),
        "ok": 0.25,
    }
    assert strict_loads(dumps_json(value)) == {
        "nan": None, "inf": None, "f32": None, "array": [1.5, None],
        "nested": [{"i": 3}, [None]], "ok": 0.25,
    }  # fmt: skip
    with pytest.raises(ValueError, match="not JSON: NaN"):
        strict_loads(json.dumps(math.nan))  # the parser used below does refuse the bare word


def test_a_run_folder_and_its_json_output_parse_strictly(tmp_path):
    done = nbv_gym(
        "run", "--world", "pp1-cuboids", "--max-steps", "2", "--no-animation",
        "--out", "run", "--json", cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    printed = strict_loads(done.stdout)
    assert printed["n_steps"] == 2 and printed["task"] == "explore"
    assert printed["run_folder"] == "run" and "step   2" in done.stderr
    files = strict_folder(tmp_path / "run")
    assert [p.name for p in files] == ["summary.json"]
    scored = nbv_gym(
        "evaluate", "--map", "run/map.npz", "--world", "pp1-cuboids", "--out", "eval", "--json",
        cwd=tmp_path,
    )  # fmt: skip
    assert scored.returncode == 0, scored.stderr
    assert 0 <= strict_loads(scored.stdout)["q"] <= 1
    assert [p.name for p in strict_folder(tmp_path / "eval")] == ["summary.json"]


def test_a_sweep_folder_and_its_json_output_parse_strictly(tmp_path):
    (tmp_path / "tiny.toml").write_text(
        'worlds = ["pp1-cuboids"]\nnoise = [0]\npolicies = ["closest-frontier"]\n'
        "repeats = 1\nmax_steps = 2\n"
    )
    done = nbv_gym("sweep", "tiny.toml", "--out", "out", "--json", "--workers", "1", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    printed = strict_loads(done.stdout)
    assert (printed["total"], printed["finished"], printed["failed"]) == (1, 1, {})
    assert printed["policies"][0]["policy"] == "closest-frontier"
    assert printed["report"].endswith("report.md") and "report:" in done.stderr
    names = {p.relative_to(tmp_path / "out").as_posix() for p in strict_folder(tmp_path / "out")}
    assert {"worlds.json", "versions.json"} <= names
    assert any(name.startswith("runs/") for name in names)
