"""Perf suite of how the environment's costs grow with the world: worlds of a 60, 120 and 240 m
window holding 50, 200 and 800 assets (the benchmark's asset density, the four asset types in
equal shares, the cluster radius scaled with the window), generated here from specs.

Keys of :func:`run`, for each window ``W`` in 60, 120, 240 (metres):
- ``scale_W_step_ms``: one env step (median over random valid goals, noise 1, no optional
  layers), and its parts ``scale_W_<part>_ms`` as ``env_<part>_ms`` of the env suite (lidar,
  insert, statistics, navigation, quality, observation).
- ``scale_W_step_cpu_ms``: the CPU time of one step (median; all the process's threads): on a
  shared machine the wall time also counts the time spent waiting for a core, the CPU time
  does not.
- ``scale_W_reset_ms``, ``scale_W_reset_cpu_ms``: one reset after the first (median).
- ``scale_W_rss_mb``: resident memory (VmRSS, MiB) of the process after those resets and steps
  (each world runs in a fresh process).
- ``scale_W_goals``: the number of goals (actions).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from nbv_gym.perf.env import PARTS, _status_mib, _time_parts

#: window side (m) → number of assets: the benchmark's density, 50 assets per 60 m × 60 m.
WORLDS = {60: 50, 120: 200, 240: 800}
STEPS = 15
RESETS = 3


def spec_text(window_m: int, n_assets: int) -> str:
    """The TOML spec of the scale suite's world of a ``window_m`` square window and ``n_assets``."""
    half = window_m / 2
    return f"""
name = "scale-{window_m}m"
description = "{n_assets} mixed assets in a {window_m} m square (nbv-gym bench --suite scale)"
ground_size_m = {window_m + 4:.1f}

[placement]
seed = 11
n_assets = {n_assets}
cluster_radius_m = {half:.1f}
window_m = [{-half:.1f}, {-half:.1f}, {half:.1f}, {half:.1f}]

[assets]
mix = {{ cuboids = 1.0, crosses = 1.0, helicoids = 1.0, trees = 1.0 }}
"""


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Step, reset and memory figures on each world of :data:`WORLDS`, each in a fresh process."""
    figures: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as folder:
        for window, n_assets in WORLDS.items():
            progress(f"{window} m window, {n_assets} assets: {RESETS} resets, {STEPS} steps")
            spec = Path(folder) / f"scale-{window}m.toml"
            spec.write_text(spec_text(window, n_assets), encoding="utf-8")
            code = f"from nbv_gym.perf.scale import one_world; one_world({str(spec)!r})"
            done = subprocess.run(
                [sys.executable, "-c", code], capture_output=True, text=True, check=True
            )
            measured = json.loads(done.stdout.strip().splitlines()[-1])
            figures.update({f"scale_{window}_{key}": value for key, value in measured.items()})
    return figures


def one_world(spec: str) -> None:
    """Print (JSON) the step, parts, reset and memory figures of an environment on ``spec``."""
    from nbv_gym.env import ExploreEnv

    env = ExploreEnv(world=spec, noise=1, max_steps=STEPS + 5)
    env.reset(seed=0)  # builds the world and compiles once
    resets = []
    for seed in range(1, RESETS + 1):
        start = time.perf_counter(), time.process_time()
        env.reset(seed=seed)
        resets.append((time.perf_counter() - start[0], time.process_time() - start[1]))
    _, info = env.reset(seed=RESETS + 1)
    spent = _time_parts(env)
    rng, steps, parts = np.random.default_rng(0), [], []
    for _ in range(STEPS):
        goal = int(rng.choice(np.flatnonzero(info["action_mask"])))
        spent.clear()
        start = time.perf_counter(), time.process_time()
        _, _, terminated, truncated, info = env.step(goal)
        steps.append((time.perf_counter() - start[0], time.process_time() - start[1]))
        parts.append(dict(spent))
        if terminated or truncated:
            _, info = env.reset(seed=len(steps))
    step, step_cpu = 1e3 * np.median(steps, axis=0)
    reset, reset_cpu = 1e3 * np.median(resets, axis=0)
    figures = {
        "step_ms": float(step),
        "step_cpu_ms": float(step_cpu),
        "reset_ms": float(reset),
        "reset_cpu_ms": float(reset_cpu),
        "rss_mb": _status_mib("VmRSS"),
        "goals": float(env.sim.n_goals),
    }
    for key in PARTS:
        figures[key.removeprefix("env_")] = 1e3 * float(np.median([p.get(key, 0.0) for p in parts]))
    print(json.dumps(figures))
