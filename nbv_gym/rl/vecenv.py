"""A ``VecEnv`` of environments in worker processes that import neither torch nor SB3, and the
protocol it shares with the Dask actors of :mod:`nbv_gym.rl.daskvec`.

SB3's ``SubprocVecEnv`` runs its worker function from a module that imports stable-baselines3,
and with it torch, in every worker: ~200 MiB of resident memory per worker that no environment
uses. :class:`LeanSubprocVecEnv` keeps SB3's ``VecEnv`` contract and its worker protocol (step,
reset with seeds and options, ``terminal_observation`` and ``TimeLimit.truncated`` at episode
ends, attributes, methods, wrappers), with the child side in :mod:`nbv_gym.rl.vecworker`. An
exception in an environment is raised in the parent, with the worker's traceback as its cause.
Methods named in ``prefetch`` (``action_masks`` for MaskablePPO) are answered from the last step
or reset, which brought their answers along: one round trip to the workers per step, not two.

Like every ``forkserver`` or ``spawn`` child, a worker imports the parent's main module (as
``__mp_main__``): a script whose top level imports torch or SB3 brings them back into every
worker. ``nbv-gym train``'s main module is its console script, which imports neither; scripts
should import SB3 inside functions (``experiments/worker_rss.py`` does).
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Sequence
from typing import Any

import cloudpickle
import gymnasium
import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from nbv_gym.rl import vecworker


class WorkerTraceback(Exception):
    """The traceback of an exception raised in a worker process (the ``__cause__`` of the
    exception the parent raises)."""

    def __str__(self) -> str:
        return "\n" + self.args[0]


class ProtocolVecEnv(VecEnv):
    """SB3's ``VecEnv`` over environments that answer :func:`nbv_gym.rl.vecworker.answer`'s
    protocol somewhere else; subclasses carry the messages: :meth:`_post` sends a command to
    some environments, :meth:`_collect` returns their answers in order. ``prefetch``: methods
    whose answers (called without arguments) come with every step and reset; :meth:`env_method`
    returns them until the next command reaches the environments."""

    def __init__(self, num_envs: int, prefetch: Sequence[str] = ()):
        self.prefetch = tuple(prefetch)
        self._prefetched: list[dict[str, Any]] = [{} for _ in range(num_envs)]
        self.waiting = self.closed = False
        observation_space, action_space = self._call("get_spaces", None, [0])[0]
        super().__init__(num_envs, observation_space, action_space)

    def _post(self, command: str, data: Sequence[Any], indices: Sequence[int]) -> None:
        """Send ``(command, data[k])`` to environment ``indices[k]``."""
        raise NotImplementedError

    def _collect(self, indices: Sequence[int]) -> list[tuple]:
        """The answers ``(ok, result[, prefetched])`` of the environments ``indices`` to the
        command posted last, in that order."""
        raise NotImplementedError

    def _shutdown(self) -> None:
        """Stop the environments (no command is in flight)."""
        raise NotImplementedError

    def step_async(self, actions: np.ndarray) -> None:
        """Send one action to each worker."""
        self._post("step", list(actions), range(self.num_envs))
        self.waiting = True

    def step_wait(self) -> VecEnvStepReturn:
        """Collect the workers' steps (an ended episode is reset in its worker)."""
        self.waiting = False
        results = self._receive(range(self.num_envs))
        observations, rewards, dones, infos, reset_infos = map(list, zip(*results, strict=True))
        for i, reset_info in enumerate(reset_infos):
            if reset_info is not None:  # the infos of each environment's latest reset
                self.reset_infos[i] = reset_info
        return self._stack(observations), np.stack(rewards), np.stack(dones), infos

    def reset(self) -> VecEnvObs:
        """Reset every environment with its seed and options: the stacked observations."""
        indices = range(self.num_envs)
        self._post("reset", list(zip(self._seeds, self._options, strict=True)), indices)
        observations, reset_infos = map(list, zip(*self._receive(indices), strict=True))
        self.reset_infos = reset_infos
        self._reset_seeds()  # seeds and options serve one reset
        self._reset_options()
        return self._stack(observations)

    def close(self) -> None:
        """Stop the workers (after any step in flight)."""
        if self.closed:
            return
        if self.waiting:
            self._receive(range(self.num_envs), raise_errors=False)
        self._shutdown()
        self.closed = True

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Each environment's rendered picture (None where it renders none)."""
        return self._call("render", None, None)

    def has_attr(self, attr_name: str) -> bool:
        """Whether every environment has attribute ``attr_name``."""
        return all(self._call("has_attr", attr_name, None))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute ``attr_name`` of the environments at ``indices``."""
        return self._call("get_attr", attr_name, indices)

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set attribute ``attr_name`` of the environments at ``indices``."""
        self._call("set_attr", (attr_name, value), indices)

    def env_method(
        self, method_name: str, *method_args, indices: VecEnvIndices = None, **method_kwargs
    ) -> list[Any]:
        """Call ``method_name`` on the environments at ``indices``: their results."""
        indices = list(self._get_indices(indices))
        if not (method_args or method_kwargs):
            if all(method_name in self._prefetched[i] for i in indices):
                return [self._prefetched[i][method_name] for i in indices]
        return self._call("env_method", (method_name, method_args, method_kwargs), indices)

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper], indices: VecEnvIndices = None
    ) -> list[bool]:
        """Whether the environments at ``indices`` are wrapped in ``wrapper_class`` (compared by
        name)."""
        # by name: unpickling the class (SB3's Monitor) would import torch in the workers
        name = (wrapper_class.__module__, wrapper_class.__qualname__)
        return self._call("is_wrapped", name, indices)

    def _call(self, command: str, data: Any, indices: VecEnvIndices) -> list[Any]:
        """Send ``(command, data)`` to the environments ``indices`` and return their answers."""
        indices = list(self._get_indices(indices))
        self._post(command, [data] * len(indices), indices)
        return self._receive(indices)

    def _receive(self, indices, raise_errors: bool = True) -> list[Any]:
        """The answers of the environments ``indices``, all read before the first error is
        raised so that every channel stays in step. Keeps what they prefetched (nothing but
        after a step or reset: any other command may change what the methods answer)."""
        indices = list(indices)
        answers = self._collect(indices)
        for i, (ok, result, *prefetched) in zip(indices, answers, strict=True):
            self._prefetched[i] = prefetched[0] if prefetched else {}
            if not ok and raise_errors:
                error, text = result
                raise error from WorkerTraceback(f"in environment {i}:\n{text}")
        return [result for _, result, *_ in answers]

    def _stack(self, observations: list) -> VecEnvObs:
        """Observations of each environment stacked along a first axis, per key of a ``Dict``
        space or item of a ``Tuple`` space."""
        space = self.observation_space
        if isinstance(space, gymnasium.spaces.Dict):
            return {key: np.stack([o[key] for o in observations]) for key in space.spaces}
        if isinstance(space, gymnasium.spaces.Tuple):
            return tuple(np.stack(items) for items in zip(*observations, strict=True))
        return np.stack(observations)


class LeanSubprocVecEnv(ProtocolVecEnv):
    """The environments built by ``env_fns``, one worker process each, started with
    ``start_method`` (``forkserver``: Embree's thread pool does not survive ``fork``).
    ``prefetch``: methods whose answers (called without arguments) come with every step and
    reset; :meth:`env_method` returns them until the next command reaches the workers."""

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gymnasium.Env]],
        start_method: str = "forkserver",
        prefetch: Sequence[str] = (),
    ):
        # typeshed's BaseContext lacks the Process that every start method's context has
        context: Any = multiprocessing.get_context(start_method)
        self.remotes, self.processes = [], []
        for env_fn in env_fns:
            remote, work_remote = context.Pipe()
            process = context.Process(
                target=vecworker.serve,
                args=(work_remote, remote, cloudpickle.dumps(env_fn), tuple(prefetch)),
                daemon=True,  # a crashed parent leaves no workers behind
            )
            process.start()
            work_remote.close()
            self.remotes.append(remote)
            self.processes.append(process)
        super().__init__(len(env_fns), prefetch)

    def _post(self, command: str, data: Sequence[Any], indices: Sequence[int]) -> None:
        for i, item in zip(indices, data, strict=True):
            self.remotes[i].send((command, item))

    def _collect(self, indices: Sequence[int]) -> list[tuple]:
        return [self._receive_one(i) for i in indices]

    def _shutdown(self) -> None:
        for remote in self.remotes:
            try:
                remote.send(("close", None))
            except OSError:  # that worker has exited already
                pass
        for process in self.processes:
            process.join()
        for remote in self.remotes:
            remote.close()

    def _receive_one(self, i: int) -> tuple:
        """Worker ``i``'s answer."""
        try:
            return self.remotes[i].recv()
        except (EOFError, ConnectionResetError):
            process = self.processes[i]
            process.join(timeout=1.0)
            raise EOFError(
                f"The worker of environment {i} (pid {process.pid}) exited with code "
                f"{process.exitcode}; its output above may say why."
            ) from None
