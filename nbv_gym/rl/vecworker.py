"""The child side of :class:`~nbv_gym.rl.vecenv.LeanSubprocVecEnv`: one environment served over a
pipe.

This module imports only the standard library and Gymnasium, so a worker process loads neither torch nor
stable-baselines3 (SB3's own worker function lives in a module that imports both: ~200 MiB of
resident memory per worker that no environment uses). The environment factory arrives pickled
(by cloudpickle in the parent); unpickling it imports only what the factory needs.

The protocol (:func:`answer`, which the Dask actors of :mod:`nbv_gym.rl.envgroup` answer too) is
SB3's ``SubprocVecEnv``'s: the parent sends ``(command, data)`` and the worker
answers ``(True, result)``, or ``(False, (exception, traceback text))`` when the environment
raised, so the parent can raise it in turn. Answers to ``step`` and ``reset`` carry a third item:
the answers of the environment's ``prefetch`` methods (for example ``action_masks``, which
MaskablePPO asks for before every step) called with no arguments right after, so the parent
need not ask for them in another round trip.
"""

from __future__ import annotations

import pickle
import sys
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

import gymnasium


def serve(
    remote: Connection, parent_remote: Connection, env_fn: bytes, prefetch: tuple[str, ...] = ()
) -> None:
    """Build the environment from the pickled factory ``env_fn`` and answer the parent's commands
    on ``remote`` until ``close``, the parent's end closing, or an interrupt; ``prefetch`` names
    the methods whose answers come with every step and reset (module docstring)."""
    parent_remote.close()
    env = pickle.loads(env_fn)()
    try:
        while True:
            try:
                command, data = remote.recv()
            except EOFError:
                break
            if command == "close":
                env.close()
                break
            remote.send(answer(env, command, data, prefetch))
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group: the parent handles it
        pass
    finally:
        remote.close()


def answer(env: Any, command: str, data: Any, prefetch: tuple[str, ...] = ()) -> tuple:
    """The answer of ``env`` to ``(command, data)``: ``(True, result)``, with the answers of the
    ``prefetch`` methods as a third item after a step or reset, or ``(False, (exception,
    traceback text))`` when the environment raised (a ``RuntimeError`` holding the exception's
    repr if the exception does not pickle)."""
    try:
        result = COMMANDS[command](env, data)
    except Exception as error:
        return False, _picklable(error, traceback.format_exc())
    if command in ("step", "reset"):
        return True, result, _prefetched(env, prefetch)
    return True, result


def _prefetched(env: Any, names: tuple[str, ...]) -> dict[str, Any]:
    """The answers of the methods ``names`` called with no arguments, leaving out those that
    raise (the parent then calls them and gets the error)."""
    answers = {}
    for name in names:
        try:
            answers[name] = env.get_wrapper_attr(name)()
        except Exception:
            pass
    return answers


def _picklable(error: Exception, text: str) -> tuple[Exception, str]:
    try:
        pickle.dumps(error)
    except Exception:  # send its text
        return RuntimeError(repr(error)), text
    return error, text


def step(env: Any, action: Any) -> tuple:
    """Step with ``action`` in SB3's ``VecEnv`` convention: ``(observation, reward, done, info,
    reset_info)``. At an episode's end ``info`` holds ``terminal_observation`` and the
    environment is reset: ``observation`` and ``reset_info`` are the next episode's first
    (``reset_info`` is None when no reset happened). ``info["TimeLimit.truncated"]`` tells a
    truncation from a termination."""
    observation, reward, terminated, truncated, info = env.step(action)
    done = terminated or truncated
    info["TimeLimit.truncated"] = truncated and not terminated
    reset_info = None
    if done:
        info["terminal_observation"] = observation
        observation, reset_info = env.reset()
    return observation, reward, done, info, reset_info


def reset(env: Any, data: tuple[int | None, dict | None]) -> tuple:
    """Reset with ``data = (seed, options)``; empty options are not passed (as SB3 does)."""
    seed, options = data
    return env.reset(seed=seed, **({"options": options} if options else {}))


def env_method(env: Any, data: tuple[str, tuple, dict]) -> Any:
    """Call the method ``name`` of the environment or its wrappers with ``args``, ``kwargs``."""
    name, args, kwargs = data
    return env.get_wrapper_attr(name)(*args, **kwargs)


def has_attr(env: Any, name: str) -> bool:
    """Whether ``env`` or one of its wrappers has attribute ``name``."""
    try:
        env.get_wrapper_attr(name)
    except AttributeError:
        return False
    return True


def set_attr(env: Any, data: tuple[str, Any]) -> None:
    """Set an attribute of the outermost wrapper (as SB3's workers do)."""
    setattr(env, *data)


def is_wrapped(env: Any, wrapper: tuple[str, str]) -> bool:
    """Whether a wrapper of the class named ``(module, qualified name)`` wraps the environment.
    The parent sends the class by name: unpickling SB3's ``Monitor`` would import torch here. A
    class whose module this process never imported wraps nothing."""
    module, qualname = wrapper
    if module not in sys.modules:
        return False
    wrapper_class: Any = sys.modules[module]
    for part in qualname.split("."):
        wrapper_class = getattr(wrapper_class, part)
    while isinstance(env, gymnasium.Wrapper):
        if isinstance(env, wrapper_class):
            return True
        env = env.env
    return False


#: command name → ``function(env, data)``; ``close`` is handled by :func:`serve`.
COMMANDS: dict[str, Callable[[Any, Any], Any]] = {
    "step": step,
    "reset": reset,
    "render": lambda env, _: env.render(),
    "get_spaces": lambda env, _: (env.observation_space, env.action_space),
    "env_method": env_method,
    "get_attr": lambda env, name: env.get_wrapper_attr(name),
    "has_attr": has_attr,
    "set_attr": set_attr,
    "is_wrapped": is_wrapped,
}
