"""``nbv-gym evaluate`` on synthetic arrays and point clouds, through the CLI as a user runs it."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from nbv_gym.core.pointclouds import write_points
from nbv_gym.metrics.cuboids import benchmark_grid
from tests.helpers import invoke


@pytest.fixture(scope="module")
def perfect_map(tmp_path_factory):
    folder = tmp_path_factory.mktemp("map")
    gt = np.zeros(benchmark_grid().shape, bool)
    gt[100:110, 200, 10:30] = True  # a thin wall across cuboids (10, 20, 1) and (10, 20, 2)
    np.save(folder / "gt.npy", gt)
    np.save(folder / "prob.npy", np.where(gt, np.float32(0.97), np.float32(0.12)))
    return folder


def test_map_mode_writes_csv_summary_and_heat_map(perfect_map, tmp_path):
    out = tmp_path / "eval"
    result = invoke("evaluate", "--map", perfect_map / "prob.npy",
                    "--ground-truth", perfect_map / "gt.npy", "--out", out, "--json")  # fmt: skip
    assert result.code == 0, result.err
    summary = json.loads(result.out)  # progress goes to stderr
    assert summary["q"] == 1.0 and summary["cov_p0.7_d0.15"] == 1.0 and summary["n_occ"] == 2
    assert summary["wd_occ_max"] < 1.0
    assert json.loads((out / "summary.json").read_text())["q"] == 1.0
    rows = list(csv.DictReader((out / "cuboids.csv").open()))
    assert len(rows) == 60 * 60 * 6 and sum(int(r["u_occ"]) for r in rows) == 2
    assert (out / "quality.png").read_bytes()[:4] == b"\x89PNG"


def test_cloud_mode_prints_the_empir3d_table(tmp_path):
    axis = np.arange(0, 1, 0.02)
    x, y = np.meshgrid(axis, axis)
    cloud = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    write_points(tmp_path / "ref.ply", cloud)
    write_points(tmp_path / "cand.xyz", cloud + [0, 0, 0.03])
    result = invoke(
        "evaluate", tmp_path / "ref.ply", tmp_path / "cand.xyz", "--json", "--region", 0.5
    )
    assert result.code == 0, result.err
    scores = json.loads(result.out)
    assert scores["q_a"] == pytest.approx(0.7) and scores["q_t"] == 1.0
    text = invoke("evaluate", tmp_path / "ref.ply", tmp_path / "cand.xyz").out
    assert "q_r" in text and "hausdorff_m" in text


def test_errors_name_the_file_and_the_problem(perfect_map, tmp_path):
    np.save(tmp_path / "small.npy", np.zeros((10, 10, 10), np.float32))
    result = invoke("evaluate", "--map", tmp_path / "small.npy",
                    "--ground-truth", perfect_map / "gt.npy")  # fmt: skip
    assert result.code == 2
    assert "small.npy: expected a float probability grid of shape (600, 600, 60)" in result.err
    result = invoke("evaluate", tmp_path / "none.ply", tmp_path / "none.pcd")
    assert "none.ply: the point-cloud file does not exist" in result.err
    assert "nothing to evaluate" in invoke("evaluate").err
