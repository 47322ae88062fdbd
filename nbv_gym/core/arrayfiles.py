"""NPY and NPZ files from anyone: headers read and sizes bounded before anything is allocated.

``numpy.load`` allocates whatever an array header declares (a 100-byte file can ask for 23 GiB)
and lets a corrupt header escape as ``SyntaxError``. These readers parse each header first,
refuse object arrays (pickles), shapes the data cannot hold and totals above a limit, and raise
:class:`DataFileError` naming the file for every problem.
"""

from __future__ import annotations

import io
import math
import os
import tokenize
import zipfile
import zlib
from collections.abc import Iterable
from pathlib import Path
from typing import IO, Any, cast

import numpy as np

from nbv_gym.core.errors import DataFileError, missing_file

#: The most array bytes one NPZ file may unpack to (a sparse 0.05 m map holds about 1 GiB).
MAX_NPZ_BYTES = 4 << 30
#: What numpy raises for a malformed array header or body.
_NUMPY_ERRORS = (ValueError, OSError, EOFError, SyntaxError, tokenize.TokenError, TypeError)
_ZIP_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, NotImplementedError)


def read_npy(path: str | Path) -> np.ndarray:
    """The array of the NPY file at ``path``; the header's shape must fit the file's size."""
    from nbv_gym.core.inputs import open_input

    path = Path(path)
    with open_input(path, "Array file", MAX_NPZ_BYTES) as stream:
        return _read_array(stream, os.fstat(stream.fileno()).st_size, path)


def read_npz(
    path: str | Path, max_bytes: int | None = None, names: Iterable[str] | None = None
) -> dict[str, np.ndarray]:
    """The arrays (name → array) of the NPZ file at ``path`` (only those of ``names`` when
    given), at most ``max_bytes`` (default :data:`MAX_NPZ_BYTES`) in all, each header checked
    against its member's size first."""
    path, limit = Path(path), MAX_NPZ_BYTES if max_bytes is None else max_bytes
    wanted = None if names is None else {f"{name}.npy" for name in names}
    arrays, total = {}, 0
    from nbv_gym.core.inputs import open_input

    try:
        with open_input(path, "Array file", limit) as file, zipfile.ZipFile(file) as archive:
            for info in archive.infolist():
                if wanted is not None and info.filename not in wanted:
                    continue
                total += info.file_size
                if total > limit:
                    raise DataFileError(f"{path}: its arrays unpack to more than {limit} bytes")
                with archive.open(info) as stream:
                    arrays[info.filename.removesuffix(".npy")] = _read_array(
                        stream, info.file_size, f"{path}: {info.filename}"
                    )
    except _ZIP_ERRORS as error:
        raise DataFileError(f"{path}: not a readable .npz file ({error})") from None
    return arrays


def _read_array(stream: IO[bytes], size: int, source: str | Path) -> np.ndarray:
    """The array in ``stream`` (``size`` bytes, header included), refused unless the header is
    valid, the dtype holds no objects and the data fits in ``size``."""
    shape, fortran_order, dtype = _header(stream, source)
    if dtype.hasobject:
        raise DataFileError(f"{source}: holds Python objects (a pickle); refusing to load it")
    for axis, length in enumerate(shape):
        declared_count(length, source, f"the length of axis {axis}")
    check_body(source, f"a {dtype} array of shape {shape}", math.prod(shape) * dtype.itemsize,
               size - stream.tell())  # fmt: skip
    need = math.prod(shape) * dtype.itemsize
    data = bytearray(need)
    try:
        # zipfile's members and files opened 'rb' are buffered streams, which have readinto
        if cast(io.BufferedIOBase, stream).readinto(data) != need:
            raise EOFError("the data ends early")
        return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran_order else "C")
    except _NUMPY_ERRORS as error:
        raise DataFileError(f"{source}: not a valid NPY array ({_one_line(error)})") from None


def declared_count(value: Any, source: str | Path, what: str) -> int:
    """``value``, a count a file's header declares (points, vertices, an array's length), as an
    int; :class:`DataFileError` naming ``source`` and ``what`` unless it is an integer ≥ 0."""
    try:
        count = int(value)
        exact = count == float(value) if not isinstance(value, str) else str(count) == value
    except (TypeError, ValueError):
        exact = False
    if not exact or count < 0:
        raise DataFileError(f"{source}: {what} is {value!r}; expected an integer ≥ 0")
    return count


def check_body(source: str | Path, what: str, declared: int, held: int) -> None:
    """The one check of every reader that a header's sizes fit the file: ``declared`` bytes (of
    ``what``, e.g. "12 vertices of 12 bytes") against the ``held`` bytes after the header;
    :class:`DataFileError` naming ``source`` when the body is shorter (truncated) or longer
    (the header declares less than the file holds: the rest would be silently ignored)."""
    if declared > held:
        raise DataFileError(
            f"{source}: truncated: {what} needs {declared} bytes, the file holds {held} "
            "after its header"
        )
    if declared < held:
        raise DataFileError(
            f"{source}: the header declares {what} ({declared} bytes) but the file holds "
            f"{held} bytes after it; the rest would be ignored (a wrong count?)"
        )


def _header(stream: IO[bytes], source: str | Path) -> tuple[tuple[int, ...], bool, np.dtype]:
    """Shape, Fortran order and dtype of the NPY header at the start of ``stream``."""
    try:
        version = np.lib.format.read_magic(stream)
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f"unsupported NPY version {version}")
        if version == (1, 0):
            return np.lib.format.read_array_header_1_0(stream)
        return np.lib.format.read_array_header_2_0(stream)
    except _NUMPY_ERRORS as error:
        raise DataFileError(f"{source}: not a valid NPY header ({_one_line(error)})") from None


def _one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


def read_saved(path: str | Path, format_name: str, kind: str) -> dict[str, np.ndarray]:
    """The arrays of an nbv-gym ``.npz`` file whose ``format`` array is ``format_name``;
    :class:`DataFileError` naming ``kind`` ("occupancy map", …) for any other file."""
    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"{path}: the {kind} file {missing_file(path)}")
    arrays = read_npz(path)
    stored = arrays.get("format")
    if stored is None or stored.shape != () or stored.dtype.kind != "U" or stored != format_name:
        raise DataFileError(f"{path} is not an nbv-gym {kind} ({format_name} .npz file)")
    return arrays


def array_of(
    arrays: dict[str, np.ndarray], name: str, kinds: str, shape: tuple[int | None, ...], source
) -> np.ndarray:
    """``arrays[name]``, checked: present, of a numpy dtype kind in ``kinds`` (``"f"``, ``"iu"``,
    …) and of ``shape`` (None: any length on that axis); :class:`DataFileError` otherwise."""
    array = arrays.get(name)
    if (
        array is None
        or array.dtype.kind not in kinds
        or array.ndim != len(shape)
        or any(want not in (None, got) for want, got in zip(shape, array.shape, strict=True))
    ):
        found = "nothing" if array is None else f"{array.dtype} {array.shape}"
        wanted = "×".join("n" if s is None else str(s) for s in shape) or "scalar"
        raise DataFileError(f"{source}: expected {name!r} of shape ({wanted}), found {found}")
    return array
