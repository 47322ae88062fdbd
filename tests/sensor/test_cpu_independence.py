"""Results do not depend on which BLAS kernel the CPU selects: one short episode run in
subprocesses under two OpenBLAS core types (Haswell: AVX2 and FMA; Prescott: SSE3 only) gives
the same bits — every scan's map-frame points, the map, Q and the goals."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

#: Runs one episode and prints a digest of everything it computed.
EPISODE = """
import hashlib, json
import numpy as np
from nbv_gym.env.explore import EnvConfig
from nbv_gym.episode import make_env, run_episode
from nbv_gym.policies import load_policy
from nbv_gym.core.protocol import EpisodeConfig
from nbv_gym.simulator import SimulatorConfig

policy = load_policy("closest-frontier")
config = EnvConfig(SimulatorConfig(world="pp1-cuboids", noise=2, episode=EpisodeConfig(max_steps=4)))
from nbv_gym.sensor.lidar import Lidar
env = make_env(config, policy)
scans = hashlib.sha256()
simulate = Lidar.scan
def recorded(self, robot, rng):
    scan = simulate(self, robot, rng)
    scans.update(np.ascontiguousarray(scan.points_map).tobytes())
    return scan
Lidar.scan = recorded
result = run_episode(env, policy, seed=3)
try:  # the BLAS kernel this process selected
    from threadpoolctl import threadpool_info
    kernel = next((i.get("architecture") for i in threadpool_info() if i["user_api"] == "blas"), None)
except ImportError:
    kernel = None
print(json.dumps({
    "kernel": kernel,
    "goals": [row["goal"] for row in result.steps],
    "q": [row["q"].hex() for row in result.steps],
    "path": [row["path_length_m"].hex() for row in result.steps],
    "scans": scans.hexdigest(),
}))
"""


def _episode(core: str) -> dict:
    env = {**os.environ, "OPENBLAS_CORETYPE": core}
    done = subprocess.run(
        [sys.executable, "-c", EPISODE], capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_an_episode_gives_the_same_bits_under_two_blas_kernels():
    haswell, prescott = _episode("Haswell"), _episode("Prescott")
    kernels = haswell.pop("kernel"), prescott.pop("kernel")
    if None in kernels or kernels[0] == kernels[1]:
        pytest.skip(f"OPENBLAS_CORETYPE did not select two BLAS kernels here ({kernels})")
    assert haswell == prescott
