"""Runs that keep their scans, and the two study commands end to end."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from nbv_gym.cli.main import app
from nbv_gym.mapping.mapfile import load_map
from nbv_gym.studies import StudyError
from nbv_gym.studies.runs import SCANS_NAME, find_runs, make_run, replay, run_map
from tests.helpers import run_cli


def test_replayed_scans_rebuild_the_runs_map(tmp_path):
    folder = make_run("pp1-cuboids", 1, "closest-frontier", 0, 2, tmp_path / "a" / "run")
    saved = load_map(folder / "map.npz").logodds
    rebuilt = replay(folder / SCANS_NAME, 0.1).logodds
    np.testing.assert_array_equal(np.isnan(rebuilt), np.isnan(saved))
    np.testing.assert_array_equal(rebuilt[~np.isnan(saved)], saved[~np.isnan(saved)])
    (run,) = find_runs(tmp_path)
    assert (run.world, run.noise, run.has_scans) == ("pp1-cuboids", 1, True)
    assert run_map(run, 0.1).grid.res == pytest.approx(0.1)


def test_a_folder_without_run_maps_is_refused(tmp_path):
    (tmp_path / "runs.csv").write_text("key\n")
    with pytest.raises(StudyError, match=r"holds no run folder .* A sweep folder keeps no maps"):
        find_runs(tmp_path)


def test_study_empir3d_on_a_cloud_file(tmp_path):
    x, y = np.meshgrid(np.arange(40) * 0.05, np.arange(40) * 0.05, indexing="ij")
    cloud = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) + 0.025
    np.save(tmp_path / "plate.npy", cloud)
    result = CliRunner().invoke(
        app, ["study", "empir3d", str(tmp_path / "plate.npy"), "--out", str(tmp_path / "s")]
    )
    assert result.exit_code == 0, result.output
    assert "| coverage (X, 40%) moves Q_c most |" in result.output
    report = (tmp_path / "s" / "report" / "report.md").read_text()
    assert "The paper's Table I" in report
    assert (tmp_path / "s" / "ablations.csv").read_text().count("\n") == 1 + 1 + 8


def test_study_wd_refuses_a_resolution_that_does_not_cut_whole_cuboids(tmp_path):
    result = run_cli("study", "wd", "--out", str(tmp_path), "--resolution", "0.07")
    assert result.returncode == 2, result.stderr
    assert "resolution 0.07 m does not cut the comparison box" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
def test_study_wd_end_to_end(tmp_path):
    args = ["study", "wd", "--out", str(tmp_path), "--worlds", "pp1-cuboids", "--share-worlds",
            "pp1-cuboids", "--noise", "0", "--resolution", "0.1", "--cuboids", "8",
            "--share-cuboids", "8", "--max-steps", "2"]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "not reproducible here" in result.output
    for name in (
        "ideal_cuboids.csv",
        "limits.csv",
        "shares.csv",
        "report/fig4_informative_share.png",
    ):
        assert (tmp_path / name).is_file()
    again = CliRunner().invoke(app, ["study", "wd", "--out", str(tmp_path), "--report-only"])
    assert again.exit_code == 0, again.output
