"""``nbv-gym bench`` as a user runs it: one JSON object on stdout, progress on stderr."""

from __future__ import annotations

import json

import pytest

from tests.helpers import run_cli


@pytest.mark.slow
def test_bench_json_is_one_object_on_stdout():
    result = run_cli("bench", "--json", "--suite", "foundation")
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    for key in ("world_build_s", "scan_rays_per_s", "embree_rays_per_s"):
        assert figures[key] > 0
    assert "building" in result.stderr
