"""Output paths of the commands, checked before any work starts (so a bad ``--out`` fails in a
second, not after the whole episode or sweep), and the rules that keep results from being lost.

- Every command checks its output with :func:`writable_folder` or :func:`writable_file`.
- A folder belongs to the command that wrote it (:func:`claim_folder`): ``run`` refuses a sweep's
  folder and ``sweep`` a run's, naming it, so neither overwrites the other's files.
- A command that replaces its own earlier results writes into a temporary sibling and swaps the
  files in only when it finished (:func:`staged_folder`): a crash leaves the earlier files intact.
- Files are written atomically (:func:`write_text`, :class:`atomic`, :func:`write_together`):
  to a temporary sibling, renamed into place once complete.
- :func:`describe_os_error` turns a failed write (full disk, no permission, a file where a folder
  should be) into one line that names the path; the CLI's error boundary uses it.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from nbv_gym.core.errors import NbvGymError, broken_link


class OutputError(NbvGymError):
    """An output file or folder cannot be written; the message names it and says why."""


def writable_folder(path: str | Path, option: str = "--out") -> Path:
    """``path`` as a folder this process can write into, created (with its parents) if missing;
    :class:`OutputError` if it is a file or cannot be created or written."""
    path = _checked(Path(path), option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        why = f"it {link}" if (link := broken_link(path)) else _why(error)
        raise OutputError(f"{option} {path}: cannot create the folder ({why}).") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {path}: the folder is not writable (permission denied).")
    return path


def writable_file(path: str | Path, option: str = "--out") -> Path:
    """``path`` as a file this process can write (its folder is created if missing);
    :class:`OutputError` if it is a folder or cannot be written."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{option} {path} is a folder; give a file name.")
    _checked(path.parent, option, of=path)
    writable_folder(path.parent, option)
    _remember(path)
    if path.exists() and not os.access(path, os.W_OK):
        raise OutputError(f"{option} {path}: the file is not writable (permission denied).")
    return path


def _checked(folder: Path, option: str, of: Path | None = None) -> Path:
    """``folder``, remembered as the command's output, after checking that no file stands at
    its place or at the place of one of its parents (a file's "subfolder");
    :class:`OutputError` naming ``of`` (the output, ``folder`` by default) otherwise."""
    of = folder if of is None else of
    blocker = next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)
    if blocker == of:
        raise OutputError(f"{option} {of} is a file; give a folder.")
    if blocker is not None:
        raise OutputError(
            f"{option} {of}: cannot create the folder (Not a directory: {blocker} is a file)."
        )
    _remember(of)
    return folder


#: The output path the command checked last: named when a write fails without naming its file.
_last_output: list[Path] = []


def _remember(path: Path) -> None:
    _last_output[:] = [path]


def _why(error: OSError) -> str:
    return error.strerror or str(error)


#: The file that records which command wrote a folder (``run``, ``sweep``, …).
OWNER_FILE = ".nbv-gym-owner"
#: How folders written before :data:`OWNER_FILE` existed are recognised: (command, its file).
_OWNER_SIGNS = (("sweep", "sweep.toml"), ("train", "system_info.txt"), ("run", "summary.json"),
                ("score", "scorecard.json"))  # fmt: skip


def folder_owner(path: str | Path) -> str | None:
    """The command that wrote the folder ``path`` (None for a new, empty or foreign folder)."""
    path = Path(path)
    marker = path / OWNER_FILE
    if marker.is_file():
        return marker.read_text(errors="replace", encoding="utf-8").strip() or None
    return next((command for command, sign in _OWNER_SIGNS if (path / sign).is_file()), None)


def claim_folder(path: str | Path, command: str, option: str = "--out") -> Path:
    """``path`` as a writable folder of ``command`` (created if missing, marked with
    :data:`OWNER_FILE`); :class:`OutputError` naming the folder if another command wrote it."""
    owner = check_owner(path, command, option)
    writable_folder(path, option)
    if owner is None:
        (Path(path) / OWNER_FILE).write_text(f"{command}\n", encoding="utf-8")
    return Path(path)


def check_owner(path: str | Path, command: str, option: str = "--out") -> str | None:
    """The command that wrote the folder ``path`` (None if none did), after checking that it is
    ``command``; :class:`OutputError` naming the folder and its command otherwise."""
    path = _checked(Path(path), option)
    owner = folder_owner(path) if path.is_dir() else None
    if owner not in (None, command):
        raise OutputError(
            f"{option} {path} is the folder of `nbv-gym {owner}`; `nbv-gym {command}` would "
            "overwrite its files. Give another folder."
        )
    return owner


@contextmanager
def staged_folder(out: Path, names: Iterable[str]) -> Iterator[Path]:
    """A temporary sibling of the folder ``out`` to write into. When the block ends normally the
    files and folders written there replace those of ``out``, and those of ``names`` it did not write
    are removed from ``out`` (so none is stale); other files of ``out`` stay. When the block
    raises (a crash, Ctrl-C or SIGTERM, ``sys.exit``) the sibling is deleted and ``out`` is left
    as it was."""
    staging = out.parent / f".{out.name}.partial-{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        with terminate_as_interrupt():
            yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    written = {p.name for p in staging.iterdir()}
    for name in set(names) - written:
        _remove(out / name)
    for name in sorted(written):
        if (out / name).is_dir() and not (out / name).is_symlink():
            _remove(out / name)  # os.replace cannot replace a folder that holds files
        os.replace(staging / name, out / name)
    staging.rmdir()


@contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """Around work that cleans up on Ctrl-C: SIGTERM (``kill``, a batch system's stop) raises
    :class:`KeyboardInterrupt` too, so the same clean-up runs. Only in the main thread (where
    Python delivers signals); the earlier handler is restored afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    earlier = signal.signal(signal.SIGTERM, _interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, earlier)


def _interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def _remove(path: Path) -> None:
    """Delete the file or folder ``path`` (nothing if it is missing)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


#: What a failed write means to a user, by ``errno``.
_OS_REASONS: dict[int | None, str] = {
    errno.ENOSPC: "no space left on the device; free some space or choose another place",
    errno.EDQUOT: "the disk quota is exceeded; free some space or choose another place",
    errno.EACCES: "permission denied; choose a place you can write",
    errno.EPERM: "operation not permitted; choose a place you can write",
    errno.EROFS: "the file system is read-only; choose another place",
    errno.ENOTDIR: "a part of the path is a file, not a folder",
    errno.EISDIR: "it is a folder; give a file name",
    errno.ENOENT: "no such file or folder",
    errno.ENAMETOOLONG: "the name is too long",
}


def describe_os_error(error: OSError) -> str:
    """One line for a failed file operation: its path (the output the command checked last
    when the error names none, as a write to an open file does) and what it means."""
    reason = _OS_REASONS.get(error.errno, _why(error))
    path = error.filename or (f"writing {_last_output[0]}" if _last_output else None)
    return f"{path}: {reason}." if path else f"cannot read or write a file: {reason}."


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (temporary file, then rename)."""
    with atomic(path, "w") as f:
        f.write(text)


def write_new(path: Path, text: str, advice: str = "give another path") -> None:
    """Write ``text`` to ``path`` whole, unless a file is there: to a temporary sibling, then
    linked to its name (atomic, and refused where the name was taken meanwhile, by another
    process writing the same file). OutputError naming the file and ``advice`` when it exists;
    nothing half-written either way."""
    partial = temporary(path)
    try:
        partial.write_text(text, encoding="utf-8")
        try:
            os.link(partial, path)
        except FileExistsError:
            raise
        except OSError:  # a file system without hard links: exclusive creation instead
            with open(path, "x", encoding="utf-8") as stream:
                stream.write(text)
    except FileExistsError:
        raise OutputError(
            f"{path} exists: another process wrote it while this one ran; it is left as it is "
            f"and this command wrote nothing ({advice})."
        ) from None
    finally:
        partial.unlink(missing_ok=True)


class atomic:
    """Open a temporary sibling of ``path`` for writing and rename it onto ``path`` on success."""

    def __init__(self, path: Path, mode: str):
        self.path, self.mode = Path(path), mode
        self.temporary = temporary(self.path)

    def __enter__(self):
        self.file = open(self.temporary, self.mode, encoding=text_encoding(self.mode))
        return self.file

    def __exit__(self, kind, value, trace) -> None:
        self.file.close()
        if kind is None:
            os.replace(self.temporary, self.path)
        else:
            self.temporary.unlink(missing_ok=True)


def text_encoding(mode: str) -> str | None:
    """UTF-8 for a text ``mode``, None for a binary one: every text file the package writes is
    UTF-8, whatever the locale."""
    return None if "b" in mode else "utf-8"


def write_together(writers: dict[Path, tuple[str, Any]]) -> None:
    """Write several files, each by ``write(file)`` opened in ``mode``, to temporary names, and
    put them in place only when all were written (tables that must agree)."""
    written = []
    try:
        for path, (mode, write) in writers.items():
            written.append(temporary(path))
            with open(written[-1], mode, encoding=text_encoding(mode)) as f:
                write(f)
    except BaseException:
        for partial in written:
            partial.unlink(missing_ok=True)
        raise
    for path, complete in zip(writers, written, strict=True):
        os.replace(complete, path)


def temporary(path: Path) -> Path:
    """The temporary sibling ``<name>.tmp<pid>`` a file is written to before it is renamed."""
    return path.with_name(f"{path.name}.tmp{os.getpid()}")
