"""What a long phase says while it runs: phase messages and progress bars, both on stderr.

Library code announces its long phases (a world build, the first compilation of the kernels)
through the ``nbv_gym`` logger at level INFO; the command line shows them on stderr
(:func:`speak_on_stderr`), a program that imports nbv-gym sees them only if it configures
logging. Progress bars (:func:`progress_bar`) draw on a terminal only; in a log file or a pipe
they write a plain line now and then instead of ``\\r`` frames.
"""

from __future__ import annotations

import functools
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

LOGGER = logging.getLogger("nbv_gym")
#: Set by :func:`speak_on_stderr` so that worker processes started later speak too.
SPEAK_VARIABLE = "NBV_GYM_SPEAK"
#: Seconds between two plain progress lines when stderr is not a terminal.
PLAIN_INTERVAL_S = 30.0


def say(message: str) -> None:
    """Announce a phase (``"building world pp1-trees …"``) to whoever listens."""
    LOGGER.info(message)


class _PhaseHandler(logging.StreamHandler):
    """The stderr handler :func:`speak_on_stderr` adds once (its ``nbv_gym`` mark tells it apart)."""

    nbv_gym = True


def speak_on_stderr() -> None:
    """Show the phase messages on stderr, in this process and the worker processes it starts."""
    os.environ[SPEAK_VARIABLE] = "1"
    if not any(getattr(h, "nbv_gym", False) for h in LOGGER.handlers):
        handler = _PhaseHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        LOGGER.addHandler(handler)
    LOGGER.setLevel(logging.INFO)


def speak_if_asked() -> None:
    """:func:`speak_on_stderr` in a worker process whose parent called it."""
    if os.environ.get(SPEAK_VARIABLE) == "1":
        speak_on_stderr()


@functools.cache
def say_if_compiling() -> None:
    """Say that the kernels are being compiled when no compiled kernel is cached yet (a new
    install, or a new numba): numba caches them beside the package (or in
    ``NUMBA_CACHE_DIR``), so this happens once per install. Checked once per process."""
    if not _kernels_cached():
        say("compiling kernels, once per install (about 15 s on 2 cores)…")


def kernel_cache_error(error: BaseException) -> str | None:
    """One line for ``error`` if numba raised it while reading its cache of compiled kernels (a
    truncated or overwritten ``.nbi``/``.nbc`` file: numba lets the unpickling error through),
    naming the cache folder and the cure; None for any other error."""
    frames, tb = [], error.__traceback__
    while tb is not None:
        frames.append(tb.tb_frame.f_code.co_filename.replace("\\", "/"))
        tb = tb.tb_next
    if not any(name.endswith("numba/core/caching.py") for name in frames):
        return None
    folder = os.environ.get("NUMBA_CACHE_DIR") or f"the __pycache__ folders of {_package()}"
    return (
        f"numba's cache of compiled kernels is unreadable ({type(error).__name__}: {error}) in "
        f"{folder}; delete its *.nbi and *.nbc files (they are compiled again, about 15 s) or "
        "set NUMBA_CACHE_DIR to an empty folder."
    )


def _package() -> Path:
    return Path(__file__).resolve().parents[1]


def _kernels_cached() -> bool:
    folder = Path(os.environ.get("NUMBA_CACHE_DIR") or _package())
    return next(folder.rglob("*.nbi"), None) is not None


def progress_bar(total: int, desc: str = "", unit: str = "it", **options: Any) -> Any:
    """A tqdm bar on stderr when stderr is a terminal; otherwise a :class:`PlainProgress` that
    writes tqdm's status line every :data:`PLAIN_INTERVAL_S` seconds and at the end, without
    ``\\r``. ``options`` go to tqdm (``disable=True`` silences both)."""
    from tqdm import tqdm

    if sys.stderr.isatty():
        return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, **options)
    return PlainProgress(
        total, desc, unit, options.get("initial", 0), options.get("disable"), options.get("leave")
    )


class PlainProgress:
    """The part of tqdm's interface nbv-gym uses, writing whole lines for logs and pipes. As
    tqdm's, a bar made with ``leave=False`` leaves no last line, nor does one closed by an
    exception (the error is the news)."""

    def __init__(self, total: int, desc: str, unit: str, initial=0, disable=False, leave=True):
        self.total, self.desc, self.unit, self.n = total, desc, unit, initial
        self.disable, self.leave, self.postfix = bool(disable), leave is not False, ""
        self.start = self.last = time.monotonic()

    def update(self, n: int = 1) -> None:
        """Count ``n`` more items; print a line at most every few seconds."""
        self.n += n
        now = time.monotonic()
        if now - self.last >= PLAIN_INTERVAL_S:
            self._line(now)

    def set_description(self, desc: str) -> None:
        """Show ``desc`` before the count."""
        self.desc = desc

    def set_postfix(self, **values: Any) -> None:
        """Show ``key=value`` pairs after the count."""
        self.postfix = ", ".join(f"{k}={v}" for k, v in values.items())

    def set_postfix_str(self, text: str) -> None:
        """Show ``text`` after the count."""
        self.postfix = text

    def write(self, message: str) -> None:
        """Print ``message`` on stderr (unless the bar is disabled)."""
        if not self.disable:
            print(message, file=sys.stderr, flush=True)

    def close(self) -> None:
        """Print the final count (if the bar is kept and it changed)."""
        if self.leave and self.n != getattr(self, "_written", None):
            self._line(time.monotonic())

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, kind: Any, *exc: Any) -> None:
        self.leave = self.leave and kind is None
        self.close()

    def _line(self, now: float) -> None:
        from tqdm import tqdm

        self.last, self._written = now, self.n
        meter = tqdm.format_meter(self.n, self.total, self.last - self.start, prefix=self.desc,
                                  unit=self.unit, postfix=self.postfix or None, ncols=0)  # fmt: skip
        self.write(meter)


class Stages:
    """A progress bar (stderr) over the named stages of a command: ``stage(name)`` starts the
    next one, so a slow first run (compiling kernels) shows where it is."""

    def __init__(self, total: int):
        self.bar = progress_bar(total, unit="stage", leave=False,
                                bar_format="{desc}{n_fmt}/{total_fmt} stages [{elapsed}]")  # fmt: skip
        self.started = False

    def __enter__(self) -> Stages:
        return self

    def __call__(self, name: str) -> None:
        """Start stage ``name`` (the previous one is done)."""
        if self.started:
            self.bar.update()
        self.started = True
        self.bar.set_description(name)

    def __exit__(self, *exc) -> None:
        self.bar.update()
        self.bar.close()
