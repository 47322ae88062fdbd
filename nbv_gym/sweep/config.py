"""Sweep configs (shipped: ``nbv_gym/configs/sweep/*.toml``): which worlds, noise levels, policies and repeats to run.

A sweep is the product worlds × noise × policies × repeats. Every run has a key such as
``pp1-trees/noise1/closest-frontier/rep0`` and a seed derived from the base seed, the world, the
noise level and the repeat with SHA-256 — the policy is left out on purpose, so that all policies
of one (world, noise, repeat) start from the same seed (common random numbers: the first scan is
the same and comparisons between policies are paired).

The task's settings are top-level keys (:class:`~nbv_gym.env.task.TaskConfig`'s, flat: ``task``,
``max_steps``, ``budget_scans``, ``time_budget_s``, ``speed_mps``, ``scan_time_s``, ``lidar``);
``noise`` is the sweep's list of levels. The ``[env]`` table overrides
:class:`~nbv_gym.env.explore.EnvConfig` fields for every run (for example
``[env.simulator.lidar]``'s range or ``[env.nbv]``); the world, the noise and the task's settings
are the sweep's and may not appear there (an old ``[env.simulator.episode]`` key gets one line
naming its top-level key).
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from nbv_gym.core.config import check, from_dict, merge, read_toml, to_dict
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.core.names import check_name
from nbv_gym.core.protocol import NOISE_LEVELS, check_noise_level
from nbv_gym.env.task import MAX_SCANS, TaskConfig
from nbv_gym.policies import POLICIES

#: The seven policies of the paper, in its order (the registry's order).

#: The most runs one sweep config may list (worlds × noise × policies × repeats; the paper's
#: sweep has 756), and the most scans per episode: bounds on the work a config can ask for.
MAX_RUNS = 100_000
MAX_STEPS = MAX_SCANS
#: Keys of ``[env]`` the sweep sets itself, as dotted paths.
_RESERVED_ENV_KEYS = (
    "simulator.world",
    "simulator.noise",
    "simulator.episode.max_steps",
    "simulator.episode.time_budget_s",
    "simulator.episode.speed_mps",
    "simulator.episode.scan_time_s",
)
#: A sweep file's flat keys that are its task's (:class:`~nbv_gym.env.task.TaskConfig`; the
#: sweep's ``noise`` is its grid of levels, the layers are its policies' own).
TASK_FILE_KEYS = ("task", "max_steps", "budget_scans", "time_budget_s", "speed_mps",
                  "scan_time_s", "lidar")  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class SweepConfig:
    """A sweep: every combination of ``worlds`` × ``noise`` × ``policies`` × ``repeats``.

    ``worlds`` (required): benchmark world names or world spec files (``.toml``, relative to the
    config file); ``policies`` (required): registered policy names, ``module:Class`` or a
    trained agent (anything :func:`nbv_gym.policies.load_policy` takes); ``noise``:
    localisation-noise levels (0, 1, 2); ``repeats``: runs per combination; ``seed``: base seed
    of every run seed; ``task``: the task's settings (:class:`~nbv_gym.env.task.TaskConfig`,
    flat keys in the file: ``task`` — ``"explore"``, the default, ``"budget"`` or ``"time"`` —,
    ``max_steps``, ``budget_scans``, ``time_budget_s``, ``speed_mps``, ``scan_time_s``,
    ``lidar``; its ``noise`` is replaced by each of the sweep's); ``retries``: how many times a failed run is retried
    within one invocation; ``run_timeout_s``: wall-clock limit of one run
    (world building included), after which its worker is stopped and the run recorded as failed
    ("timed out after N s"); ``env``: overrides of :class:`~nbv_gym.env.explore.EnvConfig` for
    every run.
    """

    name: str = "sweep"
    worlds: tuple[str, ...]
    noise: tuple[int, ...] = tuple(NOISE_LEVELS)
    policies: tuple[str, ...]
    repeats: int = 3
    seed: int = 0
    retries: int = 2
    task: TaskConfig = field(default_factory=TaskConfig)
    run_timeout_s: float = 1800.0
    env: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_name(self.name, "name")
        check(bool(self.worlds), "worlds", "name at least one world")
        check(bool(self.noise), "noise", "name at least one noise level")
        check(bool(self.policies), "policies", "name at least one policy")
        for i, level in enumerate(self.noise):
            check_noise_level(level, f"noise[{i}]")
        for key in ("worlds", "noise", "policies"):
            values = getattr(self, key)
            duplicates = sorted({str(v) for v in values if values.count(v) > 1})
            check(not duplicates, key, f"lists {', '.join(duplicates)} more than once")
        for i, policy in enumerate(self.policies):
            _check_policy_name(policy, f"policies[{i}]")
        names = [_checked_world_name(world, f"worlds[{i}]") for i, world in enumerate(self.worlds)]
        twice = sorted({n for n in names if names.count(n) > 1})
        check(not twice, "worlds", f"two worlds are named {', '.join(twice)}; rename a spec")
        check(self.repeats >= 1, "repeats", f"must be ≥ 1, got {self.repeats}")
        total = len(self.worlds) * len(self.noise) * len(self.policies) * self.repeats
        check(
            total <= MAX_RUNS,
            "repeats",
            f"the sweep would hold {total:,} runs (worlds × noise × policies × repeats), more "
            f"than {MAX_RUNS:,}; split it into several sweeps",
        )
        check(self.seed >= 0, "seed", f"must be ≥ 0, got {self.seed}")
        check(self.retries >= 0, "retries", f"must be ≥ 0, got {self.retries}")
        check(
            0 < self.run_timeout_s < math.inf,
            "run_timeout_s",
            f"must be a number of seconds > 0, got {self.run_timeout_s}",
        )
        self.env_config(self.worlds[0], self.noise[0])  # checks every key of [env]

    def env_config(self, world: str, noise: int):
        """The :class:`~nbv_gym.env.explore.EnvConfig` of one run (``world`` a name or spec path)."""
        from nbv_gym.env.explore import EnvConfig
        from nbv_gym.sensor.presets import DEFAULT_LIDAR, beam_pattern

        for dotted in _RESERVED_ENV_KEYS:
            if _has_path(self.env, dotted):
                key = dotted.rsplit(".", 1)[-1]
                raise ConfigError(
                    f"env.{dotted}: set by the sweep; use the top-level key "
                    f"{'worlds' if key == 'world' else key!r} instead"
                )
        lidar = self.task.lidar
        _check_one_pattern(self.env, lidar, f"lidar {lidar}")
        pattern = {} if lidar == DEFAULT_LIDAR else {"lidar": beam_pattern(lidar)}
        run = {"simulator": {"world": world, "noise": noise, **pattern}}
        config = from_dict(EnvConfig, merge(self.env, run), "env")
        episode = self.task.episode(config.simulator.episode)
        return replace(config, simulator=replace(config.simulator, episode=episode))

    def runs(self) -> list[RunSpec]:
        """All runs, repeat by repeat (so a partial sweep covers every policy evenly)."""
        names = {world: world_name(world) for world in self.worlds}  # each spec read once
        return [
            RunSpec(
                names[world], world, level, policy, repeat, self._seed(names[world], level, repeat)
            )
            for repeat in range(self.repeats)
            for level in self.noise
            for world in self.worlds
            for policy in self.policies
        ]

    def run_seed(self, world: str, noise: int, repeat: int) -> int:
        """The seed of every run of (``world``, ``noise``, ``repeat``): SHA-256 of the base seed and
        those three, as a 63-bit integer."""
        return self._seed(world_name(world), noise, repeat)

    def _seed(self, name: str, noise: int, repeat: int) -> int:
        text = f"{self.seed}/{name}/noise{noise}/rep{repeat}"
        return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big") >> 1

    def world_digests(self) -> dict[str, str]:
        """World name → content digest of its spec (:meth:`~nbv_gym.worlds.spec.WorldSpec.digest`)."""
        from nbv_gym.worlds import load_spec

        return {world_name(world): load_spec(world).digest() for world in self.worlds}

    def results_fingerprint(self) -> dict[str, Any]:
        """The parts of the config that change a run's result (for resuming into a folder)."""
        data = self.file_dict()
        for key in ("name", "worlds", "noise", "policies", "repeats", "retries", "run_timeout_s"):
            data.pop(key)
        return data

    def file_dict(self) -> dict[str, Any]:
        """The config as its file holds it (:func:`sweep_config` reads it back): the task's
        keys flat beside the others."""
        data, task = to_dict(self), self.task.flat()
        return {**data, **{key: task[key] for key in TASK_FILE_KEYS if key in task}}


@dataclass(frozen=True)
class RunSpec:
    """One run of a sweep: ``world`` (the world's name), ``world_source`` (name or spec path to
    load), ``noise``, ``policy``, ``repeat`` and its ``seed``."""

    world: str
    world_source: str
    noise: int
    policy: str
    repeat: int
    seed: int

    @property
    def key(self) -> str:
        """``world/noiseN/policy/repK``, e.g. ``pp1-trees/noise1/closest-frontier/rep0``."""
        return f"{self.world}/noise{self.noise}/{self.policy}/rep{self.repeat}"

    @property
    def file_stem(self) -> str:
        """A file name for the run: the key made safe, plus a short hash against collisions."""
        safe = re.sub(r"[^A-Za-z0-9._-]+", "_", self.key.replace("/", "__"))
        return f"{safe}--{hashlib.sha256(self.key.encode()).hexdigest()[:8]}"


#: Keys a sweep config file must give (the others have defaults, see :class:`SweepConfig`).
REQUIRED_KEYS = ("worlds", "policies")


def load_sweep_config(path: str | Path) -> SweepConfig:
    """The :class:`SweepConfig` of a TOML file; relative world spec paths are taken relative to
    the file. Raises :class:`ConfigError` naming the file and the offending key."""
    return read_sweep_config(path)[0]


# Keys that only one task reads: under another task, their defaults go unmentioned.
TASK_KEYS = {"max_steps": "explore", "budget_scans": "budget", "time_budget_s": "time"}


def sweep_config(data: Mapping[str, Any]) -> SweepConfig:
    """The :class:`SweepConfig` of a file's table (:meth:`SweepConfig.file_dict`'s shape: the
    task's keys flat)."""
    rest = {key: value for key, value in data.items() if key not in TASK_FILE_KEYS}
    task = TaskConfig.from_flat({k: data[k] for k in TASK_FILE_KEYS if k in data})
    return from_dict(SweepConfig, {**rest, "task": to_dict(task)})


def read_sweep_config(path: str | Path) -> tuple[SweepConfig, dict[str, Any]]:
    """:func:`load_sweep_config`, and the defaults it filled in for keys the file left out."""
    path = Path(path)
    data = read_toml(path, "Sweep config (see nbv-gym configs list)")
    missing = [key for key in REQUIRED_KEYS if key not in data]
    known = {f.name for f in fields(SweepConfig)} | set(TASK_FILE_KEYS)
    if missing and set(data) <= known:  # unknown keys first
        raise ConfigError(
            f"{path}: missing required key(s) {', '.join(missing)} (e.g. worlds = "
            '["pp1-trees"], policies = ["closest-frontier"]; see nbv-gym configs show quick).'
        )
    data.setdefault("name", path.stem)
    if isinstance(data.get("worlds"), list):
        data["worlds"] = [_resolve_world(w, path.parent) for w in data["worlds"]]
    try:
        config = sweep_config(data)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None
    task = config.task.name
    filled = {
        key: value
        for key, value in config.file_dict().items()
        if key not in data
        and key not in ("env", "speed_mps", "scan_time_s", "lidar")
        and TASK_KEYS.get(key, task) == task
    }
    return config, filled


def with_overrides(config: SweepConfig, **values: Any) -> SweepConfig:
    """``config`` with some top-level fields replaced (None values are ignored)."""
    return replace(config, **{k: v for k, v in values.items() if v is not None})


def with_lidar(config: SweepConfig, lidar: str | None) -> SweepConfig:
    """``config`` with the lidar preset ``lidar`` (``--lidar``; unchanged for None); a config
    that sets the beam pattern itself (``[env.simulator.lidar]``) is refused rather than
    silently overridden."""
    if lidar is None:
        return config
    changed = replace(config, task=replace(config.task, lidar=lidar))  # checks the name
    _check_one_pattern(config.env, lidar, f"--lidar {lidar}", always=True)
    return changed


def _check_one_pattern(env: Mapping[str, Any], lidar: str, given: str, always=False) -> None:
    """:class:`ConfigError` when ``[env.simulator.lidar]`` sets a beam-pattern key and a
    lidar preset other than the default (or, ``always``, any preset) is ``given``."""
    from nbv_gym.sensor.presets import DEFAULT_LIDAR, PATTERN_KEYS

    table = env.get("simulator", {}).get("lidar", {})
    clash = sorted(set(table) & set(PATTERN_KEYS)) if isinstance(table, Mapping) else []
    if clash and (always or lidar != DEFAULT_LIDAR):
        option = given.split()[0]
        raise ConfigError(
            f"{given}: the config sets env.simulator.lidar.{clash[0]} itself; drop "
            f"{option} or those keys (the beam pattern has one source)"
        )


def world_name(world: str) -> str:
    """The name of a benchmark world or of the world in a spec file."""
    if world.endswith(".toml"):
        from nbv_gym.worlds import load_spec

        return load_spec(world).name
    return world


def dumps_toml(data: Mapping[str, Any]) -> str:
    """``data`` (nested tables of strings, numbers, booleans and lists of them) as TOML text."""
    lines: list[str] = []
    _dump_table(data, "", lines)
    return "\n".join(lines).lstrip("\n") + "\n"


def _dump_table(data: Mapping[str, Any], prefix: str, lines: list[str]) -> None:
    tables = {k: v for k, v in data.items() if isinstance(v, Mapping)}
    for key, value in data.items():
        if key not in tables:
            lines.append(f"{_toml_key(key)} = {_toml_value(value)}")
    for key, value in tables.items():
        name = f"{prefix}.{_toml_key(key)}" if prefix else _toml_key(key)
        lines.extend(["", f"[{name}]"])
        _dump_table(value, name, lines)


def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_value(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise ConfigError(f"cannot write {type(value).__name__} {value!r} to TOML")


def _check_policy_name(name: str, key: str) -> None:
    from nbv_gym.policies import MODELS

    if name.partition("@")[0] not in POLICIES and name not in MODELS and ":" not in name:
        try:
            raise UnknownNameError("policy", name, POLICIES)
        except UnknownNameError as error:
            raise ConfigError(f"{key}: {error} Or give module:Class for your own policy.") from None


def _checked_world_name(world: str, key: str) -> str:
    from nbv_gym.core.errors import NbvGymError
    from nbv_gym.worlds import load_spec
    from nbv_gym.worlds.distribution import is_distribution

    if is_distribution(world):
        raise ConfigError(
            f"{key}: {world!r} is a world distribution; a sweep runs fixed worlds (benchmark "
            "names such as 'pp1-trees', or spec files), so that every run can be repeated and "
            "paired across policies. Distributions are for training (train_worlds) and the env."
        )

    try:
        return load_spec(world).name
    except NbvGymError as error:
        raise ConfigError(f"{key}: {error}") from None


def _resolve_world(world: Any, base: Path) -> Any:
    if isinstance(world, str) and world.endswith(".toml") and not Path(world).is_absolute():
        return str((base / world).resolve())
    return world


def _has_path(data: Mapping[str, Any], dotted: str) -> bool:
    head, _, rest = dotted.partition(".")
    if head not in data:
        return False
    return not rest or (isinstance(data[head], Mapping) and _has_path(data[head], rest))
