"""nbv-gym view: the scene of a run folder and its self-contained HTML page."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from nbv_gym.core.grid import GridSpec
from nbv_gym.core.inputs import InputFileError
from nbv_gym.core.pose import Pose
from nbv_gym.core.trajectory import read_trajectory, write_trajectory
from nbv_gym.mapping import OccupancyMap, ViewpointStatistics
from nbv_gym.mapping.mapfile import save_map
from nbv_gym.reporting.view import ViewError, load_scene, write_view

BOX = GridSpec.from_bounds((-2.0, -2.0, -1.0), (6.0, 2.0, 2.0), 0.1)
PARAMS = dict(p_hit=0.7, p_miss=0.4, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5,
              max_range_m=20.0)  # fmt: skip
#: voxel index → probability: a ground voxel (z centre 0.05 m), two above it, one free
VOXELS = {(5, 5, 10): 0.9, (65, 25, 15): 0.7, (15, 25, 25): 0.97, (30, 1, 20): 0.2}


@pytest.fixture
def run_folder(tmp_path):
    logodds = np.full(BOX.shape, np.nan, np.float32)
    for index, p in VOXELS.items():
        logodds[index] = np.log(p / (1 - p))
    save_map(OccupancyMap.from_logodds(BOX, logodds, **PARAMS), tmp_path / "map.npz")
    statistics = ViewpointStatistics(GridSpec.from_bounds((-2.0, -2.0, 0.0), (6.0, 2.0, 2.0), 1.0),
                                     n_sectors=32, min_range_m=1.0, max_range_m=20.0,
                                     min_return_z_m=0.0)  # fmt: skip
    statistics.update(np.array([-1.5, 0.5, 0.5]), np.array([[4.6, 0.5, 0.6]]))  # along y = 0.5
    statistics.save(tmp_path / "statistics.npz")
    poses = [Pose(0.0, 0.0, 0.0, 0.0), Pose(3.5, 0.5, 0.0, 1.0), Pose(5.5, -1.5, 0.0, -2.0)]
    write_trajectory(tmp_path / "trajectory.csv", poses)
    summary = {"world": "pp1-cuboids", "policy": "closest-frontier",
               "final": {"q": 0.25, "discovered": 0.7}}  # fmt: skip
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    return tmp_path


def test_trajectory_round_trip(tmp_path):
    path = write_trajectory(tmp_path / "t.csv", [Pose(1.0, 2.0, 0.5, 0.25), Pose(-3.0, 4.0, 0.0)])
    np.testing.assert_allclose(read_trajectory(path), [[1, 2, 0.5, 0.25], [-3, 4, 0, 0]])


def test_a_run_whose_trajectory_is_not_a_regular_file_is_refused_without_blocking(run_folder):
    (run_folder / "trajectory.csv").unlink()
    os.mkfifo(run_folder / "trajectory.csv")  # reading it would wait for a writer forever
    with pytest.raises(InputFileError, match=r"trajectory .* is not a regular file \(a FIFO\)"):
        load_scene(run_folder)


def test_scene_holds_the_occupied_voxels_above_the_ground_the_path_and_the_truth(run_folder):
    scene = load_scene(run_folder, max_points=500)
    # by hand: centres low + (index + ½) · 0.1 of the voxels with p ≥ 0.5 and z ≥ 0.2 m
    want = np.array([[-2, -2, -1]]) + (np.array([[15, 25, 25], [65, 25, 15]]) + 0.5) * 0.1
    np.testing.assert_allclose(scene.voxels, want, atol=1e-9)
    np.testing.assert_allclose(scene.values, [0.97, 0.7], rtol=1e-5)
    np.testing.assert_allclose(scene.poses[:, :2], [[0, 0], [3.5, 0.5], [5.5, -1.5]])
    assert len(scene.truth) == 500 and "closest-frontier on pp1-cuboids · Q 0.250" in scene.title
    with_ground = load_scene(run_folder, max_points=10, min_z_m=-1.0)
    assert len(with_ground.voxels) == 3


def test_colouring_by_a_statistic_reads_the_voxels_cell_of_g(run_folder):
    scene = load_scene(run_folder, "n_obs", max_points=10)
    # voxel (65, 25, 15) → (4.55, 0.55, 0.55): in the observed row y ∈ [0, 1), z ∈ [0, 1);
    # voxel (15, 25, 25) → (-0.45, 0.55, 1.55): z ∈ [1, 2), never observed
    assert scene.values[1] >= 1 and scene.values[0] == 0 and scene.label == "n_obs"
    with pytest.raises(ViewError, match="unknown colouring 'height'"):
        load_scene(run_folder, "height")
    (run_folder / "statistics.npz").unlink()
    with pytest.raises(ViewError, match=r"needs the run folder's statistics.npz"):
        load_scene(run_folder, "r_min")


def test_html_page_loads_plotly_from_its_cdn_or_inlines_it_offline(run_folder):
    scene = load_scene(run_folder, max_points=300)
    page = write_view(scene, run_folder / "view.html").read_text()
    assert 'src="https://cdn.plot.ly/plotly-' in page and "plotly.js v" not in page
    for name in ("ground truth", "map (occupied voxels)", "robot path and scans"):
        assert f'"name":"{name}"' in page
    offline = write_view(scene, run_folder / "offline.html", offline=True).read_text()
    assert 'src="http' not in offline and "Plotly.newPlot" in offline
    assert offline.count("plotly.js v") >= 1  # the library itself is inlined
    assert len(offline) - len(page) > 3_000_000


def test_page_without_network_says_why_it_is_blank_and_how_to_write_one_that_needs_none(run_folder):
    """Opened without a network, the CDN page's plotly.js does not load: a message stands in the
    figure's place (shown unless a script after the library finds Plotly defined); an offline page, whose
    library is inside it, carries no message."""
    scene = load_scene(run_folder, max_points=300)
    page = write_view(scene, run_folder / "view.html").read_text()
    message = page.index('id="nbv-gym-no-plotly"')
    # first in the page (the figure's empty full-height box would push it out of sight) …
    assert page.index("<body>") < message < page.index('src="https://cdn.plot.ly/plotly-')
    assert "nbv-gym view RUN_DIR --offline" in page[message:]
    # … and hidden by a script after the library's, only when the library is there
    check = page.index('typeof Plotly !== "undefined"')
    assert page.index('src="https://cdn.plot.ly/plotly-') < check < page.index("</body>")
    assert "display: none" not in page[message : page.index("</div>", message)]  # shown by default
    offline = write_view(scene, run_folder / "offline.html", offline=True).read_text()
    assert "nbv-gym-no-plotly" not in offline


def test_missing_map_is_explained(tmp_path):
    with pytest.raises(ViewError, match="no such map; give a run folder"):
        load_scene(tmp_path)
