"""Files read with bounds: the one way nbv-gym opens the files a user hands it or a folder holds
(configs, scorecards, result tables, manifests, point clouds, arrays).

A path must name a regular file (after symbolic links): a FIFO named ``scorecard.json`` would
block the read forever, and ``/dev/zero`` or ``/dev/urandom`` never end, so both are refused
before a byte is read. The file is opened without blocking and checked on the open handle (no
race between the check and the read), then read up to a limit per kind of file; a larger file
is refused with the limit named (the limits are listed in docs/security.md).
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any, BinaryIO

from nbv_gym.core.errors import TOO_DEEP, DataFileError, file_type, missing_file

#: Results that are JSON (scorecards, summaries, manifests, table digests).
MAX_JSON_BYTES = 64 << 20
#: Result tables (``runs.csv``, ``steps.csv``, Parquet tables of a sweep folder).
MAX_TABLE_BYTES = 4 << 30


class InputFileError(DataFileError):
    """A file to read is missing, not a regular file or too large; the message names it."""


def open_input(path: str | Path, kind: str, max_bytes: int) -> BinaryIO:
    """``path`` opened for binary reading, after checking on the open handle that it is a
    regular file of at most ``max_bytes``; :class:`InputFileError` naming the ``kind`` of file
    ("Scorecard", …) otherwise. The caller closes it (``with open_input(...) as f:``)."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputFileError(f"{kind} {path} {missing_file(path)}.") from None
    except IsADirectoryError:
        raise InputFileError(f"{kind} {path} is a folder, not a file.") from None
    except OSError as error:
        raise InputFileError(f"{kind} {path}: cannot open it ({error.strerror}).") from None
    try:
        _check_regular(os.fstat(fd), path, kind, max_bytes)
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def _check_regular(info: os.stat_result, path: Path, kind: str, max_bytes: int) -> None:
    if stat.S_ISDIR(info.st_mode):
        raise InputFileError(f"{kind} {path} is a folder, not a file.")
    if not stat.S_ISREG(info.st_mode):
        raise InputFileError(
            f"{kind} {path} is not a regular file ({file_type(info.st_mode)}); give a file."
        )
    if info.st_size > max_bytes:
        raise InputFileError(
            f"{kind} {path} has {info.st_size:,} bytes, more than the limit of {max_bytes:,} "
            "bytes for such files (docs/security.md)."
        )


def read_input(path: str | Path, kind: str, max_bytes: int) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_input`), at most ``max_bytes`` even
    if the file grows while it is read."""
    with open_input(path, kind, max_bytes) as stream:
        size = max(os.fstat(stream.fileno()).st_size + 1, 1 << 16)  # one read, unless it grows
        chunks, total = [], 0
        while data := stream.read(min(size, max_bytes + 1 - total)):
            chunks.append(data)
            total += len(data)
            if total > max_bytes:
                raise InputFileError(f"{kind} {path} grew past the limit of {max_bytes:,} bytes.")
    return b"".join(chunks)


def read_input_text(path: str | Path, kind: str, max_bytes: int) -> str:
    """The UTF-8 text of the regular file ``path`` (:func:`read_input`)."""
    data = read_input(path, kind, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise InputFileError(f"{kind} {path} is not UTF-8 text: {error}") from None


def read_json(path: str | Path, kind: str, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """The strict JSON value of the regular file ``path``: ``NaN``, ``Infinity`` and duplicate
    keys (which Python's ``json`` accepts, and no other parser agrees on) are refused."""
    text = read_input_text(path, kind, max_bytes)
    try:
        return json.loads(text, parse_constant=_no_constant, object_pairs_hook=_unique_keys)
    except ValueError as error:
        raise InputFileError(f"{kind} {path} is not valid JSON: {error}") from None
    except RecursionError:
        raise InputFileError(f"{kind} {path} is not valid JSON: {TOO_DEEP}.") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON (nbv-gym writes an undefined number as null)")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    found: dict[str, Any] = {}
    for key, value in pairs:
        if key in found:
            raise ValueError(f"the key {key!r} appears twice in one object")
        found[key] = value
    return found
