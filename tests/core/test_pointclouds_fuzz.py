"""Point-cloud readers fed arbitrary, mutated and hostile-header files: a valid (n, 3) result or
a PointCloudError, never another exception, a hang or a memory blow-up."""

from __future__ import annotations

import io

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from nbv_gym.core.pointclouds import SUFFIXES, read_points, write_points

pytest.importorskip("hypothesis")

HUGE = st.one_of(
    st.integers(-5, 40), st.integers(-(2**70), 2**70), st.sampled_from([10**12, 2**63 - 1, 2**64])
)

pytestmark = pytest.mark.fuzz
PLY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8",
             "float64", "list uchar int", "list int float", "bogus"]  # fmt: skip


def _points(draw) -> np.ndarray:
    n = draw(st.integers(1, 12))
    values = st.floats(-1e3, 1e3, allow_nan=False, width=32)
    return np.array(draw(st.lists(values, min_size=3 * n, max_size=3 * n))).reshape(n, 3)


@st.composite
def mutated(draw, content: bytes) -> bytes:
    """``content`` with a few random edits: byte flips, cuts, insertions, duplicated spans."""
    data = bytearray(content)
    for _ in range(draw(st.integers(0, 4))):
        at = draw(st.integers(0, len(data)))
        kind = draw(st.sampled_from(["flip", "cut", "insert", "duplicate", "truncate"]))
        if kind == "flip" and at < len(data):
            data[at] = draw(st.integers(0, 255))
        elif kind == "cut":
            del data[at : at + draw(st.integers(1, 16))]
        elif kind == "insert":
            data[at:at] = draw(st.binary(max_size=16))
        elif kind == "duplicate":
            data[at:at] = data[at : at + draw(st.integers(1, 64))]
        else:
            del data[at:]
    return bytes(data)


@st.composite
def written_files(draw) -> tuple[str, bytes]:
    """(suffix, bytes) of a valid point cloud written by nbv-gym, then mutated."""
    suffix = draw(st.sampled_from(SUFFIXES))
    buffer = io.BytesIO()
    points = _points(draw)
    if suffix == ".npy":
        np.save(buffer, points)
    else:
        path = _scratch(suffix)
        write_points(path, points)
        buffer.write(path.read_bytes())
    return suffix, draw(mutated(buffer.getvalue()))


@st.composite
def ply_files(draw) -> bytes:
    """A PLY header of random elements, counts and property types, then random bytes."""
    fmt = draw(st.sampled_from(["ascii", "binary_little_endian", "binary_big_endian", "x"]))
    lines = ["ply", f"format {fmt} 1.0"]
    for _ in range(draw(st.integers(0, 3))):
        name = draw(st.sampled_from(["vertex", "face", "edge"]))
        lines.append(f"element {name} {draw(HUGE)}")
        for prop in draw(st.lists(st.sampled_from(["x", "y", "z", "nx", "red"]), max_size=5)):
            lines.append(f"property {draw(st.sampled_from(PLY_TYPES))} {prop}")
    header = "\n".join([*lines, "end_header", ""]).encode()
    return header + draw(st.binary(max_size=256))


@st.composite
def pcd_files(draw) -> bytes:
    """A PCD header of random fields, sizes, types, counts and point count, then random bytes."""
    fields = draw(st.lists(st.sampled_from(["x", "y", "z", "rgb", "i"]), min_size=1, max_size=5))
    k = len(fields) + draw(st.integers(-1, 1))
    sizes = draw(
        st.lists(st.sampled_from(["1", "2", "4", "8", "3", "-4", "x"]), min_size=k, max_size=k)
    )
    types = draw(st.lists(st.sampled_from(["F", "I", "U", "Q"]), min_size=k, max_size=k))
    counts = draw(
        st.lists(st.sampled_from(["1", "0", "3", "-1", "99999999999"]), min_size=k, max_size=k)
    )
    points = draw(HUGE)
    data = draw(st.sampled_from(["ascii", "binary", "binary_compressed", ""]))
    lines = [f"FIELDS {' '.join(fields)}", f"SIZE {' '.join(sizes)}", f"TYPE {' '.join(types)}",
             f"COUNT {' '.join(counts)}", f"WIDTH {points}", "HEIGHT 1", f"POINTS {points}",
             f"DATA {data}", ""]  # fmt: skip
    body = draw(st.one_of(st.binary(max_size=256), st.just(b"1 2 3\n4 5 6\nnan 1 2\n")))
    return "\n".join(lines).encode() + body


@st.composite
def npy_files(draw) -> bytes:
    """An NPY header of a random dtype (object included), order and shape, then random bytes."""
    dtype = draw(st.sampled_from(["<f8", "<f4", ">i4", "|u1", "|b1", "<c16", "|O", "<U3", "|V8"]))
    shape = tuple(draw(st.lists(HUGE.filter(lambda v: 0 <= v < 2**62), max_size=3)))
    buffer = io.BytesIO()
    header = {"descr": dtype, "fortran_order": draw(st.booleans()), "shape": shape}
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue() + draw(st.binary(max_size=256))


_SCRATCH = {}


def _scratch(suffix: str):
    return _SCRATCH[suffix]


@pytest.fixture(scope="module", autouse=True)
def scratch(folder):
    _SCRATCH.update({s: folder / f"written{s}" for s in SUFFIXES})


def _read(contract, folder, suffix: str, content: bytes) -> None:
    path = folder / f"input{suffix}"
    path.write_bytes(content)
    result = contract(lambda: read_points(path), len(content))
    if isinstance(result, np.ndarray):
        assert result.ndim == 2 and result.shape[1] == 3 and len(result) > 0
        assert result.dtype == np.float64 and np.isfinite(result).all()


@given(st.sampled_from(SUFFIXES), st.data())
def test_unmutated_files_read_back_their_points(folder, suffix, data):
    points = _points(data.draw)
    path = write_points(folder / f"exact{suffix}", points)
    np.testing.assert_allclose(read_points(path), points, rtol=1e-6)


@given(written_files())
def test_mutated_files_of_every_format(contract, folder, case):
    suffix, content = case
    _read(contract, folder, suffix, content)


@given(st.sampled_from(SUFFIXES), st.binary(max_size=512))
def test_arbitrary_bytes_of_every_format(contract, folder, suffix, content):
    _read(contract, folder, suffix, content)


@given(ply_files())
def test_ply_headers(contract, folder, content):
    _read(contract, folder, ".ply", content)


@given(pcd_files())
def test_pcd_headers(contract, folder, content):
    _read(contract, folder, ".pcd", content)


@given(npy_files())
def test_npy_headers(contract, folder, content):
    _read(contract, folder, ".npy", content)
