"""Connecting to a Dask cluster, for sweeps and for training: a scheduler's address (``tls://``
with Dask's TLS settings) or ``"local"`` for a new LocalCluster of one-thread worker processes
started with :data:`~nbv_gym.core.processes.WORKER_ENVIRONMENT`. Dask is imported inside the
functions (the ``dist`` extra)."""

from __future__ import annotations

import os
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
    try:
        return Client(scheduler, timeout="30s", security=client_security(scheduler)), None
    except (OSError, ValueError) as error:  # unreachable, or not an address
        raise ClusterError(
            f"Cannot reach the Dask scheduler at {scheduler!r}: {error}. Start one with "
            "`dask scheduler` (and `dask worker ADDRESS` on each machine), or use "
            f"--scheduler local.{_TLS_HINT if scheduler.startswith('tls://') else ''}"
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
