"""Exceptions raised by nbv-gym.

Every error the library raises on bad input derives from :class:`NbvGymError`, so a caller can catch
one type. Messages say what was expected, what came, and what to do. Only the CLI turns these into
exit codes.
"""

from __future__ import annotations

import difflib
import errno
import os
import stat
from collections.abc import Iterable
from pathlib import Path


class NbvGymError(Exception):
    """Base class of every error nbv-gym raises on bad input."""


def missing_file(path: object) -> str:
    """Why the file ``path`` cannot be read, for a message: ``"is a folder, not a file"``,
    ``"is not a regular file (a FIFO)"`` (a device, a socket), ``"is a symbolic link to X that
    loops"`` (or that points to nothing) or ``"does not exist"``."""
    path = Path(str(path))
    if path.is_dir():
        return "is a folder, not a file"
    if path.exists():
        return f"is not a regular file ({file_type(path.stat().st_mode)})"
    return broken_link(path) or "does not exist"


def broken_link(path: Path) -> str | None:
    """``"is a symbolic link to X that loops"`` (or ``"… that points to nothing"``) when
    ``path`` is a symbolic link that leads to no file, else None."""
    if not path.is_symlink():
        return None
    try:
        path.stat()
    except OSError as error:
        what = "loops" if error.errno == errno.ELOOP else "points to nothing"
        return f"is a symbolic link to {os.readlink(path)} that {what}"
    return None


def file_type(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` that is not a regular file or folder is ("a FIFO")."""
    kinds = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))  # fmt: skip
    return next((name for test, name in kinds if test(mode)), "not a plain file")


#: Why a JSON or TOML file nested deeper than Python's parsers recurse is refused.
TOO_DEEP = "it nests arrays or tables deeper than the parser reads (a result or config nests a few)"


class ConfigError(NbvGymError, ValueError):
    """A config or spec value is missing, unknown or out of range; the message names its key."""


class UnknownNameError(NbvGymError, KeyError):
    """A name (world, policy, metric, …) is not registered."""

    def __init__(self, kind: str, name: str, valid: Iterable[str]):
        valid = sorted(valid)
        close = difflib.get_close_matches(name, valid, n=3)
        hint = f" Did you mean {', '.join(repr(c) for c in close)}?" if close else ""
        self.message = f"Unknown {kind} {name!r}.{hint} Valid {_plural(kind)}: {', '.join(valid)}."
        super().__init__(self.message)

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


def _plural(noun: str) -> str:
    """``policy`` → ``policies``, ``world`` → ``worlds``."""
    return noun[:-1] + "ies" if noun.endswith("y") and noun[-2:-1] not in "aeiou" else noun + "s"


class DataFileError(NbvGymError, ValueError):
    """A data file (map, statistics, array) is unreadable, truncated, too large or not what it
    claims to be; the message names the file."""


class PoseError(NbvGymError, ValueError):
    """A pose lies outside the world or the map."""


#: The PyTorch build the ``rl`` extra is tested with, from PyTorch's CPU-only index: a plain
#: ``pip install torch`` (or of the extra) pulls the multi-GB CUDA build on Linux.
CPU_TORCH = "pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu"


class MissingExtraError(NbvGymError, ImportError):
    """An optional dependency is missing; the message names the extra to install (and, for
    the ``rl`` extra, the CPU build of PyTorch to install first)."""

    def __init__(self, package: str, extra: str):
        first = f"{CPU_TORCH}, then " if extra == "rl" else ""
        super().__init__(
            f"This feature needs {package!r}, which is not installed. "
            f'Install it with: {first}pip install "nbv-gym[{extra}]"'
        )


class ClusterError(NbvGymError):
    """A Dask cluster cannot be reached, refuses this client, or has lost all its workers; the
    message says what to do."""
