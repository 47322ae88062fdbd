"""The remote side of :class:`~nbv_gym.rl.daskvec.DaskVecEnv`: several environments in one Dask
actor, answering :func:`nbv_gym.rl.vecworker.answer`'s protocol for a batch of them per call.

Like :mod:`~nbv_gym.rl.vecworker`, this module imports neither torch nor stable-baselines3, so a
Dask worker holding environments stays without them. A Dask worker runs all its actors' calls on
one thread: one actor per worker, holding that worker's share of the environments, steps them one
after the other in a single call.
"""

from __future__ import annotations

import pickle
from typing import Any

from nbv_gym.rl.vecworker import answer


class EnvGroup:
    """The environments built by the cloudpickled list of factories ``env_fns``; ``prefetch``
    names the methods whose answers come with every step and reset."""

    def __init__(self, env_fns: bytes, prefetch: tuple[str, ...] = ()):
        self.envs = [env_fn() for env_fn in pickle.loads(env_fns)]
        self.prefetch = tuple(prefetch)

    def serve(self, command: str, requests: list[tuple[int, Any]]) -> list[tuple]:
        """The answers to ``(command, data)`` of the environments at the positions ``requests``
        names, as ``[(position, data), …]``: one answer each, in that order."""
        return [answer(self.envs[k], command, data, self.prefetch) for k, data in requests]

    def close(self) -> None:
        """Close every environment of the group."""
        for env in self.envs:
            env.close()
