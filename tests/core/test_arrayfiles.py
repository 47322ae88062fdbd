"""NPY/NPZ reading: numpy's own results for valid files, refusals without allocating otherwise."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from nbv_gym.core.arrayfiles import read_npy, read_npz
from nbv_gym.core.errors import DataFileError


def _npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buffer, {"descr": descr, "fortran_order": False, "shape": shape}
    )
    return buffer.getvalue()


@pytest.mark.parametrize(
    "array",
    [np.arange(12.0).reshape(3, 4), np.asfortranarray(np.arange(6, dtype=">i4").reshape(2, 3)),
     np.array("text"), np.float32(2.5), np.zeros((0, 3), bool)],
    ids=["c-order", "fortran-big-endian", "string", "scalar", "empty"],
)  # fmt: skip
def test_valid_files_read_as_numpy_reads_them(tmp_path, array):
    np.save(tmp_path / "a.npy", array)
    np.savez_compressed(tmp_path / "a.npz", first=array, second=np.arange(3))
    expected = np.load(tmp_path / "a.npy")
    got = read_npy(tmp_path / "a.npy")
    assert got.dtype == expected.dtype and got.shape == expected.shape
    np.testing.assert_array_equal(got, expected)
    arrays = read_npz(tmp_path / "a.npz")
    np.testing.assert_array_equal(arrays["first"], expected)
    np.testing.assert_array_equal(arrays["second"], [0, 1, 2])


def test_a_header_larger_than_its_file_is_refused_before_allocating(tmp_path):
    path = tmp_path / "huge.npy"
    path.write_bytes(_npy_header((10**12, 3)) + bytes(64))
    with pytest.raises(DataFileError, match=r"truncated: .* needs 24000000000000 bytes"):
        read_npy(path)


def test_object_arrays_are_refused_without_unpickling(tmp_path):
    np.save(tmp_path / "objects.npy", np.array([{"a": 1}, None], dtype=object))
    with pytest.raises(DataFileError, match="holds Python objects"):
        read_npy(tmp_path / "objects.npy")


def test_corrupt_headers_are_data_file_errors(tmp_path):
    path = tmp_path / "bad.npy"
    path.write_bytes(_npy_header((3,)).replace(b"{", b"\x00"))
    with pytest.raises(DataFileError, match="not a valid NPY header"):
        read_npy(path)


def test_an_npz_unpacking_past_the_limit_is_refused(tmp_path):
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("zeros.npy", _npy_header((1 << 18,)) + bytes(8 << 18))
    assert path.stat().st_size < 1 << 16  # 2 MiB of zeros compress to a few kB
    with pytest.raises(DataFileError, match=r"unpack to more than 1048576 bytes"):
        read_npz(path, max_bytes=1 << 20)
    assert read_npz(path, max_bytes=4 << 20)["zeros"].shape == (1 << 18,)
