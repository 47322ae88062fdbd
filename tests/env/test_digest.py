"""The protocol pinned bit for bit: a 10-step episode on two worlds hashed to a recorded digest.

Each world runs ``ExploreEnv(world=W, noise=1)`` from ``reset(seed=0)`` for at most 10 steps; each
step takes the valid frontier goal with the lowest index (``observation["frontier"] > 0`` and the
action mask), else the lowest valid goal. Every part of every reset/step result — each observation
array (bytes, dtype, shape), the reward, terminated, truncated and each ``info`` key (arrays as
bytes + dtype + shape, floats by ``repr``) — is hashed with SHA-256 and compared with
``tests/env/data/episode_digest.json``, which keeps one hash per part per step so a failure names
the first step and the parts that differ.

Internal work (speed-ups, refactors) must leave the digest unchanged. A change that alters the
protocol on purpose re-records it in the same commit, and says why in the commit message::

    NBV_GYM_RECORD_DIGEST=1 pytest tests/env/test_digest.py -p no:randomly

Floating-point sums compiled by numba may be vectorised differently on another CPU family; the
file records the CPU it was made on (``host_cpu``), and a failure message shows both.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from nbv_gym.env import ExploreEnv

WORLDS = ("pp1-cuboids", "pp1-trees")
STEPS = 10
SEED = 0
DATA = Path(__file__).parent / "data" / "episode_digest.json"
RECORD = os.environ.get("NBV_GYM_RECORD_DIGEST") == "1"


def canonical(value) -> bytes:
    """Bytes that identify ``value`` exactly: arrays by dtype, shape and bytes; floats by repr."""
    if isinstance(value, np.ndarray):
        head = f"ndarray {value.dtype.str} {value.shape}|".encode()
        return head + np.ascontiguousarray(value).tobytes()
    if isinstance(value, dict):
        return b"{" + b",".join(canonical(k) + b":" + canonical(value[k]) for k in value) + b"}"
    if isinstance(value, (list, tuple)):
        return f"{type(value).__name__}[".encode() + b",".join(map(canonical, value)) + b"]"
    if isinstance(value, np.generic):
        return f"{type(value).__name__} {value.dtype.str} ".encode() + value.tobytes()
    if isinstance(value, (bool, int, float, str, type(None))):
        return f"{type(value).__name__} {value!r}".encode()
    raise TypeError(f"no canonical form for {type(value).__name__}")


def sha(value) -> str:
    return hashlib.sha256(canonical(value)).hexdigest()


def choose(observation: dict, info: dict) -> int:
    """The valid frontier goal with the lowest index, else the lowest valid goal."""
    valid = np.asarray(info["action_mask"], bool)
    frontier = valid & (observation["frontier"] > 0)
    return int(np.flatnonzero(frontier if frontier.any() else valid)[0])


def step_parts(observation, info, reward=None, terminated=None, truncated=None) -> dict[str, str]:
    """One hash per observation array, per info key and per scalar of a reset or step."""
    parts = {f"obs.{k}": sha(observation[k]) for k in sorted(observation)}
    parts.update({f"info.{k}": sha(info[k]) for k in sorted(info)})
    if reward is not None:
        parts.update(reward=sha(reward), terminated=sha(terminated), truncated=sha(truncated))
    return parts


def episode_parts(world: str) -> list[dict[str, str]]:
    """The per-step part hashes of the pinned episode on ``world`` (reset first)."""
    env = ExploreEnv(world=world, noise=1)
    observation, info = env.reset(seed=SEED)
    steps = [step_parts(observation, info)]
    for _ in range(STEPS):
        goal = choose(observation, info)
        observation, reward, terminated, truncated, info = env.step(goal)
        steps.append(
            {"goal": sha(goal), **step_parts(observation, info, reward, terminated, truncated)}
        )
        if terminated or truncated:
            break
    return steps


def total(steps: list[dict[str, str]]) -> str:
    """One SHA-256 over every part of every step."""
    return hashlib.sha256(json.dumps(steps, sort_keys=True).encode()).hexdigest()


def host_cpu() -> str:
    import llvmlite.binding as llvm

    return f"{os.uname().machine} {llvm.get_host_cpu_name()}"


def record() -> None:
    episodes = {world: episode_parts(world) for world in WORLDS}
    data = {
        "about": "tests/env/test_digest.py; re-record: NBV_GYM_RECORD_DIGEST=1 pytest "
        "tests/env/test_digest.py -p no:randomly",
        "host_cpu": host_cpu(),
        "steps": STEPS,
        "seed": SEED,
        "digest": {world: total(steps) for world, steps in episodes.items()},
        "episodes": episodes,
    }
    DATA.parent.mkdir(parents=True, exist_ok=True)
    DATA.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")


@pytest.fixture(scope="module")
def recorded() -> dict:
    if RECORD:
        record()
    return json.loads(DATA.read_text())


@pytest.mark.parametrize("world", WORLDS)
def test_episode_matches_the_recorded_digest(world, recorded):
    steps = episode_parts(world)
    if total(steps) == recorded["digest"][world]:
        return
    expected = recorded["episodes"][world]
    for index, (got, want) in enumerate(zip(steps, expected, strict=False)):
        differ = sorted(k for k in set(got) | set(want) if got.get(k) != want.get(k))
        if differ:
            pytest.fail(
                f"{world}: step {index} differs from the recorded digest in {differ} "
                f"(recorded on {recorded['host_cpu']}, this is {host_cpu()}). If the protocol "
                "changed on purpose, re-record: NBV_GYM_RECORD_DIGEST=1 pytest "
                "tests/env/test_digest.py, and say why in the commit."
            )
    pytest.fail(f"{world}: {len(steps)} steps, recorded {len(expected)}")


def test_canonical_form_tells_dtype_shape_and_float_bits_apart():
    assert sha(np.zeros(2, np.float32)) != sha(np.zeros(2, np.float64))
    assert sha(np.zeros((2, 1))) != sha(np.zeros((1, 2)))
    assert sha(0.1 + 0.2) != sha(0.3)
    assert sha(np.bool_(True)) != sha(True) != sha(1)
