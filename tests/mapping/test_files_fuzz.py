"""Map and statistics loaders fed mutated files: a loaded map or a DataFileError (an NbvGymError),
never another exception, a hang or a memory blow-up."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from nbv_gym.core import arrayfiles
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping import mapfile
from nbv_gym.mapping.mapfile import load_map, save_map
from nbv_gym.mapping.occupancy import OccupancyMap
from nbv_gym.mapping.statistics import ViewpointStatistics

pytestmark = pytest.mark.fuzz

GRID = GridSpec((-0.4, -0.4, 0.0), 0.1, (8, 8, 4))
PARAMS = dict(p_hit=0.7, p_miss=0.4, p_clamp_min=0.12, p_clamp_max=0.97, p_occupied=0.5)


def _saved(thing, folder) -> dict[str, np.ndarray]:
    path = folder / "valid.npz"
    save_map(thing, path) if isinstance(thing, OccupancyMap) else thing.save(path)
    with np.load(path) as data:
        return dict(data)


@pytest.fixture(scope="module")
def valid_map(folder) -> dict[str, np.ndarray]:
    logodds = np.full(GRID.shape, np.nan, np.float32)
    logodds[2:5, 3, :2] = [[0.4, -1.0]] * 3
    return _saved(OccupancyMap.from_logodds(GRID, logodds, **PARAMS, max_range_m=2.0), folder)


@pytest.fixture(scope="module")
def valid_statistics(folder) -> dict[str, np.ndarray]:
    grid = GridSpec((-2.0, -2.0, 0.0), 1.0, (4, 4, 2))
    stats = ViewpointStatistics(grid, n_sectors=32, min_range_m=1.7, max_range_m=20.0,
                                min_return_z_m=0.2)  # fmt: skip
    stats.update(np.array([0.1, 0.1, 1.0]), np.array([[1.5, 0.5, 0.5], [-1.5, 1.5, 1.5]]))
    return _saved(stats, folder)


@pytest.fixture(scope="module", autouse=True)
def small_limits():
    """A map limit of 2¹⁶ voxels, so that examples explore both sides of it cheaply."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(mapfile, "MAX_LOAD_VOXELS", 1 << 16)
        patch.setattr(arrayfiles, "MAX_NPZ_BYTES", 1 << 22)
        yield


def _values(draw) -> np.ndarray:
    """A random array: any numeric or string dtype, 0–3 axes, extreme values included."""
    kind = draw(st.sampled_from(["f8", "f4", "i8", "u4", "i1", "b1", "U4", "c8"]))
    shape = tuple(draw(st.lists(st.integers(0, 9), max_size=3)))
    if kind == "U4":
        return np.full(shape, draw(st.text(max_size=4)), "U4")
    if kind[0] in "iub":
        info = np.iinfo(kind) if kind != "b1" else None
        low, high = (info.min, info.max) if info else (0, 1)
        value = draw(
            st.one_of(st.integers(low, high), st.sampled_from([low, high, 0, 1, -1 % (high + 1)]))
        )
        return np.full(shape, value).astype(kind)
    value = draw(st.one_of(st.floats(), st.sampled_from([0.0, -0.0, 1e300, 0.5, 3.0])))
    with np.errstate(over="ignore"):
        return np.full(shape, value).astype(kind)


@st.composite
def mutated_arrays(draw, arrays: dict[str, np.ndarray]) -> bytes:
    """The .npz bytes of ``arrays`` with a few arrays replaced, dropped, resized or added."""
    arrays = dict(arrays)
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from([*arrays, "extra"]))
        action = draw(st.sampled_from(["replace", "drop", "grid", "slice"]))
        if action == "drop":
            arrays.pop(name, None)
        elif action == "grid" and "shape" in arrays:
            sizes = st.one_of(st.integers(-3, 80), st.integers(2**16, 2**62))
            arrays["shape"] = np.array(draw(st.lists(sizes, min_size=3, max_size=3)), np.int64)
        elif action == "slice" and name in arrays and arrays[name].ndim:
            arrays[name] = arrays[name][: draw(st.integers(0, 5))]
        else:
            arrays[name] = _values(draw)
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return buffer.getvalue()


@st.composite
def mutated_bytes(draw, arrays: dict[str, np.ndarray]) -> bytes:
    """The .npz bytes of ``arrays``, then a few bytes flipped or cut (headers included)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    data = bytearray(buffer.getvalue())
    for _ in range(draw(st.integers(1, 3))):
        at = draw(st.integers(0, len(data) - 1))
        if draw(st.booleans()):
            data[at] = draw(st.integers(0, 255))
        else:
            del data[at:]
            break
    return bytes(data)


def _load(contract, folder, loader, content: bytes) -> None:
    path = folder / "input.npz"
    path.write_bytes(content)
    contract(lambda: loader(path), len(content))


@given(data=st.data())
def test_mutated_map_arrays(contract, folder, valid_map, data):
    _load(contract, folder, load_map, data.draw(mutated_arrays(valid_map)))


@given(data=st.data())
def test_mutated_map_bytes(contract, folder, valid_map, data):
    _load(contract, folder, load_map, data.draw(mutated_bytes(valid_map)))


@given(data=st.data())
def test_mutated_statistics_arrays(contract, folder, valid_statistics, data):
    content = data.draw(mutated_arrays(valid_statistics))
    _load(contract, folder, ViewpointStatistics.load, content)


@given(data=st.data())
def test_mutated_statistics_bytes(contract, folder, valid_statistics, data):
    content = data.draw(mutated_bytes(valid_statistics))
    _load(contract, folder, ViewpointStatistics.load, content)


@given(st.binary(max_size=512))
def test_arbitrary_bytes(contract, folder, content):
    _load(contract, folder, load_map, content)
    _load(contract, folder, ViewpointStatistics.load, content)
