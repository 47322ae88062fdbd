"""The perf suites (speed figures), run by ``nbv-gym bench``: one flat dict of named measurements.

Each suite is a function ``run(progress) -> dict[str, float]`` in its own module of this package;
keys keep their meaning forever once they exist. Progress goes through the callback (stderr in
the CLI).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from nbv_gym.core.errors import UnknownNameError

Progress = Callable[[str], None]

#: The world every perf suite measures on.
PERF_WORLD = "pp1-trees"

#: suite name → module holding its ``run(progress)``.
SUITES: dict[str, str] = {
    "foundation": "nbv_gym.perf.foundation",
    "mapping": "nbv_gym.perf.mapping",
    "metrics": "nbv_gym.perf.metrics",
    "nbv": "nbv_gym.perf.nbv",
    "env": "nbv_gym.perf.env",
    "rl": "nbv_gym.perf.rl",
    "references": "nbv_gym.perf.decisions",
    "rl-cluster": "nbv_gym.perf.rlcluster",
    "scale": "nbv_gym.perf.scale",
    "team": "nbv_gym.perf.team",
}


def run_suites(names: list[str] | None, progress: Progress) -> dict[str, float]:
    """Run the named suites (all when ``names`` is empty or None) and merge their figures."""
    for name in names or []:
        if name not in SUITES:
            raise UnknownNameError("perf suite", name, SUITES)
    results: dict[str, float] = {}
    for name in names or list(SUITES):
        progress(f"[{name}]")
        results.update(importlib.import_module(SUITES[name]).run(progress))
    return results
