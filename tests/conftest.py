"""Shared fixtures: every test session builds worlds into its own cache, never the user's."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

from tests.helpers import keeps_contract

#: Hypothesis profiles (``HYPOTHESIS_PROFILE`` selects one): ``fuzz``, the default, a bounded and
#: derandomised run for the test suite (the same examples every time); ``long``, thousands of
#: random examples per test for occasional runs (``HYPOTHESIS_PROFILE=long pytest -m fuzz``).
settings.register_profile(
    "fuzz",
    max_examples=30,
    derandomize=True,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "long",
    max_examples=3000,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "fuzz"))


@pytest.fixture(scope="session", autouse=True)
def world_cache(tmp_path_factory):
    """Point NBV_GYM_CACHE at a directory shared by the xdist workers of this session."""
    root = tmp_path_factory.getbasetemp()
    shared = (root.parent if os.environ.get("PYTEST_XDIST_WORKER") else root) / "world-cache"
    shared.mkdir(exist_ok=True)
    previous = os.environ.get("NBV_GYM_CACHE")
    os.environ["NBV_GYM_CACHE"] = str(shared)
    yield shared
    if previous is None:
        os.environ.pop("NBV_GYM_CACHE", None)
    else:
        os.environ["NBV_GYM_CACHE"] = previous


PEEKING_POLICIES = '''
import numpy as np


class Oracle:
    """Reads info["q"] and its environment: an oracle that says so."""

    privileged = True
    observation_layers = ()

    def reset(self, seed=None):
        self.env, self.calls = None, []

    def attach(self, env):
        self.calls.append(("attach", type(env).__name__))
        self.env = env

    def act(self, observation, info):
        self.calls.append(("act", float(info["q"]), info["world"], self.env.sim.steps))
        return int(np.flatnonzero(info["action_mask"])[0])


class Peek:
    """Reads the privileged info[KEY] without declaring it."""

    key = "q"
    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        info[self.key]
        return int(np.flatnonzero(info["action_mask"])[0])


class PeekWorld(Peek):
    key = "world"


class PeekPose(Peek):
    key = "true_pose"
'''


@pytest.fixture
def peeking_policies(tmp_path_factory):
    """A folder on ``sys.path`` holding ``peeking.py``: an oracle (``peeking:Oracle``) and
    policies that read info["q"], ["world"] or ["true_pose"] without declaring it."""
    import sys

    folder = tmp_path_factory.mktemp("policies")
    (folder / "peeking.py").write_text(PEEKING_POLICIES)
    sys.modules.pop("peeking", None)  # never a module of that name another test imported
    sys.path.insert(0, str(folder))
    yield folder
    sys.path.remove(str(folder))
    sys.modules.pop("peeking", None)


@pytest.fixture(scope="module")
def contract():
    """:func:`keeps_contract`, as a fixture for the fuzz tests."""
    return keeps_contract


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """A folder for the files of one test module's examples (each example overwrites its file)."""
    return tmp_path_factory.mktemp("fuzz")
