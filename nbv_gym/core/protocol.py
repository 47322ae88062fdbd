"""The benchmark's protocol in one place (docs/protocol.md#tasks): the three tasks and their
Gymnasium ids (registered on ``import nbv_gym``), their numbers, the effort model that charges a
robot's time, the localisation-noise levels and the episode config every task is built from.

- ``explore`` — ``nbv_gym/Explore-v0``, the paper's protocol: an episode terminates at
  :data:`DISCOVERED_TARGET` of the ground discovered and is truncated at
  :data:`EXPLORE_MAX_STEPS` steps.
- ``budget`` — ``nbv_gym/ExploreBudget-v0``, equal scans with travel free: a fixed budget of
  scans (:data:`BUDGET_SCANS` by default), never terminated by the discovered fraction,
  truncated at the budget. The robot teleports, so the budget equalises scans only. The reward
  is ΔQ in both, so a budget episode's return is Q after the budget minus Q after the first
  scan; its score is Q after the budget (and the area under Q against scans).
- ``time`` — ``nbv_gym/ExploreTime-v0``, equal robot time (travel and scans charged): a budget
  of :data:`TIME_BUDGET_S` seconds under the :class:`EffortModel`; a goal whose travel and scan
  would overrun the remaining time is not valid, and the episode ends when no goal fits in
  what is left. Its score is the area under Q against elapsed time and Q at the budget.

The effort model (stated here once): the time a robot has spent after ``scans`` scans that
followed the first one and a path of ``path_m`` metres is ``path_m / speed_mps + scans ·
scan_time_s``. The first scan, taken where the robot starts, is at time 0 (every task counts
scans after the first one).

This module imports nothing heavy: ``import nbv_gym`` reads it to register the ids.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

from nbv_gym.core.config import check
from nbv_gym.core.errors import ConfigError

TASKS = ("explore", "budget", "time")
EXPLORE_ID = "nbv_gym/Explore-v0"
BUDGET_ID = "nbv_gym/ExploreBudget-v0"
TIME_ID = "nbv_gym/ExploreTime-v0"
#: Gymnasium id of each task.
TASK_IDS = {"explore": EXPLORE_ID, "budget": BUDGET_ID, "time": TIME_ID}
#: Truncation of the explore task (``EpisodeConfig.max_steps``).
EXPLORE_MAX_STEPS = 100
#: Default budget of the budget task: scans after the first one. Measured at noise 1 (pp1-cuboids,
#: pp1-trees, pp2-crosses, pp2-helicoids × 2 seeds), the baseline fastest to 70 % discovered,
#: random-frontier, needs 5–11 scans (median 7), random-free a median of 11 (one episode never),
#: closest-frontier 9–23 (median 15): after 12 scans every random-frontier episode has passed 70 %
#: and Q still rises for every policy, so the budget rewards quality per scan, not discovery.
BUDGET_SCANS = 12
#: The voxel edge of the map and of the worlds' ground truth, metres (``MapConfig.resolution_m``).
RESOLUTION_M = 0.1
#: The explore task ends when this fraction of the ground is discovered (the paper's 70 %).
DISCOVERED_TARGET = 0.70
#: What each task charges, for every table and figure that shows its results.
TASK_CHARGES = {
    "explore": f"the paper's protocol: until {DISCOVERED_TARGET * 100:g} % discovered, scans and "
    "travel free",
    "budget": "equal scans, travel free",
    "time": "equal robot time: travel and scans charged",
}
#: (σ_p metres, σ_q radians) of the paper's three localisation-noise levels.
NOISE_LEVELS: dict[int, tuple[float, float]] = {0: (0.0, 0.0), 1: (0.005, 0.005), 2: (0.05, 0.01)}


def check_noise_level(level: object, key: str = "noise") -> None:
    """Raise :class:`ConfigError` (naming ``key``) unless ``level`` is one of :data:`NOISE_LEVELS`."""
    levels = ", ".join(map(str, NOISE_LEVELS))
    check(level in NOISE_LEVELS, key, f"expected one of {levels}, got {level!r}")


#: Driving speed of the effort model, m/s: the Clearpath Husky's top speed (1.0 m/s, Clearpath
#: Robotics' Husky datasheet), the robot of the paper's experiments (Aravecchia et al.,
#: "Next-Best-View selection from observation viewpoint statistics", IROS 2023).
SPEED_MPS = 1.0
#: Time one stop-and-scan costs besides driving, s: stopping from 1 m/s and settling, one
#: stationary revolution of the lidar (0.1 s at 10 Hz), inserting it into the map and choosing
#: the next goal. Chosen, not measured (docs/protocol.md#effort): at 10 s a scan costs as much
#: time as 10 m of driving.
SCAN_TIME_S = 10.0
#: Default budget of the time task, s (docs/protocol.md#effort says why).
TIME_BUDGET_S = 600.0
#: The physically meaningful range (inclusive, with its unit) of each effort value, the one
#: place every entry checks them (the CLI's options, sweep, training and tuning configs, the
#: env's keywords): a robot from 1 cm/s to 100 m/s; a scan free (0 s) to an hour; a time budget
#: from 1 s to a day. Inside them every figure of the clock stays finite (the scan cap of a
#: day at 100 m/s is 8,640,001 scans).
EFFORT_RANGES: dict[str, tuple[float, float, str]] = {
    "speed_mps": (0.01, 100.0, "m/s"),
    "scan_time_s": (0.0, 3600.0, "s"),
    "time_budget_s": (1.0, 86_400.0, "s"),
}


def check_effort(key: str, value: float, name: str | None = None) -> None:
    """Raise :class:`ConfigError` naming ``name`` (default ``key``) unless ``value`` lies in
    ``key``'s range of :data:`EFFORT_RANGES` (NaN never does)."""
    low, high, unit = EFFORT_RANGES[key]
    check(
        low <= value <= high,
        name or key,
        f"must be from {low:,g} to {high:,g} {unit}, got {value}",
    )


@dataclass(frozen=True)
class EffortModel:
    """The time a robot spends: ``path_m / speed_mps + scans · scan_time_s`` (module docstring).

    Args:
        speed_mps: driving speed, m/s (in :data:`EFFORT_RANGES`: 0.01 to 100).
        scan_time_s: the time of one stop-and-scan besides driving, s (0 to 3,600).
    """

    speed_mps: float = SPEED_MPS
    scan_time_s: float = SCAN_TIME_S

    def __post_init__(self) -> None:
        check_effort("speed_mps", self.speed_mps)
        check_effort("scan_time_s", self.scan_time_s)

    def elapsed_s(self, path_m: float, scans: int) -> float:
        """Seconds spent after driving ``path_m`` metres and taking ``scans`` scans (after the
        first)."""
        return path_m / self.speed_mps + scans * self.scan_time_s

    def drive_m(self, seconds: float) -> float:
        """Metres driven in ``seconds`` (the one conversion of time to path: reach included)."""
        return seconds * self.speed_mps

    def scan_cap(self, time_budget_s: float) -> int:
        """A number of scans no episode of ``time_budget_s`` can reach (each goal costs more
        than a scan, since it lies in another cell): the time task's ``max_steps``, a cap that
        never binds."""
        per_scan = max(self.scan_time_s, 1.0 / self.speed_mps)  # every goal is ≥ 1 m away
        return max(1, math.ceil(time_budget_s / per_scan) + 1)


@dataclass(frozen=True)
class TimeBudget:
    """A robot's budget of time under an effort model: the one place that knows whether there
    is a budget and what is left of it.

    Args:
        seconds: the time task's budget, s (in :data:`EFFORT_RANGES`: 1 to 86,400); None in the
            other tasks: nothing runs out, every drive fits and the reach is unlimited (inf).
        effort: the effort model that charges the robot's time.
    """

    seconds: float | None = None
    effort: EffortModel = field(default_factory=EffortModel)

    def __post_init__(self) -> None:
        if self.seconds is not None:
            check_effort("time_budget_s", self.seconds)

    @property
    def limited(self) -> bool:
        """Whether there is a budget (the time task)."""
        return self.seconds is not None

    def remaining_s(self, elapsed_s: Any) -> Any:
        """Seconds left after ``elapsed_s`` (a float or an array of them; inf without a budget,
        negative once overrun)."""
        return math.inf if self.seconds is None else self.seconds - elapsed_s

    def reach_m(self, remaining_s: float) -> float:
        """The longest path, metres, whose drive and a scan fit in ``remaining_s`` seconds
        (inf without a budget; negative when not even a scan fits)."""
        return self.effort.drive_m(remaining_s - self.effort.scan_time_s)

    def fits(self, path_m: float, remaining_s: float) -> bool:
        """Whether a drive of ``path_m`` metres and a scan fit in ``remaining_s`` seconds."""
        return bool(path_m <= self.reach_m(remaining_s))

    def bound_m(self) -> float:
        """A path no valid goal's exceeds: the whole budget driven without a scan, metres (inf
        without a budget)."""
        return math.inf if self.seconds is None else self.effort.drive_m(self.seconds)

    def held(self, remaining_s: Any) -> Any:
        """The share of the budget ``remaining_s`` is (a float or an array; 1 without a budget):
        how long a gain is held, the weight of the time task's reward."""
        return 1.0 if self.seconds is None else remaining_s / self.seconds

    def share(self, seconds: float) -> float:
        """``seconds`` over the budget, at most 1 (a clock's progress; over 1 s without a
        budget)."""
        return min(seconds / (self.seconds or 1.0), 1.0)


@dataclass(frozen=True)
class EpisodeConfig:
    """When an episode ends and how steps are rewarded.

    An episode terminates when the discovered fraction reaches ``discovered_target`` (never when
    it is None: the budget and time tasks) and is truncated after ``max_steps`` steps or when no
    goal is valid. With a ``time_budget_s`` (the time task), a goal whose drive and scan would
    overrun the remaining time is not valid, so the episode ends when the budget is spent.
    Time is charged by the effort model (:class:`EffortModel`) of
    ``speed_mps`` and ``scan_time_s``, in every task. Reward = ΔQ − ``path_penalty_per_m`` · path
    length of the step, ΔQ weighted in the time task by the share of the budget left after it
    (the rewards then sum to the area under Q(t) over the budget). The robot starts at ``start_xy_m`` heading ``start_yaw_rad``.
    """

    max_steps: int = EXPLORE_MAX_STEPS
    discovered_target: float | None = DISCOVERED_TARGET
    path_penalty_per_m: float = 0.0
    start_xy_m: tuple[float, float] = (0.0, 0.0)
    start_yaw_rad: float = 0.0
    time_budget_s: float | None = None
    speed_mps: float = SPEED_MPS
    scan_time_s: float = SCAN_TIME_S

    def __post_init__(self) -> None:
        check(self.max_steps >= 1, "max_steps", "must be ≥ 1")
        check(
            self.discovered_target is None or 0 < self.discovered_target <= 1,
            "discovered_target",
            "must be in (0, 1], or None for no termination",
        )
        check(self.path_penalty_per_m >= 0, "path_penalty_per_m", "must be ≥ 0")
        TimeBudget(self.time_budget_s, EffortModel(self.speed_mps, self.scan_time_s))  # checks

    @cached_property
    def effort(self) -> EffortModel:
        """The effort model of ``speed_mps`` and ``scan_time_s`` (built once)."""
        return EffortModel(self.speed_mps, self.scan_time_s)

    @cached_property
    def budget(self) -> TimeBudget:
        """The time budget of ``time_budget_s`` under :attr:`effort` (built once)."""
        return TimeBudget(self.time_budget_s, self.effort)


def task_episode(
    task: str, episode: Any, budget_scans: int | None = None, time_budget_s: float | None = None
) -> Any:
    """``episode`` (an :class:`EpisodeConfig`) for ``task``: unchanged for
    ``explore``; for ``budget`` without termination and with ``max_steps`` = ``budget_scans``
    (default :data:`BUDGET_SCANS`); for ``time`` without termination, with ``time_budget_s``
    (default: the episode's own, else :data:`TIME_BUDGET_S`) and the scan cap that never binds
    (:meth:`EffortModel.scan_cap`) as ``max_steps``."""
    check_task(task)
    if task == "explore":
        return episode
    if task == "budget":
        return replace(episode, discovered_target=None, max_steps=budget_scans or BUDGET_SCANS)
    budget = time_budget_s or episode.time_budget_s or TIME_BUDGET_S
    cap = episode.effort.scan_cap(budget)
    return replace(episode, discovered_target=None, time_budget_s=budget, max_steps=cap)


def check_task(task: str) -> None:
    """Raise :class:`ConfigError` unless ``task`` is one of :data:`TASKS`."""
    if task not in TASKS:
        raise ConfigError(f"task: expected one of {', '.join(TASKS)}, got {task!r}")
