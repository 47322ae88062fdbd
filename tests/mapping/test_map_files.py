"""Saved maps and statistics that are not what they claim are refused with DataFileError."""

from __future__ import annotations

import numpy as np
import pytest

from nbv_gym.core.errors import DataFileError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.mapfile import MAX_LOAD_VOXELS, load_map, save_map
from nbv_gym.mapping.occupancy import OccupancyMap
from nbv_gym.mapping.statistics import ViewpointStatistics

GRID = GridSpec((0.0, 0.0, 0.0), 0.5, (4, 4, 2))
PARAMS = dict(p_hit=0.7, p_miss=0.4, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5)


@pytest.fixture
def saved_map(tmp_path) -> dict[str, np.ndarray]:
    logodds = np.full(GRID.shape, np.nan, np.float32)
    logodds[1, 2, 0] = 0.85
    path = tmp_path / "map.npz"
    save_map(OccupancyMap.from_logodds(GRID, logodds, **PARAMS, max_range_m=5.0), path)
    with np.load(path) as data:
        return dict(data)


def _write(tmp_path, arrays) -> str:
    np.savez(tmp_path / "changed.npz", **arrays)
    return tmp_path / "changed.npz"


def test_a_saved_map_loads_back(tmp_path, saved_map):
    loaded = load_map(_write(tmp_path, saved_map))
    assert loaded.grid == GRID and loaded.params["max_range_m"] == 5.0


@pytest.mark.parametrize(
    "change, message",
    [
        ({"shape": np.array([10**5, 10**5, 10**5])}, rf"larger than {MAX_LOAD_VOXELS} voxels"),
        ({"shape": np.array([4, 4])}, r"expected a grid's origin .* shape int64 \(2,\)"),
        ({"index": np.array([999])}, r"voxel indices outside the \(4, 4, 2\) grid"),
        ({"logodds": np.zeros(2, np.float32)}, r"expected 'logodds' of shape \(1\)"),
        ({"params": np.array([1.0, 0.4, 0.12, 0.97, 0.5, 5.0])}, r"p_hit: must be in \(0\.5, 1\)"),
        ({"params": np.array([0.7, 0.4, 0.12, 0.97, 0.5, np.inf])}, "max_range_m must be finite"),
        ({"format": np.array("something else")}, "is not an nbv-gym occupancy map"),
    ],
    ids=["huge-grid", "grid-shape", "index", "logodds", "p-hit", "range", "format"],
)
def test_maps_that_do_not_fit_are_refused(tmp_path, saved_map, change, message):
    with pytest.raises(DataFileError, match=message):
        load_map(_write(tmp_path, {**saved_map, **change}))


def test_statistics_arrays_must_have_the_grid_shape(tmp_path):
    grid = GridSpec((0.0, 0.0, 0.0), 1.0, (3, 3, 2))
    stats = ViewpointStatistics(grid, n_sectors=32, min_range_m=1.0, max_range_m=9.0,
                                min_return_z_m=0.2)  # fmt: skip
    stats.save(tmp_path / "stats.npz")
    with np.load(tmp_path / "stats.npz") as data:
        arrays = dict(data)
    assert ViewpointStatistics.load(_write(tmp_path, arrays)).grid == grid
    arrays["shape"] = np.array([3000, 3000, 2000])
    with pytest.raises(DataFileError, match=r"expected 'n_obs' of shape \(3000×3000×2000\)"):
        ViewpointStatistics.load(_write(tmp_path, arrays))


@pytest.mark.parametrize(
    "frame",
    ['{"offset_m": [1.0, 2.0], "scale": 1.0, "up": "z"}', '{"offset_m": [0, 0, 0]}',
     '{"offset_m": [0, 0, NaN], "scale": 1.0, "up": "z"}', '{"offset_m": [0, 0, 0], '
     '"scale": -1.0, "up": "z"}', '{"offset_m": [0, 0, 0], "scale": 1.0, "up": "x"}', "[1, 2]"],
    ids=["two-numbers", "no-scale", "nan", "negative-scale", "x-up", "a-list"],
)  # fmt: skip
def test_a_scene_frame_record_that_is_no_frame_is_refused(tmp_path, saved_map, frame):
    from nbv_gym.mapping.mapfile import recorded_frame

    with pytest.raises(DataFileError, match="its scene frame record is not one nbv-gym writes"):
        recorded_frame(_write(tmp_path, {**saved_map, "frame": np.array(frame)}))


def test_a_scene_frame_is_recorded_and_read_back_and_none_is_empty(tmp_path, saved_map):
    from nbv_gym.mapping.mapfile import recorded_frame

    frame = {"offset_m": [99.8, 49.8, 20.0], "scale": 0.001, "up": "y"}
    occupancy = load_map(_write(tmp_path, saved_map))
    save_map(occupancy, tmp_path / "scene.npz", "scan@0123", frame)
    assert recorded_frame(tmp_path / "scene.npz") == frame
    assert recorded_frame(_write(tmp_path, saved_map)) == {}  # a procedural world's map
    older = {k: v for k, v in saved_map.items() if k != "frame"}
    assert recorded_frame(_write(tmp_path, older)) == {}  # saved before frames were recorded
