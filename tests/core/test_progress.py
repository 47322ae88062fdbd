"""Long phases speak on stderr, and progress in a log is whole lines, never ``\\r`` frames."""

from __future__ import annotations

import logging
import os
import subprocess
import sys

from nbv_gym.core import progress
from nbv_gym.core.progress import PlainProgress, progress_bar, say_if_compiling


def test_a_cold_sweep_logged_to_a_file_names_its_phases_without_carriage_returns(tmp_path):
    (tmp_path / "tiny.toml").write_text(
        'worlds = ["pp1-cuboids"]\nnoise = [0]\npolicies = ["closest-frontier"]\n'
        "repeats = 1\nmax_steps = 2\n"
    )
    environment = {**os.environ, "NBV_GYM_CACHE": str(tmp_path / "cold-cache")}
    with open(tmp_path / "log.txt", "w") as log:  # a file: not a terminal
        done = subprocess.run(
            [sys.executable, "-m", "nbv_gym", "sweep", "tiny.toml", "--out", "out",
             "--workers", "1"],
            stdout=subprocess.DEVNULL, stderr=log, cwd=tmp_path, env=environment,
        )  # fmt: skip
    text = (tmp_path / "log.txt").read_text()
    assert done.returncode == 0, text
    assert "building world pp1-cuboids (mesh + ground truth), once per content" in text
    assert "world pp1-cuboids built in" in text
    assert "building the report of out" in text and "report built in" in text
    assert "tiny: 100%" in text and "1/1" in text  # the progress line, written once at the end
    assert "\r" not in text


def test_compilation_is_announced_when_no_kernel_is_cached(tmp_path, monkeypatch, caplog):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    say_if_compiling.cache_clear()
    try:
        with caplog.at_level(logging.INFO, logger="nbv_gym"):
            say_if_compiling()
        assert "compiling kernels, once per install" in caplog.text
        (tmp_path / "sub").mkdir()
        (tmp_path / "sub" / "kernel.f-1.py311.nbi").write_bytes(b"")
        say_if_compiling.cache_clear()
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="nbv_gym"):
            say_if_compiling()
        assert caplog.text == ""
    finally:
        say_if_compiling.cache_clear()


def test_off_a_terminal_the_bar_writes_a_line_every_interval_and_at_the_end(capsys, monkeypatch):
    bar = progress_bar(10, "sweep", "run")  # pytest captures stderr: not a terminal
    assert isinstance(bar, PlainProgress)
    clock = iter([0.0, 1.0, 31.0, 32.0, 33.0])
    monkeypatch.setattr(progress.time, "monotonic", lambda: next(clock))
    bar = PlainProgress(10, "sweep", "run")  # starts at 0 s
    bar.update()  # 1 s: quiet
    bar.update()  # 31 s: a line
    bar.set_postfix(failed=0)
    bar.update(8)  # 32 s: quiet
    bar.close()  # 33 s: the last line
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 2 and lines[0].startswith("sweep:  20%") and "2/10" in lines[0]
    assert lines[1].startswith("sweep: 100%") and "10/10" in lines[1] and "failed=0" in lines[1]
