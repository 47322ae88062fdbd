"""The export, view and record commands and --version as a user runs them (a subprocess)."""

from __future__ import annotations

from importlib.metadata import version

import numpy as np
import pytest

from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping import OccupancyMap
from nbv_gym.mapping.mapfile import save_map
from tests.helpers import run_cli

BOX = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 1.0), 0.1)
PARAMS = dict(p_hit=0.7, p_miss=0.4, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
              max_range_m=20.0)  # fmt: skip


@pytest.fixture
def map_file(tmp_path):
    logodds = np.full(BOX.shape, np.nan, np.float32)
    logodds[3, 4, 5], logodds[70, 30, 12], logodds[10, 10, 10] = 2.0, 0.5, -1.5
    path = tmp_path / "map.npz"
    save_map(OccupancyMap.from_logodds(BOX, logodds, **PARAMS), path)
    return path


def test_version():
    result = run_cli("--version")
    assert result.returncode == 0 and result.stdout.strip() == f"nbv-gym {version('nbv-gym')}"


def test_export_writes_a_pcd_that_pypcd4_reads(map_file, tmp_path):
    pypcd4 = pytest.importorskip("pypcd4")
    result = run_cli("export", str(map_file), "--format", "pcd", "--out", str(tmp_path / "m.pcd"))
    assert result.returncode == 0 and "2 voxels" in result.stdout, result.stderr
    cloud = pypcd4.PointCloud.from_path(tmp_path / "m.pcd")
    centres = np.array([[-2, -2, -1]]) + (np.array([[3, 4, 5], [70, 30, 12]]) + 0.5) * 0.1
    np.testing.assert_allclose(cloud.numpy(("x", "y", "z")), centres, atol=4e-6)
    default = run_cli("export", str(map_file), "--min-p", "0")
    assert default.returncode == 0 and "3 voxels" in default.stdout
    assert map_file.with_suffix(".ply").is_file()


def test_export_refuses_bad_formats_in_one_line(map_file, tmp_path):
    result = run_cli("export", str(map_file), "--format", "las")
    assert (
        result.returncode == 2 and "unknown format 'las'; use one of ply, pcd, bt" in result.stderr
    )
    result = run_cli("export", str(map_file), "--format", "pcd", "--out", str(tmp_path / "m.ply"))
    assert result.returncode == 2 and "does not end in .pcd" in result.stderr
    assert "Traceback" not in result.stderr
