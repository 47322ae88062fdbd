"""The policy registry and interface shared by the baselines, trained agents and user code (docs/policies.md).

A policy is any object with ``reset(seed)`` and ``act(observation, info) -> int`` (a goal index)
and, optionally, ``observation_layers``: the names of the optional observation layers it needs
(for example the NBV gain layers), which the environment then computes. Policies are named in a
registry (the seven baselines) or as ``module:Class`` for user code.
"""

from __future__ import annotations

import importlib
import inspect
import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from nbv_gym.core.config import read_toml
from nbv_gym.core.errors import NbvGymError, UnknownNameError
from nbv_gym.core.protocol import check_task

#: Registered policy names → ``module:Class`` of their implementation.
POLICIES: dict[str, str] = {
    "random-frontier": "nbv_gym.policies.frontier:RandomFrontier",
    "closest-frontier": "nbv_gym.policies.frontier:ClosestFrontier",
    "random-free": "nbv_gym.policies.frontier:RandomFree",
    "nbv-nobs": "nbv_gym.policies.nbv:NbvNobs",
    "nbv-rmin": "nbv_gym.policies.nbv:NbvRmin",
    "nbv-nomega": "nbv_gym.policies.nbv:NbvNomega",
    "nbv-sigma": "nbv_gym.policies.nbv:NbvSigma",
    "ig-unknown": "nbv_gym.policies.information_gain:IgUnknown",
    "ig-entropy": "nbv_gym.policies.information_gain:IgEntropy",
    "frontier-tour": "nbv_gym.policies.frontier_tour:FrontierTour",
    "oracle-greedy": "nbv_gym.policies.oracle:OracleGreedy",
    "oracle-time": "nbv_gym.policies.teacher:OracleTime",
}

#: The seven policies of the paper, in its order.
PAPER_POLICIES = ("random-frontier", "closest-frontier", "random-free", "nbv-nobs", "nbv-rmin",
                  "nbv-nomega", "nbv-sigma")  # fmt: skip
#: The field's standard references beside them (``oracle-greedy`` is an oracle).
REFERENCE_POLICIES = ("ig-unknown", "ig-entropy", "frontier-tour", "oracle-greedy")
#: The teachers: oracles that label states for learning (privileged, ranked apart).
TEACHER_POLICIES = ("oracle-time",)


class PolicyError(NbvGymError):
    """A policy could not be loaded, or does not implement the interface."""


@runtime_checkable
class Policy(Protocol):
    """What the environment, ``nbv-gym run`` and ``nbv-gym sweep`` need from a policy."""

    #: Names of the optional observation layers this policy reads (may be empty).
    observation_layers: tuple[str, ...]

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode; all randomness of the policy derives from ``seed``."""

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The goal index (row-major over the 60 × 60 goal grid) to go to next; must be a valid
        goal (``info["action_mask"]``)."""


#: Prefix of a trained stable-baselines3 model: ``"sb3:runs/ppo/best_model.zip"``.
SB3_PREFIX = "sb3:"

#: Trained agents shipped in ``nbv_gym/policies/models/``: short name → model file, each with its
#: config and learning curve beside it. ``"ppo-budget"``: the shipped ``ppo`` training config
#: (MaskablePPO on ``random:mixed`` under the budget task); ``"ppo-time"``: the ``ppo-time``
#: config (the same recipe under the time task, started from ``ppo-budget``).
MODELS: dict[str, str] = {"ppo-budget": "ppo-budget.zip", "ppo-time": "ppo-time.zip"}

#: Registered name prefixes → ``module:Class`` built from the rest of the name (a path).
PREFIXES: dict[str, str] = {SB3_PREFIX: "nbv_gym.rl.agent:SB3Policy"}


def load_policy(name: str, **kwargs: Any) -> Policy:
    """A new policy from a registered name (``"closest-frontier"``), ``"module:Class"``,
    ``"sb3:PATH"`` (a model saved by ``nbv-gym train``) or a shipped model's name
    (:data:`MODELS`); ``kwargs`` go to the class's constructor. A registered name may fix one
    parameter after ``@``, the constructor keyword its class names in ``variant_parameter``
    (default ``visibility``): an NBV policy's visibility model (``"nbv-nobs@fov"``), an
    information-gain policy's λ (``"ig-unknown@0.1"``)."""
    if name in MODELS:
        name = SB3_PREFIX + str(model_path(name))
    for prefix, target in PREFIXES.items():
        if name.startswith(prefix):
            return _import_class(target, name)(name[len(prefix) :], **kwargs)
    base, at, variant = name.partition("@")
    if at and base in POLICIES:
        cls = _import_class(POLICIES[base], base)
        parameter = getattr(cls, "variant_parameter", "visibility")
        if not _has_variant(cls):
            with_variants = sorted(
                n for n, t in POLICIES.items() if _has_variant(_import_class(t, n))
            )
            raise PolicyError(
                f"Policy {name!r}: {base} has no variant after '@' (it takes no parameter); "
                f"the policies that do: {', '.join(with_variants)} (e.g. nbv-nobs@fov, "
                "ig-unknown@0.1)."
            )
        name, kwargs = base, {**kwargs, parameter: variant}
    target = POLICIES.get(name, name)
    if ":" not in target:
        raise UnknownNameError("policy", name, POLICIES)
    if name not in POLICIES:
        add_policy_folders((os.getcwd(),))  # module:Class from the current folder
    cls = _import_class(target, name)
    try:
        policy = cls(**kwargs)
    except Exception as error:
        raise PolicyError(f"Policy {name!r}: its constructor raised {_one_line(error)}") from None
    missing = [m for m in ("reset", "act") if not callable(getattr(policy, m, None))]
    if missing:
        raise PolicyError(
            f"Policy {name!r} does not implement the policy interface: it lacks "
            f"{' and '.join(missing)}(). A policy needs reset(seed) and act(observation, info)."
        )
    return policy


def _has_variant(cls: type) -> bool:
    """Whether a registered policy class takes a parameter after ``@``."""
    return getattr(cls, "variant_parameter", "visibility") in inspect.signature(cls).parameters


def add_policy_folders(folders: Iterable[str]) -> None:
    """Make ``module:Class`` policies importable from ``folders`` (appended to ``sys.path``,
    so they never shadow installed modules). :func:`load_policy` adds the current folder; a
    sweep adds its config's folder, here and in its workers."""
    for folder in map(str, folders):
        if folder not in sys.path:
            sys.path.append(folder)


def model_path(name: str) -> Path:
    """The file of the shipped model ``name`` (:data:`MODELS`) in ``nbv_gym/policies/models/``."""
    return Path(__file__).parent / "models" / MODELS[name]


def trained_task(name: str) -> tuple[str, int] | None:
    """The task and budget (scans, the training config's ``budget_scans``) an agent was trained
    under (:func:`trained_settings`); None for other policies or when no config is found."""
    found = trained_settings(name)
    return None if found is None else (found[1]["task"], found[1]["budget_scans"])


#: What an agent's training config fixes about the episodes it was trained on (besides its
#: task): keys of :class:`~nbv_gym.env.task.TaskConfig`, whose defaults a config that leaves
#: one out meant.
TRAINED_KEYS = ("budget_scans", "lidar", "time_budget_s", "speed_mps", "scan_time_s")


def trained_settings(name: str) -> tuple[Path, dict[str, Any]] | None:
    """The training config of the agent ``name`` and what it fixes about the episodes the agent
    learned from: its task and :data:`TRAINED_KEYS`. The config is
    ``models/NAME.toml`` beside a shipped model, else the ``config.toml`` of the run folder
    ``nbv-gym train`` wrote for an ``sb3:PATH`` model (beside the model, or above its
    ``checkpoints/`` folder; in a packaged folder). None for other policies, or when no config
    with a ``task`` is found."""
    config = training_config_path(name)
    if config is None or not config.is_file():
        return None
    from nbv_gym.core.errors import ConfigError
    from nbv_gym.env.task import TaskConfig

    data = read_toml(config, "Training config")
    if "task" not in data:
        return None
    keys = ("task", "noise", *TRAINED_KEYS, "max_steps", "observation_layers")
    try:
        task = TaskConfig.from_flat({k: data[k] for k in keys if k in data})
    except ConfigError as error:
        raise ConfigError(f"{config}: {error}") from None
    return config, {"task": task.name, **{k: getattr(task, k) for k in TRAINED_KEYS}}


def training_config_path(name: str) -> Path | None:
    """Where the training config of the agent ``name`` would be (:func:`trained_settings`);
    None for a policy that is not a trained agent."""
    if name in MODELS:
        return model_path(name).with_suffix(".toml")
    if not name.startswith(SB3_PREFIX):
        return None
    model = Path(name[len(SB3_PREFIX) :])
    if model.is_dir():  # a packaged folder
        return model / "config.toml"
    folder = model.parent
    return (folder.parent if folder.name == "checkpoints" else folder) / "config.toml"


def episode_task(
    policy: str, task: str | None = None, budget_scans: int | None = None
) -> tuple[str, int | None]:
    """The task to run ``policy`` under and its budget: ``task`` if given, else the task the
    agent was trained under (:func:`trained_task`), else ``"explore"``. The budget is
    ``budget_scans`` if given, else the agent's own when it runs its own task, else None (the
    task's default)."""
    own = trained_task(policy)
    task = task or (own[0] if own else "explore")
    check_task(task)
    if budget_scans is None and own and own[0] == task == "budget":
        budget_scans = own[1]
    return task, budget_scans


def required_layers(policy: object) -> tuple[str, ...]:
    """The optional observation layers ``policy`` declares (none if it declares nothing);
    :class:`PolicyError` unless they are a list or tuple of names."""
    layers = getattr(policy, "observation_layers", ())
    if isinstance(layers, str) or not all(isinstance(name, str) for name in layers):
        raise PolicyError(
            f"Policy {policy_name(policy)} declares observation_layers = {layers!r}; declare "
            f"a tuple of layer names, e.g. ({layers!r},) or ()."
        )
    return tuple(layers)


def is_oracle(policy: object) -> bool:
    """Whether ``policy`` declares that it reads privileged values (``privileged = True``):
    anything computed from the ground truth or the true pose, or the world's name
    (:data:`nbv_gym.env.views.PRIVILEGED_KEYS`). Such a policy is an oracle: the harness hands
    it the full ``info``, and results mark it and rank it apart."""
    return getattr(policy, "privileged", False) is True


def policy_name(policy: object) -> str:
    """``module:Class`` of ``policy``, for messages."""
    kind = type(policy)
    return f"{kind.__module__}:{kind.__qualname__}"


def _import_class(target: str, name: str) -> type:
    module_name, _, class_name = target.partition(":")
    if module_name.split(".")[0] == "baselines":
        moved = "nbv_gym.policies" + module_name[len("baselines") :]
        raise PolicyError(
            f"Policy {name!r}: the shipped policies moved from the package 'baselines' to "
            f"'nbv_gym.policies'; name it {moved}:{class_name} or by its registered name."
        )
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise PolicyError(
            f"Policy {name!r}: cannot import module {module_name!r}: {error}"
        ) from None
    except Exception as error:  # a SyntaxError, or an exception raised at import
        raise PolicyError(
            f"Policy {name!r}: importing module {module_name!r} failed: {_one_line(error)}"
        ) from None
    try:
        return getattr(module, class_name)
    except AttributeError:
        raise PolicyError(
            f"Policy {name!r}: module {module_name!r} has no attribute {class_name!r}."
        ) from None


def _one_line(error: BaseException) -> str:
    """``Type: message`` of ``error`` on one line, with the place of a syntax error."""
    if isinstance(error, SyntaxError):
        return f"SyntaxError: {error.msg} ({error.filename}, line {error.lineno})"
    return f"{type(error).__name__}: {' '.join(str(error).split())}"
