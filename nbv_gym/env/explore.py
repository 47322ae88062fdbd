"""``nbv_gym/Explore-v0``, ``nbv_gym/ExploreBudget-v0`` and ``nbv_gym/ExploreTime-v0``
(:mod:`nbv_gym.core.protocol`): the Gymnasium environment around the
:class:`~nbv_gym.simulator.Simulator`.

Action: ``Discrete(nx · ny)``, a goal cell of G's nx × ny x, y cells (row-major; 60 × 60 = 3600 on
every world of a 60 m window, more on larger worlds: ``MappingConfig.fit_to_world``);
``action_masks()`` and ``info["action_mask"]`` give the valid goals as (n,) int8 (Gymnasium's mask
type), and an
invalid goal raises :class:`~nbv_gym.simulator.InvalidActionError` — or snaps to the nearest
valid goal with ``invalid_action="snap"`` (:mod:`nbv_gym.env.actions`). ``action_space.sample()``
draws a valid goal. Through wrappers: ``env.get_wrapper_attr("action_masks")()``.
Observation: see :mod:`nbv_gym.env.observation`. Reward: ΔQ (minus the optional path penalty).
The world is a benchmark name, a spec file or a distribution ``random:<kind>``
(:mod:`nbv_gym.worlds.distribution`), which draws a world from its pool at every reset.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from nbv_gym.core.config import check, from_dict, merge, to_dict
from nbv_gym.core.errors import ConfigError
from nbv_gym.core.protocol import TASK_IDS, EpisodeConfig, check_task, task_episode
from nbv_gym.env import observation
from nbv_gym.env.actions import INVALID_ACTIONS, resolve_goal
from nbv_gym.env.layers import OPTIONAL_LAYERS, OptionalLayers
from nbv_gym.nbv import NbvConfig
from nbv_gym.sensor.presets import beam_pattern
from nbv_gym.simulator import (
    ResetNeededError,
    Simulator,
    SimulatorConfig,
    StepOutcome,
    goal_index,
)
from nbv_gym.worlds.distribution import POOL_SIZE, WorldDistribution, is_distribution


@dataclass(frozen=True)
class EnvConfig:
    """Configuration of ``Explore-v0``: the simulator, the optional observation layers (names in
    :data:`nbv_gym.env.layers.OPTIONAL_LAYERS`, e.g. the NBV gain layers), the NBV gain
    prediction behind them, what an invalid goal does (``invalid_action``, one of
    :data:`~nbv_gym.env.actions.INVALID_ACTIONS`), and for a world distribution
    (``simulator.world`` = ``random:…``) its pool size (``world_pool_size``) and the episodes
    run on each drawn world before the next draw (``episodes_per_world``: a switch costs ~1.8 s
    CPU on worlds with trees, the Embree scene, so training on short episodes may draw less
    often)."""

    simulator: SimulatorConfig = field(default_factory=SimulatorConfig)
    observation_layers: tuple[str, ...] = ()
    nbv: NbvConfig = field(default_factory=NbvConfig)
    invalid_action: str = "raise"
    world_pool_size: int = POOL_SIZE
    episodes_per_world: int = 1

    def __post_init__(self) -> None:
        check(
            self.invalid_action in INVALID_ACTIONS,
            "invalid_action",
            f"expected one of {', '.join(INVALID_ACTIONS)}, got {self.invalid_action!r}",
        )
        check(self.world_pool_size >= 1, "world_pool_size", "must be ≥ 1")
        check(self.episodes_per_world >= 1, "episodes_per_world", "must be ≥ 1")
        check(
            not isinstance(self.observation_layers, str),
            "observation_layers",
            f"expected a list of layer names, got the string {self.observation_layers!r}; "
            f"write ({self.observation_layers!r},)",
        )
        unknown = sorted(set(self.observation_layers) - set(OPTIONAL_LAYERS))
        check(
            not unknown,
            "observation_layers",
            f"unknown layer(s) {unknown}; optional layers: {list(OPTIONAL_LAYERS)}",
        )


class GoalSpace(spaces.Discrete):
    """``Discrete(n)`` whose ``sample()`` (without a mask) draws a goal that is valid now.

    Among the valid goals it draws from those that were also valid right after the episode's
    reset, when there are any (after the episode's end, from those): Gymnasium's env checker
    samples an action in one state and steps it after a new seeded reset, which only works for
    goals valid at every start.
    """

    def __init__(self, n: int, seed: int | None = None):
        super().__init__(n, seed=seed)
        self._mask_source: Callable[[], np.ndarray | None] | None = None

    def bind(self, mask_source: Callable[[], np.ndarray | None]) -> None:
        """Use ``mask_source()`` as the default mask of :meth:`sample`."""
        self._mask_source = mask_source

    def sample(self, mask=None, probability=None):
        """A random goal: among the bound source's valid goals when no mask or probability is
        given."""
        if mask is None and probability is None and self._mask_source is not None:
            current = self._mask_source()
            if current is not None and current.any():
                mask = current.astype(np.int8)
        return super().sample(mask=mask, probability=probability)

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_mask_source"] = None  # the space travels alone (e.g. to another process)
        return state


class ExploreEnv(gymnasium.Env):
    """Explore a world with a teleporting lidar robot; reward = improvement of map quality Q
    (in the time task weighted by the share of the budget left: the return is the area under Q(t)).

    Args:
        render_mode: None or "rgb_array".
        config: an :class:`EnvConfig` (or a dict of its fields).
        task: ``"explore"`` (the paper's protocol), ``"budget"`` (``budget_scans`` scans, no
            termination) or ``"time"`` (a time budget: travel and scans charged;
            :mod:`nbv_gym.core.protocol`); ``nbv_gym/ExploreBudget-v0`` and
            ``nbv_gym/ExploreTime-v0`` set it. In the time task ``info`` also holds the robot's
            clock, ``elapsed_s`` and ``remaining_s``.
        time_budget_s, speed_mps, scan_time_s: the time task's budget (s) and the effort model's
            speed (m/s) and scan time (s), shortcuts for ``simulator.episode``'s fields (the
            speed and scan time charge time in every task; a budget is the time task's).
        world, noise, max_steps, observation_layers, invalid_action, world_pool_size, episodes_per_world: shortcuts overriding the config's ``simulator.world``,
            ``simulator.noise``, ``simulator.episode.max_steps``, ``observation_layers``,
            ``invalid_action``, ``world_pool_size`` and ``episodes_per_world``. The registered
            ids set no ``max_episode_steps``: ``max_steps`` (and the time budget) is the one
            truncation. ``max_steps`` truncates the explore and time tasks; the budget task's
            budget is ``budget_scans`` (default :data:`~nbv_gym.core.protocol.BUDGET_SCANS`),
            and a ``max_steps`` given to it is refused naming ``budget_scans``.
        budget_scans: the budget task's budget in scans after the first (other tasks: refused).
        lidar: a lidar preset name (:mod:`nbv_gym.sensor.presets`, e.g. ``"vlp-16"``) whose
            beam pattern (channels, elevations, azimuth samples) replaces the config's.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 2}  # noqa: RUF012 (gymnasium.Env declares it an instance attribute)

    def __init__(
        self,
        render_mode: str | None = None,
        config: EnvConfig | Mapping[str, Any] | None = None,
        *,
        task: str = "explore",
        world: str | None = None,
        noise: int | None = None,
        max_steps: int | None = None,
        budget_scans: int | None = None,
        observation_layers: tuple[str, ...] | list[str] | None = None,
        invalid_action: str | None = None,
        world_pool_size: int | None = None,
        episodes_per_world: int | None = None,
        time_budget_s: float | None = None,
        speed_mps: float | None = None,
        scan_time_s: float | None = None,
        lidar: str | None = None,
    ):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise gymnasium.error.Error(
                f"render_mode must be None or 'rgb_array', got {render_mode!r}"
            )
        shortcuts = {
            "invalid_action": invalid_action,
            "world_pool_size": world_pool_size,
            "episodes_per_world": episodes_per_world,
        }
        effort = {
            "time_budget_s": time_budget_s,
            "budget_scans": budget_scans,
            "speed_mps": speed_mps,
            "scan_time_s": scan_time_s,
        }
        self.config = resolve_config(
            config, task, world, noise, max_steps, observation_layers, shortcuts, effort, lidar
        )
        self.render_mode = render_mode
        self.worlds, self._world_index, self._world_episodes = _distribution(self.config), 0, 0
        first = self.worlds.world(0) if self.worlds else None
        self.sim = Simulator(self.config.simulator, world=first)
        self.optional = OptionalLayers(self.sim, self.config.observation_layers, self.config.nbv)
        mapping, episode = self.config.simulator.mapping, self.config.simulator.episode
        self.observer = observation.Observer(
            self.sim.goal_grid,
            mapping.sensor_range_m,
            mapping.statistics.n_sectors,
            episode.max_steps,
            episode.budget,
        )
        self.action_space = GoalSpace(self.sim.n_goals)
        self.action_space.bind(self._current_mask)
        cost_high = self.observer.cost_high(mapping.navigation.cost_range_m)
        self.observation_space = observation.observation_space(
            self.sim.n_goals, self.optional.bounds(), cost_high
        )
        self._last: StepOutcome | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode (on the next world of a distribution when due): ``(observation,
        info)``."""
        if options is not None and not isinstance(options, dict):
            raise ConfigError(
                f"reset(options=...): expected a dict or None, got {type(options).__name__} "
                f"{options!r}; ExploreEnv.reset takes no options (choose worlds and budgets in "
                "the config)"
            )
        if options:  # none are supported: an option that does nothing must not pass unnoticed
            raise ConfigError(
                f"reset(options=...): unknown option(s) {sorted(map(str, options))}; "
                "ExploreEnv.reset takes no options (choose worlds and budgets in the config)"
            )
        super().reset(seed=seed)
        if self.worlds is not None and self._world_episodes % self.config.episodes_per_world == 0:
            self._draw_world(self.worlds)
        self._world_episodes += 1
        episode_seed = int(self.np_random.integers(2**63 - 1))
        self._last = self.sim.reset(episode_seed)
        self._start_mask = self.sim.goal_mask()
        self.optional.reset()
        return self._observation(), self._info()

    def step(self, action):
        """Move to goal ``action`` (snapped or refused per ``invalid_action``), scan, update:
        Gymnasium's 5-tuple."""
        goal, snapped = goal_index(action, self.sim.n_goals), False
        if self.sim.state is not None:
            mask, shape = self.sim.goal_mask(), self.sim.goal_grid.shape[:2]
            goal, snapped = resolve_goal(goal, mask, self.config.invalid_action, shape)
        outcome = self.sim.step(goal)
        self._last = outcome
        return (
            self._observation(),
            float(outcome.reward),
            outcome.terminated,
            outcome.truncated,
            {**self._info(), "goal": goal, "snapped": snapped},
        )

    def action_masks(self) -> np.ndarray:
        """(n_goals,) int8: 1 for the valid goals (sb3-contrib's MaskablePPO reads this; through
        Gymnasium wrappers call ``env.get_wrapper_attr("action_masks")()``)."""
        return self.sim.goal_mask().astype(np.int8)

    def render(self):
        """The (h, w, 3) uint8 picture of :func:`~nbv_gym.env.render.render_rgb` with
        ``render_mode='rgb_array'``, else None."""
        if self.render_mode == "rgb_array":
            from nbv_gym.env.render import render_rgb

            return render_rgb(self.sim)
        return None

    def _draw_world(self, worlds: WorldDistribution) -> None:
        """Switch to a world drawn from the distribution's pool (kept if drawn again)."""
        index = worlds.draw(self.np_random)
        if index != self._world_index:
            self.sim.set_world(worlds.world(index))
            self._world_index = index

    def _current_mask(self) -> np.ndarray | None:
        """Valid goals, narrowed to those also valid at the episode's start if any are; when
        none is valid now (the episode is over, e.g. its time budget spent), those valid at its
        start (a sample meant for the next episode, as Gymnasium's checker takes one)."""
        if self.sim.state is None:
            return None
        mask = self.sim.goal_mask()
        stable = mask & self._start_mask
        return stable if stable.any() else mask if mask.any() else self._start_mask

    @property
    def _outcome(self) -> StepOutcome:
        """The last step's outcome; :class:`ResetNeededError` before a reset."""
        if self._last is None:
            raise ResetNeededError("Call reset() first.")
        return self._last

    def _observation(self) -> dict[str, np.ndarray]:
        sim = self.sim
        optional = self.optional.compute(self._outcome)
        return self.observer.observe(
            sim.navigation, sim.statistics, sim.pose, sim.steps, optional, sim.elapsed_s
        )

    def _info(self) -> dict[str, Any]:
        outcome, sim = self._outcome, self.sim
        quality = outcome.quality
        return {
            "action_mask": sim.goal_mask().astype(np.int8),
            "world": sim.world.name,
            "goal": -1,
            "snapped": False,
            "discovered": outcome.discovered,
            "q": quality.q,
            "q_paper": quality.q_paper,
            "q_observed": quality.q_observed,
            "cov": quality.cov,
            "l1": quality.l1,
            "delta_q": outcome.delta_q,
            "path_penalty": sim.config.episode.path_penalty_per_m * outcome.path_length_m,
            "step_path_length_m": outcome.path_length_m,
            "path_length_m": sim.path_length_m,
            "steps": sim.steps,
            "true_pose": np.array(_pose_tuple(outcome.scan.true_pose)),
            "estimated_pose": np.array(_pose_tuple(outcome.scan.pose)),
            "end_reason": outcome.reason,
            "goal_grid_shape": sim.goal_grid.shape[:2],
            "goal_cell_m": sim.goal_grid.res,
            "cost_range_m": sim.config.mapping.navigation.cost_range_m,
            **self._clock(),
            **self.optional.calibration(),
        }

    def _clock(self) -> dict[str, float]:
        """The time task's ``elapsed_s`` and ``remaining_s`` (none in the other tasks, whose
        ``info`` stays as pinned; their elapsed time is the steps table's)."""
        if not self.config.simulator.episode.budget.limited:
            return {}
        return {"elapsed_s": self.sim.elapsed_s, "remaining_s": self.sim.remaining_s}


def _pose_tuple(pose) -> tuple[float, float, float, float]:
    return pose.x, pose.y, pose.z, pose.yaw


def resolve_config(
    config, task, world, noise, max_steps, observation_layers, shortcuts, effort, lidar=None
) -> EnvConfig:
    """The :class:`EnvConfig` of ``config`` for ``task`` with the keyword shortcuts applied.
    The keywords go through the same typed checks as a config dict (:func:`from_dict`):
    ``max_steps=2.5`` or ``noise=True`` is refused naming the key, never coerced."""
    if config is not None and not isinstance(config, (EnvConfig, Mapping)):
        raise ConfigError(f"config: expected an EnvConfig or a dict of its fields, got {config!r}")
    world = str(world) if isinstance(world, os.PathLike) else world
    one_name = isinstance(observation_layers, str)  # refused by EnvConfig with a hint, below
    sensor = None if lidar is None else beam_pattern(lidar)
    effort = dict(effort)
    budget_scans = effort.pop("budget_scans", None)
    _check_task_keywords(task, max_steps, budget_scans, effort.get("time_budget_s"))
    keywords = {
        "simulator": {
            "world": world,
            "noise": noise,
            "episode": {"max_steps": max_steps, **effort},
            "lidar": sensor,
        },
        "observation_layers": None if one_name else observation_layers,
        **shortcuts,
    }
    given = _given(keywords)
    if isinstance(config, EnvConfig) and not given:
        resolved = config
    else:
        base = to_dict(config) if isinstance(config, EnvConfig) else dict(config or {})
        resolved = from_dict(EnvConfig, merge(base, given))
    if one_name:
        resolved = replace(resolved, observation_layers=observation_layers)
    episode = resolved.simulator.episode
    episode = task_episode(task, episode, budget_scans)
    if max_steps is not None:
        episode = replace(episode, max_steps=max_steps)
    return replace(resolved, simulator=replace(resolved.simulator, episode=episode))


def _check_task_keywords(
    task: str, max_steps: int | None, budget_scans: int | None, time_budget_s: float | None
) -> None:
    """Refuse a budget keyword of another task than ``task``, naming the one to give."""
    if max_steps is not None and task == "budget":
        raise ConfigError(
            f"max_steps: the budget task's budget is budget_scans (max_steps truncates the "
            f"explore and time tasks); give budget_scans={max_steps!r}"
        )
    if budget_scans is not None and task != "budget":
        raise ConfigError(
            f"budget_scans is the budget task's budget; give task='budget' "
            f"(nbv_gym/ExploreBudget-v0) or max_steps, got task={task!r}"
        )
    if time_budget_s is not None and task != "time":
        raise ConfigError(
            f"time_budget_s is the time task's budget; give task='time' (nbv_gym/ExploreTime-v0) "
            f"or no time budget, got task={task!r}"
        )


def task_env(id_task: str, task: str | None = None, **kwargs: Any) -> ExploreEnv:
    """The environment of ``id_task``'s registered id (``gymnasium.make`` calls it with the
    user's keywords, :class:`ExploreEnv`'s): a ``task`` other than the id's is refused, naming
    the id to make instead."""
    if task is not None and task != id_task:
        check_task(task)
        raise ConfigError(
            f"task: {TASK_IDS[id_task]} is the {id_task} task, got task={task!r}; make "
            f"{TASK_IDS[task]} instead"
        )
    return ExploreEnv(task=id_task, **kwargs)


setattr(task_env, "metadata", ExploreEnv.metadata)  # noqa: B010  (gymnasium.make reads it)


def _given(values: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` without the None entries (nested tables too, empty ones dropped)."""
    given = {}
    for key, value in values.items():
        value = _given(value) if isinstance(value, Mapping) else value
        if value is not None and value != {}:
            given[key] = value
    return given


def _distribution(config: EnvConfig) -> WorldDistribution | None:
    """The world distribution of ``config`` (None for a single world)."""
    world = config.simulator.world
    if not is_distribution(world):
        return None
    return WorldDistribution.from_name(world, config.world_pool_size)


__all__ = ["EnvConfig", "EpisodeConfig", "ExploreEnv", "GoalSpace"]
