"""Helpers shared by the test modules: the command line as a user runs it, the command tree, and
a tiny world spec. Import them as ``from tests.helpers import …`` (the repository root is on the
test path, see ``[tool.pytest.ini_options] pythonpath``)."""

from __future__ import annotations

import contextlib
import io
import signal
import subprocess
import sys
import tracemalloc
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nbv_gym.core.errors import NbvGymError

#: A world of 10 cuboids: quick to build, enough to explore for a few steps.
TINY_WORLD = """
name = "tiny-cuboids"
description = "10 cuboids for the tests"

[placement]
seed = 7
n_assets = 10
cluster_radius_m = 30.0

[assets]
mix = { cuboids = 1.0 }
"""


def write_tiny_world(folder: Path, name: str = "tiny.toml") -> Path:
    """Write :data:`TINY_WORLD` into ``folder``; the spec file's path."""
    path = Path(folder) / name
    path.write_text(TINY_WORLD)
    return path


@dataclass
class Result:
    """What a command gave: its exit ``code``, and what it wrote to stdout (``out``) and stderr
    (``err``)."""

    code: int
    out: str
    err: str


def few_steps(env_id: str, steps: int) -> dict[str, int]:
    """The keyword that ends an episode of the registered ``env_id`` after ``steps`` scans: the
    budget task's budget, else the truncation."""
    return {"budget_scans": steps} if "Budget" in env_id else {"max_steps": steps}


def invoke(*args: object) -> Result:
    """``nbv-gym ARGS`` in this process, through the CLI's error boundary as the console script
    runs it (exit codes, one-line messages); stdout and stderr captured."""
    from nbv_gym.cli.main import app

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            app(args=[str(a) for a in args], prog_name="nbv-gym")
            code = 0
        except SystemExit as exit:
            code = exit.code if isinstance(exit.code, int) else int(exit.code is not None)
    return Result(code, out.getvalue(), err.getvalue())


def run_cli(
    *args: object, cwd: Path | None = None, timeout: float = 600
) -> subprocess.CompletedProcess:
    """``python -m nbv_gym ARGS`` in a fresh process, as a user runs it; output captured as text."""
    return subprocess.run(
        [sys.executable, "-m", "nbv_gym", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=cwd,
    )


def command_paths() -> Iterator[tuple[str, ...]]:
    """Every command and group of the ``nbv-gym`` app as its argument path (the root is ``()``),
    walked through the click tree that typer builds."""
    import typer

    from nbv_gym.cli.main import app

    def walk(command, path: tuple[str, ...]) -> Iterator[tuple[str, ...]]:
        yield path
        if is_group(command):
            for name, sub in sorted(command.commands.items()):
                yield from walk(sub, (*path, name))

    yield from walk(typer.main.get_command(app), ())


def is_group(command) -> bool:
    """Whether a command of the click tree has subcommands (typer ships its own click, so
    ``isinstance(command, click.Group)`` does not tell)."""
    return isinstance(getattr(command, "commands", None), dict)


#: Seconds one input may take before it counts as a hang.
HANG_S = 20.0
#: Bytes one input may allocate beyond a fixed allowance of 64 MiB, per byte of input.
MEMORY_PER_INPUT_BYTE = 64


class Hang(BaseException):
    """An input took longer than :data:`HANG_S` (a BaseException, so no reader swallows it)."""


def _alarm(signum, frame):
    raise Hang(f"no result after {HANG_S} s")


def keeps_contract(call: Callable[[], Any], input_size: int) -> Any:
    """Run ``call``: it must return, or raise an :class:`NbvGymError` with a one-line message,
    within :data:`HANG_S` and allocating at most 64 MiB + :data:`MEMORY_PER_INPUT_BYTE` ×
    ``input_size`` bytes (numpy's allocations included). Returns the result or the error."""
    limit = (64 << 20) + MEMORY_PER_INPUT_BYTE * input_size
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    tracemalloc.start()
    try:
        outcome = call()
    except NbvGymError as error:
        message = str(error)
        assert message.strip() and "\n" not in message, f"message {message!r}"
        outcome = error
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert peak <= limit, f"allocated {peak} bytes for {input_size} bytes of input"
    return outcome


#: Side of the units of :func:`box_mesh` and :func:`box_surface_voxels`, metres.
BOX_UNIT_M = 0.05


def box_mesh(box: tuple[int, ...]):
    """The closed axis-aligned box ``box`` = (x0, x1, y0, y1, z1) in units of
    :data:`BOX_UNIT_M`, standing on z = 0: (8, 3) float64 vertices (metres), (12, 3) faces."""
    import itertools

    import numpy as np
    import trimesh

    x0, x1, y0, y1, z1 = np.asarray(box) * BOX_UNIT_M
    corners = np.array(list(itertools.product((x0, x1), (y0, y1), (0.0, z1))))
    return corners, trimesh.convex.convex_hull(corners).faces


def box_surface_voxels(box: tuple[int, ...]) -> set[tuple[int, int, int]]:
    """The 0.1 m ground-truth voxels of :func:`box_mesh`'s box worked out alone, in integers
    (voxel i is the half-open [2i, 2i + 2) in its units): those that meet the closed box but
    do not lie in the box less its walls and lid (open in x and y, [0, z1) in z — the base
    on the ground marks nothing)."""
    import itertools

    x0, x1, y0, y1, z1 = box
    bounds = ((x0, x1), (y0, y1), (0, z1))
    ranges = [range(lo // 2 - 1, hi // 2 + 2) for lo, hi in bounds]
    voxels = set()
    for voxel in itertools.product(*ranges):
        starts = [2 * i for i in voxel]
        meets = all(s <= hi and lo < s + 2 for s, (lo, hi) in zip(starts, bounds, strict=True))
        inner = [lo < s and s + 2 <= hi for s, (lo, hi) in zip(starts, bounds, strict=True)]
        if meets and not (inner[0] and inner[1] and 0 <= starts[2] and starts[2] + 2 <= z1):
            voxels.add(voxel)
    return voxels
