"""Connecting to a Dask cluster, for sweeps and for training: a scheduler's address (``tls://``
with Dask's TLS settings) or ``"local"`` for a new LocalCluster of one-thread worker processes
started with :data:`~nbv_gym.core.processes.WORKER_ENVIRONMENT`. Dask is imported inside the
functions (the ``dist`` extra).

Every wait on a scheduler is bounded by :data:`SCHEDULER_TIMEOUT_S`: the connection and Dask's
handshake (:func:`check_scheduler_answers`, before the client connects: Dask's own client waits
for the handshake without a bound, and reads a frame of any length a peer announces) and each
call on the client (:func:`ask`). A peer that accepts and never answers, or answers with bytes
that are not Dask's protocol, is one line.
"""

from __future__ import annotations

import asyncio
import os
import threading
from typing import Any

from nbv_gym.core.errors import ClusterError, MissingExtraError
from nbv_gym.core.processes import WORKER_ENVIRONMENT

#: Dask's TLS settings a client of a ``tls://`` scheduler reads: config key → environment
#: variable. The key may be left out when the certificate file holds it too.
TLS_SETTINGS = {
    "distributed.comm.tls.ca-file": "DASK_DISTRIBUTED__COMM__TLS__CA_FILE",
    "distributed.comm.tls.client.cert": "DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT",
    "distributed.comm.tls.client.key": "DASK_DISTRIBUTED__COMM__TLS__CLIENT__KEY",
}
#: The longest wait on a Dask scheduler, s: to connect and read its handshake, and per call.
SCHEDULER_TIMEOUT_S = 30.0
_TLS_HINT = (
    " The scheduler refuses clients whose certificate its CA did not sign: check that the "
    "CA file and the client certificate are the cluster's."
)


def connect(scheduler: str, workers: int) -> tuple[Any, Any]:
    """A Dask ``Client`` of the cluster at ``scheduler`` and the LocalCluster it started (None
    for an address): ``"local"`` starts ``workers`` one-thread worker processes on this
    machine. :class:`ClusterError` when the scheduler cannot be reached or refuses us."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise MissingExtraError("dask[distributed]", "dist") from None
    if scheduler == "local":
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            env=dict(WORKER_ENVIRONMENT),
        )
        return Client(cluster), cluster
    security = client_security(scheduler)
    check_scheduler_answers(scheduler)
    try:
        return Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s", security=security), None
    except (OSError, ValueError) as error:  # unreachable, or not an address
        raise _unreachable(scheduler, error) from None
    except Exception as error:  # answered the handshake, then not as a scheduler does
        raise _foreign(scheduler, error) from None


def check_scheduler_answers(scheduler: str) -> None:
    """Connect to the Dask scheduler at ``scheduler`` and read its handshake, within
    :data:`SCHEDULER_TIMEOUT_S` (and a few seconds' grace); :class:`ClusterError` if it cannot
    be reached, stays silent or answers with something else than Dask's protocol. Runs in a
    thread of its own (its own event loop), so a peer can hold nothing but that thread."""
    try:
        from distributed.comm import connect as comm_connect
    except ImportError:
        raise MissingExtraError("dask[distributed]", "dist") from None

    security = client_security(scheduler)
    arguments = security.get_connection_args("client") if security is not None else {}

    async def handshake() -> None:
        comm = await comm_connect(scheduler, timeout=SCHEDULER_TIMEOUT_S, **arguments)
        await comm.close()

    failed: list[BaseException] = []

    def attempt() -> None:
        try:
            asyncio.run(asyncio.wait_for(handshake(), SCHEDULER_TIMEOUT_S + _GRACE_S))
        except BaseException as error:  # reported by the caller's thread
            failed.append(error)

    thread = threading.Thread(target=attempt, name="nbv-gym-scheduler-check", daemon=True)
    thread.start()
    thread.join(SCHEDULER_TIMEOUT_S + 2 * _GRACE_S)
    error = failed[0] if failed else (TimeoutError() if thread.is_alive() else None)
    if error is None:
        return
    if isinstance(error, TimeoutError):
        raise ClusterError(
            f"The peer at {scheduler!r} accepted the connection but sent no Dask handshake "
            f"within {SCHEDULER_TIMEOUT_S:g} s: it is not a Dask scheduler, or one that does "
            "not answer. Give the address `dask scheduler` printed (its port is 8786 by "
            "default), or use --scheduler local."
        )
    if isinstance(error, (OSError, ValueError)):
        raise _unreachable(scheduler, error)
    raise _foreign(scheduler, error)


#: Seconds beyond :data:`SCHEDULER_TIMEOUT_S` before the handshake check gives up (Dask's own
#: connection timeout fires first when the address cannot be reached at all).
_GRACE_S = 5.0


def _unreachable(scheduler: str, error: BaseException) -> ClusterError:
    return ClusterError(
        f"Cannot reach the Dask scheduler at {scheduler!r}: {error}. Start one with "
        "`dask scheduler` (and `dask worker ADDRESS` on each machine), or use "
        f"--scheduler local.{_TLS_HINT if scheduler.startswith('tls://') else ''}"
    )


def _foreign(scheduler: str, error: BaseException) -> ClusterError:
    message = " ".join(str(error).split())[:160] or "no message"
    return ClusterError(
        f"The peer at {scheduler!r} answered with something that is not Dask's protocol "
        f"({type(error).__name__}: {message}): it is not a Dask scheduler. Give the address "
        "`dask scheduler` printed, or use --scheduler local."
    )


def ask(client: Any, call: str, **kwargs: Any) -> Any:
    """``client.<call>(**kwargs)`` (a Dask client's call that takes Dask's ``callback_timeout``:
    ``nthreads``, ``scheduler_info``), waiting at most :data:`SCHEDULER_TIMEOUT_S`;
    :class:`ClusterError` naming the scheduler when it does not answer in time."""
    try:
        return getattr(client, call)(callback_timeout=SCHEDULER_TIMEOUT_S, **kwargs)
    except TimeoutError:
        raise ClusterError(
            f"The Dask scheduler at {client.scheduler.address} did not answer {call}() within "
            f"{SCHEDULER_TIMEOUT_S:g} s; check it and its network, then rerun the same command."
        ) from None


def describe(scheduler: str, workers: int) -> str:
    """``"Dask LocalCluster of 2 worker(s)"`` or ``"Dask cluster at ADDRESS"``."""
    if scheduler == "local":
        return f"Dask LocalCluster of {workers} worker(s)"
    return f"Dask cluster at {scheduler}"


def client_security(scheduler: str):
    """Dask's ``Security`` for a client of ``scheduler``: for a ``tls://`` address, TLS with the CA
    file, certificate and key of Dask's config (its YAML files or the environment variables of
    :data:`TLS_SETTINGS`); None (Dask's defaults) for other addresses.

    Raises :class:`ClusterError` naming the setting when the CA file or certificate is not set
    or its file does not exist."""
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
            raise ClusterError(
                f"--scheduler {scheduler} needs TLS: Dask's setting {key} {problem}. Set it in "
                f"Dask's config or as ${variable} (see docs/security.md)."
            )
    return Security(require_encryption=True)
