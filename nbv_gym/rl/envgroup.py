"""The remote side of :class:`~nbv_gym.rl.daskvec.DaskVecEnv`: several environments in one Dask
actor, answering :func:`nbv_gym.rl.vecworker.answer`'s protocol for a batch of them per call.

Like :mod:`~nbv_gym.rl.vecworker`, this module imports neither torch nor stable-baselines3, so a
Dask worker holding environments stays without them. A Dask worker runs all its actors' calls on
one thread: one actor per worker, holding that worker's share of the environments, steps them one
after the other in a single call.

The calls come either as Dask actor calls or, once :meth:`EnvGroup.open_channel` has opened one,
over a direct connection from the learner (a ``multiprocessing`` connection over TCP that the
learner authenticates with a key it sent through Dask): the same pickled requests and answers
without Dask's message layer, which costs the learner several ms of CPU per call.
"""

from __future__ import annotations

import os
import pickle
import socket
import threading
from multiprocessing.connection import Listener
from typing import Any

from nbv_gym.rl.vecworker import answer


class EnvGroup:
    """The environments built by the cloudpickled list of factories ``env_fns``; ``prefetch``
    names the methods whose answers come with every step and reset."""

    def __init__(self, env_fns: bytes, prefetch: tuple[str, ...] = ()):
        self.envs = [env_fn() for env_fn in pickle.loads(env_fns)]
        self.prefetch = tuple(prefetch)
        self._lock = threading.Lock()  # one call at a time, whichever way it came

    def serve(self, command: str, requests: list[tuple[int, Any]]) -> list[tuple]:
        """The answers to ``(command, data)`` of the environments at the positions ``requests``
        names, as ``[(position, data), …]``: one answer each, in that order."""
        with self._lock:
            return [answer(self.envs[k], command, data, self.prefetch) for k, data in requests]

    def open_channel(self, host: str, authkey: bytes) -> tuple[str, int]:
        """Listen on ``host`` (this worker's address) at a free port for one connection that
        proves it holds ``authkey``, and serve ``(command, requests)`` messages on it with
        :meth:`serve` until it closes; the ``(host, port)`` listened on."""
        listener = Listener((host, 0), authkey=authkey)
        threading.Thread(target=self._channel, args=(listener,), daemon=True).start()
        return listener.address

    def _channel(self, listener: Listener) -> None:
        try:
            with listener, listener.accept() as connection:
                no_delay(connection.fileno())
                while True:
                    command, requests = connection.recv()
                    connection.send(self.serve(command, requests))
        except Exception:  # the learner closed its end, or a peer without the key came
            pass

    def close(self) -> None:
        """Close every environment of the group."""
        with self._lock:
            for env in self.envs:
                env.close()


def no_delay(fd: int) -> None:
    """Send every message of the TCP socket ``fd`` at once: a connection sends a message's length
    and its bytes in two writes, which Nagle's algorithm and delayed ACKs would hold ~40 ms."""
    with socket.socket(fileno=os.dup(fd)) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
