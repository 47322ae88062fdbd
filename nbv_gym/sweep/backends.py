"""Where runs execute: a local process pool or a Dask cluster, behind one small interface.

A backend accepts :class:`~nbv_gym.sweep.worker.RunTask`s with :meth:`submit` (up to
:attr:`capacity` at a time) and hands back finished ones with :meth:`next_done` as
``(task, outcome)``; ``outcome`` is the dict of :func:`~nbv_gym.sweep.worker.execute_run`, or a
failure record when the worker process died. Worker processes are started with ``forkserver``
(``spawn`` where unavailable) — Embree's thread pool does not survive ``fork`` — and with one
numba thread each.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

from nbv_gym.errors import MissingExtraError
from nbv_gym.sweep.store import SweepError
from nbv_gym.sweep.worker import WORKER_ENVIRONMENT, RunTask, execute_run, failure


class Backend(Protocol):
    """Runs tasks somewhere and reports them back as they finish."""

    description: str

    @property
    def capacity(self) -> int:
        """How many tasks to keep in flight."""

    @property
    def in_flight(self) -> int:
        """Tasks submitted and not yet handed back."""

    def submit(self, task: RunTask) -> None:
        """Start ``task``."""

    def next_done(self) -> tuple[RunTask, dict[str, Any]]:
        """Wait for a task to finish; the task and its outcome."""

    def close(self) -> None:
        """Stop the workers (tasks still in flight are abandoned)."""


def make_backend(workers: int | None, scheduler: str | None) -> Backend:
    """A process pool of ``workers`` processes (default: all cores), or a Dask client of the
    cluster at ``scheduler`` (``"local"``: a new LocalCluster of ``workers`` processes)."""
    workers = workers or os.cpu_count() or 1
    if workers < 1:
        raise SweepError(f"--workers must be ≥ 1, got {workers}")
    if scheduler:
        return DaskBackend(scheduler, workers)
    return PoolBackend(workers)


class PoolBackend:
    """A local pool of worker processes; a dead worker fails the tasks in flight, then the pool
    is restarted."""

    def __init__(self, workers: int):
        self.workers = workers
        self.description = f"local process pool of {workers} worker(s)"
        self._futures: dict[Future, RunTask] = {}
        self._executor: ProcessPoolExecutor | None = None
        self._environment = _worker_environment()
        self._environment.__enter__()

    @property
    def capacity(self) -> int:
        return self.workers

    @property
    def in_flight(self) -> int:
        return len(self._futures)

    def submit(self, task: RunTask) -> None:
        if self._executor is None:
            self._executor = self._start()
        try:
            future = self._executor.submit(execute_run, task)
        except BrokenProcessPool:
            self._executor.shutdown(wait=False, cancel_futures=True)
            self._executor = self._start()
            future = self._executor.submit(execute_run, task)
        self._futures[future] = task

    def next_done(self) -> tuple[RunTask, dict[str, Any]]:
        done, _ = wait(list(self._futures), return_when=FIRST_COMPLETED)
        future = next(iter(done))
        task = self._futures.pop(future)
        try:
            return task, future.result()
        except BrokenProcessPool as error:
            message = "the worker process died (killed, out of memory or a crash in native code)"
            return task, failure(BrokenProcessPool(f"{message}: {error}"))
        except Exception as error:  # e.g. the outcome could not be pickled
            return task, failure(error)

    def close(self) -> None:
        if self._executor is not None:
            self._executor.shutdown(wait=True, cancel_futures=True)
            self._executor = None
        self._environment.__exit__(None, None, None)

    def _start(self) -> ProcessPoolExecutor:
        methods = multiprocessing.get_all_start_methods()
        context = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
        return ProcessPoolExecutor(self.workers, mp_context=context)


class DaskBackend:
    """Tasks on a Dask cluster: an existing scheduler address, or ``"local"`` for a new
    LocalCluster of one-thread worker processes. Workers need nbv-gym installed."""

    def __init__(self, scheduler: str, workers: int):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise MissingExtraError("dask[distributed]", "dist") from None
        self._cluster = None
        if scheduler == "local":
            self._cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env=dict(WORKER_ENVIRONMENT),
            )
            self.client = Client(self._cluster)
            self.description = f"Dask LocalCluster of {workers} worker(s)"
        else:
            try:
                self.client = Client(scheduler, timeout="30s", security=client_security(scheduler))
            except OSError as error:
                raise SweepError(
                    f"Cannot reach the Dask scheduler at {scheduler!r}: {error}. Start one with "
                    "`dask scheduler` (and `dask worker ADDRESS` on each machine), or use "
                    f"--scheduler local.{_TLS_HINT if scheduler.startswith('tls://') else ''}"
                ) from None
            self.description = f"Dask cluster at {scheduler}"
        self._futures: dict[Any, RunTask] = {}

    @property
    def capacity(self) -> int:
        threads = sum(self.client.nthreads().values())
        return max(1, 2 * threads)

    @property
    def in_flight(self) -> int:
        return len(self._futures)

    def submit(self, task: RunTask) -> None:
        future = self.client.submit(execute_run, task, pure=False, retries=0)
        self._futures[future] = task

    def next_done(self) -> tuple[RunTask, dict[str, Any]]:
        from distributed import wait as dask_wait

        done = dask_wait(list(self._futures), return_when="FIRST_COMPLETED").done
        future = next(iter(done))
        task = self._futures.pop(future)
        try:
            outcome = future.result()
        except Exception as error:  # KilledWorker (the worker died) and the like
            outcome = failure(error)
        future.release()
        return task, outcome

    def close(self) -> None:
        for future in self._futures:
            future.cancel()
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


#: Dask's TLS settings a client of a ``tls://`` scheduler reads: config key → environment
#: variable. The key may be left out when the certificate file holds it too.
TLS_SETTINGS = {
    "distributed.comm.tls.ca-file": "DASK_DISTRIBUTED__COMM__TLS__CA_FILE",
    "distributed.comm.tls.client.cert": "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT",
    "distributed.comm.tls.client.key": "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY",
}
_TLS_HINT = (
    " The scheduler refuses clients whose certificate its CA did not sign: check that the "
    "CA file and the client certificate are the cluster's."
)


def client_security(scheduler: str):
    """Dask's ``Security`` for a client of ``scheduler``: for a ``tls://`` address, TLS with the CA
    file, certificate and key of Dask's config (its YAML files or the environment variables of
    :data:`TLS_SETTINGS`); None (Dask's defaults) for other addresses.

    Raises :class:`SweepError` naming the setting when the CA file or certificate is not set or
    its file does not exist."""
    import dask.config
    from distributed.security import Security

    if not scheduler.startswith("tls://"):
        return None
    for key, variable in TLS_SETTINGS.items():
        value = dask.config.get(key, None)
        if value is None and key.endswith(".key"):
            continue  # the certificate file holds the key
        if not value or not os.path.isfile(value):
            problem = "is not set" if not value else f"names {value!r}, which does not exist"
            raise SweepError(
                f"--scheduler {scheduler} needs TLS: Dask's setting {key} {problem}. Set it in "
                f"Dask's config or as ${variable} (see README, Security and trust)."
            )
    return Security(require_encryption=True)


@contextlib.contextmanager
def _worker_environment():
    """Put :data:`WORKER_ENVIRONMENT` into ``os.environ`` while the pool lives (worker processes
    inherit it when they start) and restore the previous values afterwards."""
    previous = {name: os.environ.get(name) for name in WORKER_ENVIRONMENT}
    os.environ.update(WORKER_ENVIRONMENT)
    try:
        yield
    finally:
        for name, value in previous.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
