"""Tiny sweep configs for the sweep tests: the cuboids world, 2–3 steps, two policies."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

RAISING_POLICY = '''
class Raiser:
    """A policy whose act() raises: the sweep must record the run as failed and go on."""

    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        raise RuntimeError("this policy always fails")


class Crasher:
    """A policy that kills its worker process: the sweep must survive the dead worker."""

    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        import os

        os._exit(3)


class Sleeper:
    """A policy that never returns from act(): the sweep must time it out. It first touches a
    file named after its pid in the folder ``SLEEPER_MARKS`` names (when set), so a test knows
    it is running."""

    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        import os
        import pathlib
        import time

        marks = pathlib.Path(__file__).with_name("sleeper-marks")
        if marks.is_dir():
            (marks / str(os.getpid())).touch()
        while True:
            time.sleep(1)


class Fractional:
    """A policy returning a valid goal + 0.9: the goal must be refused, not rounded."""

    observation_layers = ()

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        import numpy as np

        return int(np.flatnonzero(info["action_mask"])[0]) + 0.9


class StringLayers:
    """A policy declaring a string instead of a tuple of layer names."""

    observation_layers = "n_obs"

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        return 0


class UnknownLayers:
    """A policy declaring an observation layer that does not exist."""

    observation_layers = ("gain_bogus",)

    def reset(self, seed=None):
        pass

    def act(self, observation, info):
        return 0
'''


def write_config(folder: Path, name: str = "tiny", **values) -> Path:
    """A sweep config file in ``folder`` with tiny defaults, overridden by ``values``."""
    settings = {
        "worlds": ["pp1-cuboids"],
        "noise": [0],
        "policies": ["closest-frontier", "random-frontier"],
        "repeats": 1,
        "max_steps": 2,
        "retries": 1,
        **values,
    }
    lines = [f"{key} = {_toml(value)}" for key, value in settings.items()]
    path = folder / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def _toml(value) -> str:
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return repr(value)


@pytest.fixture
def policy_module(tmp_path: Path) -> Path:
    """A folder holding ``bad_policies.py`` with the :class:`Raiser` and :class:`Crasher`."""
    (tmp_path / "bad_policies.py").write_text(textwrap.dedent(RAISING_POLICY))
    return tmp_path


@pytest.fixture(scope="session")
def make_config():
    """:func:`write_config`, as a fixture (test modules cannot import conftest)."""
    return write_config
