"""``--help`` and ``-h`` on every command and group of ``nbv-gym``, found by walking the app."""

from __future__ import annotations

import pytest
import typer
from typer.testing import CliRunner

from nbv_gym.cli.main import app
from tests.helpers import command_paths, is_group, run_cli

PATHS = list(command_paths())


def _is_group(path: tuple[str, ...]) -> bool:
    command = typer.main.get_command(app)
    for name in path:
        command = command.commands[name]
    return is_group(command)


def test_the_walk_finds_every_command_of_the_cli():
    # a hand-written list: the walk must not silently find fewer commands than the CLI has
    expected = {("run",), ("sweep",), ("report",), ("evaluate",), ("train",), ("bench",),
                ("export",), ("view",), ("record",), ("worlds", "list"), ("worlds", "build"),
                ("worlds", "preview"), ("study", "wd"), ("study", "empir3d")}  # fmt: skip
    assert expected <= set(PATHS)
    assert () in PATHS and ("worlds",) in PATHS and ("study",) in PATHS


@pytest.mark.parametrize("path", PATHS, ids=lambda path: " ".join(path) or "nbv-gym")
def test_h_is_help_on_every_command(path):
    runner = CliRunner()
    long = runner.invoke(app, [*path, "--help"], terminal_width=100)
    short = runner.invoke(app, [*path, "-h"], terminal_width=100)
    assert long.exit_code == 0 and short.exit_code == 0, (long.output, short.output)
    assert short.output == long.output
    assert long.output.startswith(f"Usage: {' '.join(('nbv-gym', *path))}".replace("  ", " "))
    assert "-h, --help" in long.output
    if not _is_group(path):
        assert "Examples:" in long.output, path


def test_h_works_from_the_console_entry_point():
    result = run_cli("study", "empir3d", "-h")
    assert result.returncode == 0 and "Usage: python -m nbv_gym study empir3d" in result.stdout


@pytest.mark.parametrize(
    "path", [p for p in PATHS if not _is_group(p)], ids=lambda path: " ".join(path)
)
def test_help_examples_fit_an_80_column_terminal(path):
    result = CliRunner().invoke(app, [*path, "--help"], terminal_width=80)
    examples = result.output.split("Examples:")[-1].split("Options:")[0]
    long = [line for line in examples.splitlines() if len(line) >= 80]
    assert result.exit_code == 0 and "nbv-gym" in examples and not long, (path, long)
