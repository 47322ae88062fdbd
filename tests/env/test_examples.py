"""The plain Gymnasium example of the README runs: ``experiments/gymnasium_async.py``."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

EXAMPLE = Path(__file__).parents[2] / "experiments" / "gymnasium_async.py"


def test_async_vector_example_finishes_budget_episodes_on_valid_goals():
    """Two async environments of the budget id, 4-scan budgets, 9 vector steps: each finishes
    two episodes (the ninth step autoresets). An invalid goal would raise in a worker."""
    command = [sys.executable, str(EXAMPLE), "--world", "pp1-cuboids", "--num-envs", "2",
               "--steps", "9", "--max-steps", "4"]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]
    lengths = [int(n) for n in re.findall(r"episode \d+: (\d+) scans", done.stdout)]
    assert lengths == [4, 4, 4, 4], done.stdout
    assert "4 episodes finished in 9 steps of 2 envs" in done.stdout
