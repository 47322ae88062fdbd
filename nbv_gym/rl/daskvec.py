"""A ``VecEnv`` whose environments live on the workers of a Dask cluster (``nbv-gym train
--scheduler``), the learner staying in this process.

Each worker holds one :class:`~nbv_gym.rl.envgroup.EnvGroup` actor with its share of the
environments. A vector step is one actor call per worker — the actions of its environments in,
their answers out (observations, rewards, infos and the prefetched action masks) — so the learner
pays one round trip per worker and step, as it pays one per process with the local lean workers
(:class:`~nbv_gym.rl.vecenv.LeanSubprocVecEnv`, whose protocol this class shares). The same
factories build the environments and the same seeds reset them: a run trains the same model, bit
for bit, on a cluster as on local workers.

Transport. Unless the scheduler's address is ``tls://``, each actor opens a direct connection
for the learner (:meth:`~nbv_gym.rl.envgroup.EnvGroup.open_channel`, a TCP port of the worker's
host, authenticated with a random key sent through Dask) and the calls go over it, pickled as
to local workers: a Dask actor call costs the learner ~6 ms of CPU in Dask's message layer, a
call over the connection the pickling alone. Over TLS, or when the learner cannot reach the
port within :data:`CONNECT_TIMEOUT_S`, the calls stay Dask actor calls (encrypted as the
cluster is).

Faults. Dask actors do not survive their worker. When a worker is lost (a call to it fails, or it
leaves the scheduler while we wait for it), its environments are built again on the worker with
the fewest environments, reset with new seeds, and their running episodes end at the step being
taken: ``done``, reward 0, ``TimeLimit.truncated`` (the learner bootstraps from the last
observation), ``info["end_reason"] =`` :data:`LOST` and the episode so far in ``info["episode"]``
(so ``episodes.csv`` lists it). A warning is logged; training goes on. With no worker left for
:data:`WORKER_WAIT_S` seconds, :class:`~nbv_gym.core.errors.ClusterError`.
"""

from __future__ import annotations

import logging
import os
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, answer_challenge, deliver_challenge
from typing import Any, cast

import cloudpickle
import gymnasium
import numpy as np

from nbv_gym.core.cluster import ask
from nbv_gym.core.errors import ClusterError
from nbv_gym.rl.envgroup import EnvGroup
from nbv_gym.rl.envs import EPISODE_INFO_KEYS
from nbv_gym.rl.vecenv import ProtocolVecEnv

#: ``info["end_reason"]`` of an episode cut short because its worker was lost.
LOST = "worker lost"
#: How long to wait for a worker when none is left, seconds.
WORKER_WAIT_S = 60.0
#: How often a wait for a worker's answer checks that the worker is still there, seconds.
POLL_S = 1.0
#: How long to wait for a worker's direct connection before falling back to actor calls, s.
CONNECT_TIMEOUT_S = 5.0

log = logging.getLogger(__name__)


class _WorkerLost(Exception):
    """The worker a call or an actor's creation waits for has left the cluster."""


@dataclass(eq=False)
class _Group:
    """Environments ``indices`` in one actor on ``worker`` (``future``: the actor's task;
    ``channel``: the direct connection to the actor, None when calls go through Dask)."""

    indices: list[int]
    worker: str
    actor: Any = None
    future: Any = None
    channel: Connection | None = None


@dataclass(eq=False)
class _Call:
    """A command in flight to ``group``: ``batch`` lists ``(env index, data)``; ``future`` is
    None when the call could not even be sent (its worker is gone)."""

    group: _Group
    command: str
    batch: list[tuple[int, Any]]
    future: Any  # a Dask future, or the group's channel


class DaskVecEnv(ProtocolVecEnv):
    """The environments built by ``env_fns`` on the cluster at ``scheduler`` (an address, or
    ``"local"`` for a LocalCluster of ``local_workers`` processes on this machine; TLS as for
    sweeps, :mod:`nbv_gym.core.cluster`), one actor per worker. ``prefetch`` as for
    :class:`~nbv_gym.rl.vecenv.ProtocolVecEnv`."""

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gymnasium.Env]],
        scheduler: str = "local",
        local_workers: int = 2,
        prefetch: Sequence[str] = (),
    ):
        from nbv_gym.core.cluster import connect, describe

        self.env_fns = list(env_fns)
        self.prefetch = tuple(prefetch)
        self.description = describe(scheduler, local_workers)
        self.direct = not scheduler.startswith("tls://")
        self.client, self.cluster = connect(scheduler, local_workers)
        n = len(self.env_fns)
        self._calls: list[_Call] = []
        self._command = ""
        self._replaced: dict[int, tuple] = {}  # step answers of rebuilt environments
        self._last: list[tuple[Any, dict]] = [(None, {})] * n  # observation, info
        self._episode = [[0.0, 0] for _ in range(n)]  # return and length so far
        self._rebuilt = [0] * n
        self._base_seed = 0
        self._start_time = time.time()
        self.lost_workers: list[str] = []
        try:
            self.groups = self._place(sorted(self._workers(set())))
            self._start(self.groups)
            super().__init__(n, prefetch)
        except BaseException:
            self._disconnect()
            raise

    def seed(self, seed: int | None = None):
        """Seed the environments (environment ``i`` with ``seed + i``) and remember the base seed
        for rebuilt workers."""
        result = super().seed(seed)
        # seed of environment 0 (VecEnv.seed draws one when seed is None)
        self._base_seed = cast(int, self._seeds[0])
        return result

    def worker_of(self, i: int) -> str:
        """The address of the worker holding environment ``i``."""
        return self._group_of[i].worker

    # transport (ProtocolVecEnv)

    def _post(self, command: str, data: Sequence[Any], indices: Sequence[int]) -> None:
        skip = self._replaced if command == "step" else {}
        batch = [(i, item) for i, item in zip(indices, data, strict=True) if i not in skip]
        self._command = command
        self._calls = [self._send(g, command, b) for g, b in self._batches(batch).items()]

    def _collect(self, indices: Sequence[int]) -> list[tuple]:
        answers: dict[int, tuple] = {}
        for call in self._calls:
            answers.update(self._answers(call))
        self._calls = []
        answers.update({i: self._replaced.pop(i) for i in indices if i not in answers})
        self._track(self._command, answers)
        return [answers[i] for i in indices]

    def _shutdown(self) -> None:
        for group in self.groups:
            try:
                group.actor.close().result(timeout=10)
            except Exception:  # the worker is gone already
                pass
            _close(group.channel)
        self._disconnect()

    # placement

    def _place(self, workers: list[str]) -> list[_Group]:
        """The environments in contiguous shares, one group per worker (fewer when there are
        fewer environments than workers)."""
        shares = np.array_split(np.arange(len(self.env_fns)), min(len(workers), len(self.env_fns)))
        return [_Group([int(i) for i in s], w) for s, w in zip(shares, workers, strict=False)]

    def _start(self, groups: list[_Group]) -> None:
        """Create the actors of ``groups`` on their workers (all at once)."""
        for group in groups:
            env_fns = cloudpickle.dumps([self.env_fns[i] for i in group.indices])
            group.future = self.client.submit(
                EnvGroup, env_fns, self.prefetch, actor=True, pure=False,
                workers=[group.worker], allow_other_workers=False,
            )  # fmt: skip
        for group in groups:
            group.actor = self._result(group.future, group.worker)
        if self.direct:
            for group in groups:
                group.channel = self._open_channel(group)
        self._group_of = {i: g for g in self.groups for i in g.indices}

    def _open_channel(self, group: _Group) -> Connection | None:
        """A direct connection to ``group``'s actor (module docstring); None, logged, when the
        worker's address is not TCP or the learner cannot reach the port it listens on."""
        host = group.worker.removeprefix("tcp://").rpartition(":")[0].strip("[]")
        if not group.worker.startswith("tcp://") or not host:
            return None
        authkey = os.urandom(32)
        address = self._result(group.actor.open_channel(host, authkey), group.worker)
        try:
            sock = socket.create_connection(tuple(address), timeout=CONNECT_TIMEOUT_S)
            sock.settimeout(None)  # blocking again: waits poll with POLL_S
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # as no_delay
            channel = Connection(sock.detach())
            answer_challenge(channel, authkey)
            deliver_challenge(channel, authkey)
        except Exception as error:  # a firewall, a closed port: Dask's calls still work
            log.warning(
                "Cannot connect to Dask worker %s at %s:%s directly (%s); its environments "
                "take Dask actor calls (slower).", group.worker, *address, error,
            )  # fmt: skip
            return None
        return channel

    def _batches(self, batch: list[tuple[int, Any]]) -> dict[_Group, list[tuple[int, Any]]]:
        batches: dict[_Group, list[tuple[int, Any]]] = {}
        for i, item in batch:
            batches.setdefault(self._group_of[i], []).append((i, item))
        return batches

    # calls and faults

    def _send(self, group: _Group, command: str, batch: list[tuple[int, Any]]) -> _Call:
        requests = [(group.indices.index(i), item) for i, item in batch]
        try:
            if group.channel is not None:
                group.channel.send((command, requests))
                future = group.channel
            else:
                future = group.actor.serve(command, requests)
        except (RuntimeError, OSError):  # "Worker holding Actor was lost"
            future = None
        return _Call(group, command, batch, future)

    def _answers(self, call: _Call) -> dict[int, tuple]:
        """The answers of ``call``'s environments, by index; when its worker is lost, those of
        the environments rebuilt elsewhere (module docstring)."""
        indices = [i for i, _ in call.batch]
        try:
            if call.future is None:
                raise _WorkerLost
            return dict(zip(indices, self._result(call.future, call.group.worker), strict=True))
        except (_WorkerLost, OSError):
            pass
        group = self._rebuild(call.group, reset=call.command != "reset")
        if call.command == "step":
            return {i: self._replaced.pop(i) for i in indices}
        return self._answers(self._send(group, call.command, call.batch))

    def _result(self, future, worker: str):
        """``future``'s result; :class:`_WorkerLost` once ``worker`` has left the cluster, or
        when the call failed because the worker is closing under it (a cluster scaled down
        answers "cannot schedule new futures after shutdown"). ``future`` may be a group's
        channel: its next message."""
        if isinstance(future, Connection):
            return self._receive_from(future, worker)
        while True:
            try:
                return future.result(timeout=POLL_S)
            except TimeoutError:
                if worker not in ask(self.client, "nthreads"):
                    raise _WorkerLost from None
            except Exception as error:  # the environments' own errors come as answers
                if self._leaving(worker):
                    raise _WorkerLost from error
                raise

    def _receive_from(self, channel: Connection, worker: str):
        """The next message on ``channel``; :class:`_WorkerLost` once it closes or ``worker``
        has left the cluster."""
        try:
            while not channel.poll(POLL_S):
                if worker not in ask(self.client, "nthreads"):
                    raise _WorkerLost
            return channel.recv()
        except (EOFError, OSError):  # the worker's process ended
            raise _WorkerLost from None

    def _leaving(self, worker: str) -> bool:
        """Whether the scheduler lists ``worker`` as gone or closing within :data:`POLL_S`."""
        deadline = time.monotonic() + POLL_S
        while True:
            workers = ask(self.client, "scheduler_info", n_workers=-1)["workers"]
            if workers.get(worker, {}).get("status") != "running":
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.2)

    def _rebuild(self, lost: _Group, reset: bool) -> _Group:
        """Build ``lost``'s environments again on the least loaded remaining worker; with
        ``reset``, reset them and keep the truncation of their episodes as their next step's
        answers."""
        self.groups.remove(lost)
        self.lost_workers.append(lost.worker)
        _close(lost.channel)
        while True:
            group = _Group(lost.indices, self._least_loaded())
            self.groups.append(group)
            try:
                self._start([group])
                break
            except _WorkerLost:
                self.groups.remove(group)
                self.lost_workers.append(group.worker)
        log.warning(
            "Dask worker %s was lost: environment(s) %s rebuilt on %s; their episodes end "
            "truncated (end_reason %r in episodes.csv).",
            lost.worker, lost.indices, group.worker, LOST,
        )  # fmt: skip
        if reset:
            self._reset_rebuilt(group)
        return group

    def _reset_rebuilt(self, group: _Group) -> None:
        for i in group.indices:
            self._rebuilt[i] += 1
        seeds = {i: self._base_seed + i + self.num_envs * self._rebuilt[i] for i in group.indices}
        call = self._send(group, "reset", [(i, (seed, None)) for i, seed in seeds.items()])
        for i, (ok, result, *prefetched) in self._answers(call).items():
            if not ok:
                self._replaced[i] = (ok, result)
                continue
            observation, reset_info = result
            step = (observation, 0.0, True, self._truncated_info(i), reset_info)
            self._replaced[i] = (True, step, *prefetched)
            self._last[i], self._episode[i] = (observation, reset_info), [0.0, 0]

    def _least_loaded(self) -> str:
        """The remaining worker holding the fewest environments; waits up to
        :data:`WORKER_WAIT_S` for one, then :class:`ClusterError`."""
        workers = self._workers(set(self.lost_workers))
        load = {w: sum(len(g.indices) for g in self.groups if g.worker == w) for w in workers}
        return min(sorted(load), key=load.__getitem__)

    def _workers(self, exclude: set[str]) -> list[str]:
        """The cluster's workers but ``exclude``, once there is one (:data:`WORKER_WAIT_S`)."""
        deadline = time.monotonic() + WORKER_WAIT_S
        while True:
            workers = [w for w in ask(self.client, "nthreads") if w not in exclude]
            if workers:
                return workers
            if time.monotonic() >= deadline:
                raise ClusterError(
                    f"No Dask worker is left on the {self.description} (waited "
                    f"{WORKER_WAIT_S:.0f} s; lost: {', '.join(self.lost_workers) or 'none'}). "
                    "Start workers (`dask worker ADDRESS --nthreads 1`) and resume training "
                    "from the last checkpoint (--resume)."
                )
            time.sleep(min(POLL_S, 0.2))

    def _truncated_info(self, i: int) -> dict:
        """The last step's info of environment ``i``, turned into a truncation by a lost
        worker: SB3's ``terminal_observation`` and ``TimeLimit.truncated``, and the episode's
        statistics so far (as :class:`~nbv_gym.rl.envs.EpisodeMonitor` gives them)."""
        observation, info = self._last[i]
        ret, length = self._episode[i]
        episode = {"r": round(ret, 6), "l": length, "t": round(time.time() - self._start_time, 6)}
        episode.update({key: info[key] for key in EPISODE_INFO_KEYS if key in info})
        return {
            **info,
            "end_reason": LOST,
            "episode": episode,
            "terminal_observation": observation,
            "TimeLimit.truncated": True,
        }

    def _track(self, command: str, answers: dict[int, tuple]) -> None:
        """Keep each environment's last observation and info and its episode's return and
        length so far (what :meth:`_truncated_info` needs)."""
        for i, (ok, result, *_) in answers.items():
            if not ok or command not in ("step", "reset"):
                continue
            if command == "reset":
                self._last[i], self._episode[i] = result, [0.0, 0]
                self._replaced.pop(i, None)
                continue
            observation, reward, done, info, reset_info = result
            if done:
                self._last[i], self._episode[i] = (observation, reset_info), [0.0, 0]
            else:
                self._last[i] = (observation, info)
                self._episode[i][0] += float(reward)
                self._episode[i][1] += 1

    def _disconnect(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def _close(channel: Connection | None) -> None:
    """Close ``channel`` (None: nothing); its actor's serving thread then ends."""
    if channel is not None:
        channel.close()
