"""Sweep configs (shipped: ``nbv_gym/configs/sweep/*.toml``): which worlds, noise levels, policies and repeats to run.

A sweep is the product worlds × noise × policies × repeats. Every run has a key such as
``pp1-trees/noise1/closest-frontier/rep0`` and a seed derived from the base seed, the world, the
noise level and the repeat with SHA-256 — the policy is left out on purpose, so that all policies
of one (world, noise, repeat) start from the same seed (common random numbers: the first scan is
the same and comparisons between policies are paired).

The ``[env]`` table overrides :class:`~nbv_gym.env.explore.EnvConfig` fields for every run (for
example ``[env.simulator.lidar]`` or ``[env.nbv]``); ``simulator.world``, ``simulator.noise`` and
``simulator.episode.max_steps`` are set by the sweep and may not appear there.
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
from nbv_gym.core.protocol import (
    BUDGET_SCANS,
    EXPLORE_MAX_STEPS,
    NOISE_LEVELS,
    TIME_BUDGET_S,
    check_effort,
    check_noise_level,
    check_task,
    task_episode,
)
from nbv_gym.policies import POLICIES

#: The seven policies of the paper, in its order (the registry's order).

#: The most runs one sweep config may list (worlds × noise × policies × repeats; the paper's
#: sweep has 756), and the most scans per episode: bounds on the work a config can ask for.
MAX_RUNS = 100_000
MAX_STEPS = 10_000
#: Keys of ``[env]`` the sweep sets itself, as dotted paths.
_RESERVED_ENV_KEYS = (
    "simulator.world",
    "simulator.noise",
    "simulator.episode.max_steps",
    "simulator.episode.time_budget_s",
)


@dataclass(frozen=True, kw_only=True)
class SweepConfig:
    """A sweep: every combination of ``worlds`` × ``noise`` × ``policies`` × ``repeats``.

    ``worlds`` (required): benchmark world names or world spec files (``.toml``, relative to the
    config file); ``policies`` (required): registered policy names, ``module:Class`` or a
    trained agent (anything :func:`nbv_gym.policies.load_policy` takes); ``noise``:
    localisation-noise levels (0, 1, 2); ``repeats``: runs per combination; ``seed``: base seed
    of every run seed; ``max_steps``: the episode truncation of the explore task; ``task``:
    ``"explore"`` (the paper's protocol), ``"budget"`` (``budget_scans`` scans, no
    termination, travel free) or ``"time"`` (``time_budget_s`` seconds of robot time, travel
    and scans charged; the effort model's speed and scan time are ``env.simulator.episode``'s
    ``speed_mps`` and ``scan_time_s``; :mod:`nbv_gym.core.protocol`); ``retries``: how many times a failed run is retried
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
    max_steps: int = EXPLORE_MAX_STEPS
    retries: int = 2
    task: str = "explore"
    budget_scans: int = BUDGET_SCANS
    time_budget_s: float = TIME_BUDGET_S
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
        for key in ("max_steps", "budget_scans"):
            value = getattr(self, key)
            check(1 <= value <= MAX_STEPS, key, f"must be from 1 to {MAX_STEPS}, got {value}")
        check(self.retries >= 0, "retries", f"must be ≥ 0, got {self.retries}")
        check_effort("time_budget_s", self.time_budget_s)
        check_task(self.task)
        check(
            0 < self.run_timeout_s < math.inf,
            "run_timeout_s",
            f"must be a number of seconds > 0, got {self.run_timeout_s}",
        )
        self.env_config(self.worlds[0], self.noise[0])  # checks every key of [env]

    def env_config(self, world: str, noise: int):
        """The :class:`~nbv_gym.env.explore.EnvConfig` of one run (``world`` a name or spec path)."""
        from nbv_gym.env.explore import EnvConfig

        for dotted in _RESERVED_ENV_KEYS:
            if _has_path(self.env, dotted):
                key = dotted.rsplit(".", 1)[-1]
                raise ConfigError(
                    f"env.{dotted}: set by the sweep; use the top-level key "
                    f"{'worlds' if key == 'world' else key!r} instead"
                )
        episode_keys = {"max_steps": self.max_steps}
        run = {"simulator": {"world": world, "noise": noise, "episode": episode_keys}}
        config = from_dict(EnvConfig, merge(self.env, run), "env")
        episode = task_episode(
            self.task, config.simulator.episode, self.budget_scans, self.time_budget_s
        )
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
        data = to_dict(self)
        for key in ("name", "worlds", "noise", "policies", "repeats", "retries", "run_timeout_s"):
            data.pop(key)
        return data


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


def read_sweep_config(path: str | Path) -> tuple[SweepConfig, dict[str, Any]]:
    """:func:`load_sweep_config`, and the defaults it filled in for keys the file left out."""
    path = Path(path)
    data = read_toml(path, "Sweep config (see nbv-gym configs list)")
    missing = [key for key in REQUIRED_KEYS if key not in data]
    if missing and set(data) <= {f.name for f in fields(SweepConfig)}:  # unknown keys first
        raise ConfigError(
            f"{path}: missing required key(s) {', '.join(missing)} (e.g. worlds = "
            '["pp1-trees"], policies = ["closest-frontier"]; see nbv-gym configs show quick).'
        )
    data.setdefault("name", path.stem)
    if isinstance(data.get("worlds"), list):
        data["worlds"] = [_resolve_world(w, path.parent) for w in data["worlds"]]
    try:
        config = from_dict(SweepConfig, data)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from None
    filled = {
        key: value
        for key, value in to_dict(config).items()
        if key not in data and key != "env" and TASK_KEYS.get(key, config.task) == config.task
    }
    return config, filled


def with_overrides(config: SweepConfig, **values: Any) -> SweepConfig:
    """``config`` with some top-level fields replaced (None values are ignored)."""
    return replace(config, **{k: v for k, v in values.items() if v is not None})


def with_lidar(config: SweepConfig, lidar: str | None) -> SweepConfig:
    """``config`` with the beam pattern of the lidar preset ``lidar`` in ``[env.simulator.lidar]``
    (unchanged for None, or for the default preset on a config that sets no pattern key); a
    config that sets the beam pattern itself is refused rather than silently overridden."""
    from nbv_gym.sensor.presets import DEFAULT_LIDAR, PATTERN_KEYS, beam_pattern

    if lidar is None:
        return config
    pattern = beam_pattern(lidar)  # an unknown preset fails here, naming the near miss
    table = config.env.get("simulator", {}).get("lidar", {})
    clash = sorted(set(table) & set(PATTERN_KEYS)) if isinstance(table, Mapping) else []
    if clash:
        raise ConfigError(
            f"--lidar {lidar}: the config sets env.simulator.lidar.{clash[0]} itself; drop "
            "--lidar or those keys (the beam pattern has one source)"
        )
    if lidar == DEFAULT_LIDAR:
        return config
    return replace(config, env=merge(config.env, {"simulator": {"lidar": pattern}}))


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
