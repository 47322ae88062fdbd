"""Worker processes of sweeps and training: the environment they start with."""

from __future__ import annotations

import contextlib
import os
import threading

#: Environment a worker process needs: one numba thread per worker (the pool is the parallelism).
WORKER_ENVIRONMENT = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}


@contextlib.contextmanager
def worker_environment(values: dict[str, str] = WORKER_ENVIRONMENT):
    """Put ``values`` into ``os.environ`` while worker processes start (they inherit it) and
    restore the previous values afterwards: numba refuses a changed NUMBA_NUM_THREADS in a
    process whose threads have started, so the starting process must not keep it."""
    previous = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in previous.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def exit_with_parent(alive) -> None:
    """Make this worker process exit at once, mid-task or not, when ``alive`` (the read end of a
    pipe whose write end only the parent holds) reaches end-of-file: the parent ended, even by
    ``kill -9``. Watches from a daemon thread."""
    threading.Thread(target=_exit_at_end_of_file, args=(alive,), daemon=True).start()


def _exit_at_end_of_file(alive) -> None:
    try:
        alive.poll(None)
    finally:
        os._exit(1)
