"""A task's settings, declared once: :class:`TaskConfig` is what ``nbv-gym run``, ``record``,
``train`` and :class:`~nbv_gym.env.explore.ExploreEnv`'s keywords mean by "the task" — which task
(:mod:`nbv_gym.core.protocol`), the localisation noise, the lidar preset, the budget (scans of the
budget task, seconds of the time task), the effort model, the explore task's truncation and the
optional observation layers. It checks them all in one place; every entry point holds one and
builds the environment from it (:meth:`TaskConfig.env_config`, :meth:`TaskConfig.env_kwargs`).

It lives in ``env`` rather than ``core``: a lidar preset's name and a layer name are checked
against the sensor's presets and the env's layers, which ``core`` may not import.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

from nbv_gym.core.config import check, from_dict
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.core.protocol import (
    BUDGET_SCANS,
    EXPLORE_MAX_STEPS,
    SCAN_TIME_S,
    SPEED_MPS,
    TIME_BUDGET_S,
    EffortModel,
    EpisodeConfig,
    check_effort,
    check_noise_level,
    check_task,
    task_episode,
)
from nbv_gym.env.layers import OPTIONAL_LAYERS
from nbv_gym.sensor.presets import DEFAULT_LIDAR, LIDAR_PRESETS

#: The most scans one episode may ask for (a budget or a truncation): a bound on the work.
MAX_SCANS = 10_000
#: Each task's own budget or truncation key (the file key the task's episodes end by).
OWN_KEYS = {"explore": "max_steps", "budget": "budget_scans", "time": "time_budget_s"}


@dataclass(frozen=True)
class TaskConfig:
    """The settings of a task's episodes (in a TOML file, flat keys: ``task`` names
    :attr:`name`, the others are the fields' names).

    - ``name``: ``"explore"`` (the paper's protocol: until 70 % discovered, truncated after
      ``max_steps`` steps), ``"budget"`` (``budget_scans`` scans, no termination, travel free)
      or ``"time"`` (``time_budget_s`` seconds of robot time, travel and scans charged).
    - ``noise``: the localisation-noise level (0, 1, 2).
    - ``lidar``: a lidar preset's name (:mod:`nbv_gym.sensor.presets`).
    - ``budget_scans``: the budget task's budget, scans after the first (1 to 10,000).
    - ``time_budget_s``: the time task's budget, s (1 to 86,400).
    - ``speed_mps``, ``scan_time_s``: the effort model (:class:`EffortModel`), every task's clock.
    - ``max_steps``: the explore task's truncation, steps (1 to 10,000); the budget task ends at
      its budget and the time task when no goal fits in the time left.
    - ``observation_layers``: optional layers the agent observes
      (:data:`~nbv_gym.env.layers.OPTIONAL_LAYERS`).
    """

    name: str = "explore"
    noise: int = 1
    lidar: str = DEFAULT_LIDAR
    budget_scans: int = BUDGET_SCANS
    time_budget_s: float = TIME_BUDGET_S
    speed_mps: float = SPEED_MPS
    scan_time_s: float = SCAN_TIME_S
    max_steps: int = EXPLORE_MAX_STEPS
    observation_layers: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_task(self.name)
        check_noise_level(self.noise)
        if self.lidar not in LIDAR_PRESETS:
            raise ConfigError(f"lidar: {UnknownNameError('lidar', self.lidar, LIDAR_PRESETS)}")
        for key in ("budget_scans", "max_steps"):
            value = getattr(self, key)
            check(1 <= value <= MAX_SCANS, key, f"must be from 1 to {MAX_SCANS:,}, got {value}")
        check_effort("time_budget_s", self.time_budget_s)
        EffortModel(self.speed_mps, self.scan_time_s)  # checks both
        check(
            not isinstance(self.observation_layers, str),
            "observation_layers",
            f"expected a list of layer names, got the string {self.observation_layers!r}",
        )
        unknown = sorted(set(self.observation_layers) - set(OPTIONAL_LAYERS))
        check(
            not unknown,
            "observation_layers",
            f"unknown layer(s) {unknown}; optional layers: {list(OPTIONAL_LAYERS)}",
        )

    @classmethod
    def from_flat(cls, data: Mapping[str, Any], path: str = "") -> TaskConfig:
        """The :class:`TaskConfig` of a file's flat keys (``task`` for :attr:`name`, the other
        fields by name; every key given is one of them). A budget task's ``max_steps`` (its
        old name for the budget) is refused naming ``budget_scans``."""
        data = dict(data)
        if "task" in data:
            data["name"] = data.pop("task")
        if data.get("name") == "budget" and "max_steps" in data:
            where = f"{path}." if path else ""
            raise ConfigError(
                f"{where}max_steps: the budget task's budget is budget_scans now (max_steps "
                f"truncates the explore task); write budget_scans = {data['max_steps']!r}"
            )
        return from_dict(cls, data, path)

    def flat(self) -> dict[str, Any]:
        """The fields as a file's flat keys (:meth:`from_flat` reads them back), but another
        task's budget or truncation (a budget task's file holds no ``max_steps``)."""
        data = {f.name: getattr(self, f.name) for f in fields(self) if self.shapes(f.name)}
        data["task"] = data.pop("name")
        data["observation_layers"] = list(self.observation_layers)
        return data

    @property
    def effort(self) -> EffortModel:
        """The effort model of ``speed_mps`` and ``scan_time_s``."""
        return EffortModel(self.speed_mps, self.scan_time_s)

    def episode(self, base: EpisodeConfig | None = None) -> EpisodeConfig:
        """The :class:`EpisodeConfig` of the task (``base``'s other fields kept)."""
        base = replace(base or EpisodeConfig(), max_steps=self.max_steps,
                       speed_mps=self.speed_mps, scan_time_s=self.scan_time_s)  # fmt: skip
        return task_episode(self.name, base, self.budget_scans, self.time_budget_s)

    def env_config(self, world: str, base: Any = None) -> Any:
        """The :class:`~nbv_gym.env.explore.EnvConfig` of one episode on ``world``: ``base``'s
        (default: the defaults) with the task's noise, lidar, episode and layers."""
        from nbv_gym.env.explore import EnvConfig
        from nbv_gym.sensor.presets import lidar_config

        base = base or EnvConfig()
        simulator = replace(base.simulator, world=world, noise=self.noise,
                            lidar=lidar_config(self.lidar),
                            episode=self.episode(base.simulator.episode))  # fmt: skip
        return replace(base, simulator=simulator, observation_layers=self.observation_layers)

    def shapes(self, key: str) -> bool:
        """Whether the file key ``key`` shapes this task's episodes: another task's budget or
        truncation does not (a config may hold any value of it)."""
        return key not in OWN_KEYS.values() or key == OWN_KEYS[self.name]

    def env_kwargs(self) -> dict[str, Any]:
        """The :class:`~nbv_gym.env.explore.ExploreEnv` keywords of the task (plain values, as
        a recorded dataset stores them): the task, noise, lidar, layers, the effort model and
        the task's own budget or truncation."""
        key = OWN_KEYS[self.name]
        return {"task": self.name, "noise": self.noise, "lidar": self.lidar,
                "observation_layers": tuple(self.observation_layers),
                "speed_mps": self.speed_mps, "scan_time_s": self.scan_time_s,
                key: getattr(self, key)}  # fmt: skip


__all__ = ["MAX_SCANS", "OWN_KEYS", "TaskConfig"]
