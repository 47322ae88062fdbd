"""Shared fixtures: every test session builds worlds into its own cache, never the user's."""

from __future__ import annotations

import os

import pytest


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
