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
import time
import traceback
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.connection import wait as connection_wait
from typing import Any, Protocol, cast

from nbv_gym.core.cluster import ask, check_scheduler_answers, connect, describe
from nbv_gym.core.processes import worker_environment
from nbv_gym.sweep.folder import SweepError
from nbv_gym.sweep.worker import (
    STARTED,
    RunTask,
    WorkerDiedError,
    execute_run,
    failure,
    serve,
    timed_out,
)


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


def make_backend(workers: int | None, scheduler: str | None, run_timeout_s: float) -> Backend:
    """A process pool of ``workers`` processes (default: all cores), or a Dask client of the
    cluster at ``scheduler`` (``"local"``: a new LocalCluster of ``workers`` processes). A run
    taking longer than ``run_timeout_s`` is stopped and reported as failed."""
    workers = (os.cpu_count() or 1) if workers is None else workers
    if workers < 1:
        raise SweepError(f"--workers must be ≥ 1, got {workers}")
    if scheduler is not None and check_scheduler(scheduler) is not None:
        return DaskBackend(scheduler, workers, run_timeout_s)
    return PoolBackend(workers, run_timeout_s)


#: The Dask schemes a sweep can reach (``inproc://`` lives inside one process only).
SCHEDULER_SCHEMES = ("tcp", "tls")


def check_scheduler(address: str | None) -> str | None:
    """``address`` if it is None (the local process pool), ``"local"`` or
    ``tcp://HOST:PORT`` / ``tls://HOST:PORT`` with a port from 1 to 65535; :class:`SweepError`
    saying what to give otherwise (before any connection is tried)."""
    if address is None or address == "local":
        return address
    usage = (
        "give tcp://HOST:PORT, tls://HOST:PORT or 'local' (leave --scheduler out to run locally)"
    )
    scheme, sep, rest = address.strip().partition("://")
    host, colon, port = rest.rpartition(":")
    if not address.strip():
        raise SweepError(f"--scheduler is empty; {usage}")
    if not sep or scheme not in SCHEDULER_SCHEMES:
        raise SweepError(f"--scheduler {address!r}: unsupported address scheme {scheme!r}; {usage}")
    if not colon or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise SweepError(
            f"--scheduler {address!r}: expected HOST:PORT with a port from 1 to 65535; {usage}"
        )
    return address


def reach_scheduler(address: str | None) -> None:
    """:func:`check_scheduler`, then, for a scheduler's address, that a Dask scheduler answers
    there (:func:`~nbv_gym.core.cluster.check_scheduler_answers`, bounded in time): called
    before a command writes anything."""
    if check_scheduler(address) not in (None, "local"):
        check_scheduler_answers(cast(str, address))


class PoolBackend:
    """A local pool of worker processes, each running one task at a time.

    The pool knows which worker runs which task: a worker that dies (a crash, ``os._exit``,
    ``kill -9``, out of memory) fails only its own task, and a task running longer than
    ``run_timeout_s`` (from when its worker, its imports done, started it) has its worker
    killed and is reported as timed out; either way a new worker takes the freed place.
    Workers exit by themselves when this process dies (see :func:`~nbv_gym.sweep.worker.serve`)."""

    def __init__(self, workers: int, run_timeout_s: float):
        self.workers = workers
        self.run_timeout_s = run_timeout_s
        self.description = f"local process pool of {workers} worker(s)"
        methods = multiprocessing.get_all_start_methods()
        self._context = (
            multiprocessing.get_context("forkserver")
            if "forkserver" in methods
            else multiprocessing.get_context("spawn")
        )
        self._slots: list[_Slot] = []
        # (read end, write end) of the pipe that tells workers we live
        self._alive: tuple[Connection, Connection] | None = None
        self._environment = worker_environment()
        self._environment.__enter__()

    @property
    def capacity(self) -> int:
        """Runs that can be in flight at once: the pool's workers."""
        return self.workers

    @property
    def in_flight(self) -> int:
        """Runs submitted and not yet done."""
        return sum(slot.task is not None for slot in self._slots)

    def submit(self, task: RunTask) -> None:
        """Start ``task`` on an idle worker (a new one if none is idle)."""
        slot = next((s for s in self._slots if s.task is None), None) or self._start_worker()
        slot.connection.send(task)
        slot.task, slot.started = task, None

    def next_done(self) -> tuple[RunTask, dict[str, Any]]:
        """Wait for the next run to end: its task and outcome (a failure if it timed out or its
        worker died)."""
        while True:
            busy = [slot for slot in self._slots if slot.task is not None]  # each holds a task
            ends = {s: s.started + self.run_timeout_s for s in busy if s.started is not None}
            now = time.monotonic()
            late = [slot for slot, end in ends.items() if end <= now]
            if late:
                self._stop(late[0])
                return cast(RunTask, late[0].task), timed_out(self.run_timeout_s)
            waiting = [slot.connection for slot in busy] + [slot.process.sentinel for slot in busy]
            timeout = max(0.0, min(ends.values()) - now) if ends else None
            ready = set(connection_wait(waiting, timeout))
            for slot in busy:
                if slot.connection in ready or slot.process.sentinel in ready:
                    task, outcome = cast(RunTask, slot.task), self._receive(slot)
                    if isinstance(outcome, str):  # STARTED
                        slot.started = time.monotonic()
                        break
                    slot.task = None
                    return task, outcome

    def close(self) -> None:
        """Stop the workers (runs still in flight are abandoned)."""
        for slot in list(self._slots):
            if slot.task is not None:
                self._stop(slot)
            else:
                slot.connection.close()  # an idle worker exits at end-of-file
        for slot in self._slots:
            slot.process.join(5)
            if slot.process.is_alive():
                slot.process.kill()
        self._slots.clear()
        if self._alive is not None:
            for end in self._alive:
                end.close()
            self._alive = None
        self._environment.__exit__(None, None, None)

    def _start_worker(self) -> _Slot:
        if self._alive is None:
            self._alive = self._context.Pipe(duplex=False)
        ours, theirs = self._context.Pipe()
        process = self._context.Process(
            target=serve, args=(theirs, self._alive[0]), name="nbv-gym-worker", daemon=True
        )
        process.start()
        theirs.close()
        slot = _Slot(process, ours)
        self._slots.append(slot)
        return slot

    def _receive(self, slot: _Slot) -> dict[str, Any] | str:
        """What ``slot``'s worker sent (:data:`~nbv_gym.sweep.worker.STARTED` or the outcome),
        or a failure if the worker died."""
        try:
            message = slot.connection.recv()
            return STARTED if message == STARTED else message
        except (EOFError, OSError):
            pass
        except Exception as error:  # the outcome could not be unpickled
            return failure(error, traceback.format_exc())
        slot.process.join(5)
        code = slot.process.exitcode
        self._stop(slot)
        how = f"was killed by signal {-code}" if code and code < 0 else f"exited with code {code}"
        return failure(
            WorkerDiedError(
                f"the worker process running this run {how} (killed, out of memory, os._exit() "
                "or a crash in native code); the other runs went on"
            )
        )

    def _stop(self, slot: _Slot) -> None:
        """Kill ``slot``'s worker and forget it."""
        if slot.process.is_alive():
            slot.process.kill()
            slot.process.join(5)
        slot.connection.close()
        self._slots.remove(slot)


@dataclass(eq=False)
class _Slot:
    """One worker process of a :class:`PoolBackend`, its end of the task connection and the
    task it runs (None when idle) since ``started`` (``time.monotonic()``, None until the
    worker said it started the task)."""

    process: Any
    connection: Any
    task: RunTask | None = None
    started: float | None = None


class DaskBackend:
    """Tasks on a Dask cluster: an existing scheduler address, or ``"local"`` for a new
    LocalCluster of one-thread worker processes. Workers need nbv-gym installed.

    One task per worker thread is in flight, so a task runs from its submission. A run slower
    than ``run_timeout_s`` stops itself after its current step; one stuck inside a step (a
    policy that never returns) is reported as timed out here, and the worker running it is
    restarted (through its nanny; a worker without one keeps the stuck thread). With no worker
    connected for :data:`NO_WORKER_WAIT_S`, :meth:`next_done` gives up with a
    :class:`SweepError`."""

    def __init__(self, scheduler: str, workers: int, run_timeout_s: float):
        self.client, self._cluster = connect(scheduler, workers)
        self.description = describe(scheduler, workers)
        self.scheduler = scheduler
        self.run_timeout_s = run_timeout_s
        self._futures: dict[Any, RunTask] = {}
        self._started: dict[Any, float] = {}
        self._no_workers_since: float | None = None

    @property
    def capacity(self) -> int:
        """Runs that can be in flight at once: the cluster's threads."""
        return max(1, sum(ask(self.client, "nthreads").values()))

    @property
    def in_flight(self) -> int:
        """Runs submitted and not yet done."""
        return len(self._futures)

    def submit(self, task: RunTask) -> None:
        """Submit ``task`` to the cluster."""
        future = self.client.submit(execute_run, task, pure=False, retries=0)
        self._futures[future] = task
        self._started[future] = time.monotonic()

    def next_done(self) -> tuple[RunTask, dict[str, Any]]:
        """Wait for the next run to end: its task and outcome (a failure if it timed out or its
        worker was lost)."""
        from distributed import wait as dask_wait

        while True:
            late = self._late()
            if late is not None:
                return self._futures.pop(late), timed_out(self.run_timeout_s)
            try:
                waited = dask_wait(list(self._futures), _POLL_S, return_when="FIRST_COMPLETED")
            except TimeoutError:
                self._check_workers()
                continue
            future = next(iter(waited.done))
            task = self._futures.pop(future)
            del self._started[future]
            try:
                outcome = future.result()
            except Exception as error:  # KilledWorker (the worker died) and the like
                outcome = failure(error)
            future.release()
            return task, outcome

    def _late(self):
        """A future past its deadline, cancelled and its worker restarted; None if none is."""
        now = time.monotonic()
        late = [f for f, start in self._started.items() if now - start >= self.run_timeout_s]
        if not late or not ask(self.client, "nthreads"):
            return None
        future = late[0]
        del self._started[future]
        workers = [w for w, keys in self.client.processing().items() if future.key in keys]
        future.cancel()
        if workers:
            with contextlib.suppress(Exception):  # a worker without a nanny cannot restart
                self.client.restart_workers(workers, timeout=60)
        return future

    def _check_workers(self) -> None:
        """Raise :class:`SweepError` once no worker has been connected for too long."""
        if ask(self.client, "nthreads"):
            self._no_workers_since = None
            return
        now = time.monotonic()
        self._no_workers_since = self._no_workers_since or now
        if now - self._no_workers_since >= NO_WORKER_WAIT_S:
            raise SweepError(
                f"No Dask worker has been connected to {self.scheduler} for "
                f"{NO_WORKER_WAIT_S:.0f} s, with {len(self._futures)} run(s) waiting. Start "
                "workers (`dask worker ADDRESS --nthreads 1`) and rerun the same command: "
                "finished runs are kept."
            )

    def close(self) -> None:
        """Cancel the runs in flight and disconnect from the cluster."""
        for future in self._futures:
            future.cancel()
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


#: How long a Dask sweep waits with no worker connected before it gives up, seconds.
NO_WORKER_WAIT_S = 120.0
_POLL_S = 5.0  # how often a Dask sweep checks deadlines and workers, seconds
