"""The team task as a PettingZoo ``ParallelEnv``: N robots, one map, one clock (docs/team.md).

Agents are ``robot_0`` … ``robot_{N-1}``; every robot that has not stopped stays in
:attr:`TeamEnv.agents` and in every dict. Each :meth:`TeamEnv.step` runs the team's clock on to
the next moment a robot must decide (:mod:`nbv_gym.team.simulator`): exactly one robot decides
per step; the others are *busy* (``info["busy"]``) — driving and scanning, or waiting for their
turn at this moment, their teammates choosing first — and their action is ignored.

Action: ``Discrete(n_goals + 1)`` per robot: a goal cell of G (as in ``Explore-v0``) or
:attr:`TeamEnv.carry_on` (= ``n_goals``), the only action a busy robot's mask allows. The mask,
(n_goals + 1,) int8, is in both the observation and ``info["action_mask"]``; ``action_space(a)
.sample()`` draws from it.

Observation (per robot): the single-robot observation of ``Explore-v0`` (the base layers and
``state``, :mod:`nbv_gym.env.observation`) as the robot last decided on it — fresh for the
robots that decide at this moment (``info["decides_now"]``: the deciding robot and those
waiting their turn) — plus ``teammates``, (N − 1, 6) float32, one row per teammate in index order:
[x, y, goal x, goal y] / G's half-widths (the goal is where it drives to, or where it stands),
its time to that goal's scan / the budget, and 1 while it runs (0 once stopped); and
``action_mask``. Reward: the ΔQ of the robot's own scans, each weighted by the share of the
budget left after it, so the team's rewards sum (with the first scans') to the area under the
team's Q(t). :meth:`TeamEnv.state` is the global view.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from nbv_gym.core.errors import ConfigError
from nbv_gym.env import observation
from nbv_gym.env.explore import EnvConfig, GoalSpace, resolve_config
from nbv_gym.simulator import InvalidActionError, ResetNeededError, goal_index
from nbv_gym.team.simulator import TeamSimulator, check_team_size
from nbv_gym.worlds.distribution import is_distribution

try:
    from pettingzoo import ParallelEnv
except ImportError:  # pragma: no cover - the team extra is in the test extra
    raise ImportError(
        'the team environment needs PettingZoo: pip install "nbv-gym[team]"'
    ) from None

#: The layers of the global state (:meth:`TeamEnv.state`): the map's and the statistics'.
STATE_LAYERS = ("known", "free", "occupied", "n_obs", "r_min", "n_omega", "sigma_theta")
#: Columns of a robot's row in ``teammates`` and in the state.
ROBOT_COLUMNS = ("x", "y", "goal_x", "goal_y", "time_to_goal", "running")


class TeamEnv(ParallelEnv):
    """N robots exploring one world in the time task (module docstring).

    Args:
        config: an :class:`~nbv_gym.env.explore.EnvConfig` (or a dict of its fields); the
            task is the time task (its budget is the team's clock for every robot at once).
        n_robots: how many robots (≥ 1; 2–4 is the usual team).
        start_xy_m: each robot's start (x, y), metres; None: the free start points nearest to
            the episode's start (:func:`~nbv_gym.team.simulator.start_points`).
        world, noise, time_budget_s, speed_mps, scan_time_s, lidar: shortcuts as in
            :class:`~nbv_gym.env.explore.ExploreEnv`.
    """

    metadata = {"name": "nbv_gym_explore_team_v0", "render_modes": []}  # noqa: RUF012 (ParallelEnv declares it)

    def __init__(
        self,
        config: EnvConfig | Mapping[str, Any] | None = None,
        *,
        n_robots: int = 2,
        start_xy_m: list[tuple[float, float]] | None = None,
        world: str | None = None,
        noise: int | None = None,
        time_budget_s: float | None = None,
        speed_mps: float | None = None,
        scan_time_s: float | None = None,
        lidar: str | None = None,
    ):
        check_team_size(n_robots, start_xy_m)
        effort = {
            "time_budget_s": time_budget_s,
            "speed_mps": speed_mps,
            "scan_time_s": scan_time_s,
        }
        self.config = resolve_config(config, "time", world, noise, None, None, {}, effort, lidar)
        _check_supported(self.config)
        self.sim = TeamSimulator(self.config.simulator, int(n_robots), start_xy_m)
        self.possible_agents = [f"robot_{k}" for k in range(n_robots)]
        self.agents: list[str] = []
        self.render_mode = None
        self.carry_on = self.sim.n_goals
        mapping, episode = self.config.simulator.mapping, self.config.simulator.episode
        self.observer = observation.Observer(
            self.sim.shared.goal_grid,
            mapping.sensor_range_m,
            mapping.statistics.n_sectors,
            episode.max_steps,
            episode.budget,
        )
        self._observation_space = _observation_space(self, mapping.navigation.cost_range_m)
        self._action_spaces = {name: GoalSpace(self.carry_on + 1) for name in self.possible_agents}
        for index, name in enumerate(self.possible_agents):
            self._action_spaces[name].bind(functools.partial(self._mask, index))
        size = len(STATE_LAYERS) * self.sim.n_goals + len(ROBOT_COLUMNS) * n_robots + 2
        self.state_space = spaces.Box(-2.0, 2.0, (size,), np.float32)
        self._layers: list[dict[str, np.ndarray]] = []
        self._rewarded = 0  # the scans already paid out as rewards
        self._np_random: np.random.Generator | None = None

    def observation_space(self, agent: str) -> spaces.Dict:
        """Every robot's observation space (one object)."""
        self._index(agent)
        return self._observation_space

    def action_space(self, agent: str) -> GoalSpace:
        """``agent``'s action space (its own object: it samples from its own mask)."""
        self._index(agent)
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode: every robot's first scan, robot 0 to decide. ``options`` is
        accepted for PettingZoo's API and read for nothing."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int | np.integer)
                                 or seed < 0):  # fmt: skip
            raise ConfigError(f"reset(seed=...): expected None or an integer ≥ 0, got {seed!r}")
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(None if seed is None else int(seed))
        self.sim.reset(int(self._np_random.integers(2**63 - 1)))
        self._rewarded = len(self.sim.scans)
        self._layers = [self._observe_robot(k) for k in range(len(self.possible_agents))]
        self.agents = self._running()
        return self._observations(self.agents), self._infos(self.agents)

    def step(self, actions: Mapping[str, Any]):
        """The deciding robot's action runs (the busy robots' are ignored); the clock runs on to
        the next decision: PettingZoo's five dicts over the robots that ran at this step's start."""
        if self.sim.shared.state is None or not self.agents:
            raise ResetNeededError("Call reset() before step() (the team's episode has ended).")
        live = list(self.agents)
        self.sim.act(self._goal(actions))
        for index in self.sim.deciding_now():  # fresh for each robot that decides now
            self._layers[index] = self._observe_robot(index)
        rewards = self._rewards(live)
        terminated = dict.fromkeys(live, self.sim.terminated)
        truncated = {a: bool(self.sim.stopped[self._index(a)]) and not self.sim.terminated
                     for a in live}  # fmt: skip
        self.agents = self._running()
        return self._observations(live), rewards, terminated, truncated, self._infos(live)

    def state(self) -> np.ndarray:
        """The global view, (size,) float32: the map's and statistics' layers
        (:data:`STATE_LAYERS`, each (n_goals,)), every robot's row (:data:`ROBOT_COLUMNS`),
        the discovered fraction and the team's clock / the budget."""
        if not self._layers:
            raise ResetNeededError("Call reset() before state().")
        latest = self._layers[self.sim.deciding if not self.sim.ended else 0]
        rows = [self._row(k) for k in range(len(self.possible_agents))]
        tail = [
            self.sim.shared.navigation.discovered_fraction,
            self.sim.budget.share(self.sim.time_s),
        ]
        parts = [latest[name] for name in STATE_LAYERS]
        parts += [np.ravel(np.array(rows, np.float32)), np.array(tail, np.float32)]
        return np.concatenate(parts).astype(np.float32)

    def render(self) -> None:
        """Nothing: the team env has no render mode yet."""
        return None

    def close(self) -> None:
        """Nothing to release."""

    # ------------------------------------------------------------------ parts

    def _index(self, agent: str) -> int:
        try:
            return self.possible_agents.index(agent)
        except ValueError:
            raise ConfigError(f"unknown agent {agent!r}; agents: {self.possible_agents}") from None

    def _running(self) -> list[str]:
        return [a for k, a in enumerate(self.possible_agents) if not self.sim.stopped[k]]

    def _goal(self, actions: Mapping[str, Any]) -> int:
        """The deciding robot's goal in ``actions``; InvalidActionError naming what is wrong."""
        if not isinstance(actions, Mapping):
            raise InvalidActionError(
                f"actions: expected a dict agent → action, got {type(actions).__name__}"
            )
        unknown = sorted(set(map(str, actions)) - set(self.agents))
        if unknown:
            raise InvalidActionError(f"actions for {unknown}, not running robots {self.agents}")
        name = self.possible_agents[self.sim.deciding]
        if name not in actions:
            raise InvalidActionError(
                f"{name} decides now: actions must hold its goal (busy robots may be left out)"
            )
        goal = goal_index(actions[name], self.carry_on + 1)
        if goal == self.carry_on:
            raise InvalidActionError(
                f"{name} decides now: carry on ({self.carry_on}) is a busy robot's action; "
                "choose a goal where its action_mask is 1"
            )
        return goal

    def _mask(self, index: int) -> np.ndarray:
        """(n_goals + 1,) bool: robot ``index``'s valid actions."""
        mask = np.zeros(self.carry_on + 1, bool)
        if self.sim.ended or self.sim.busy(index):
            mask[self.carry_on] = not self.sim.stopped[index]
        else:
            mask[: self.carry_on] = self.sim.goal_mask()
        return mask

    def _observe_robot(self, index: int) -> dict[str, np.ndarray]:
        """Robot ``index``'s single-robot layers and state, planned for it (then for the
        deciding robot again)."""
        sim = self.sim
        if index != sim.deciding:
            sim.plan_for(index)
        robot, shared = sim.robots[index], sim.shared
        elapsed = robot.elapsed_s(sim.effort)
        layers = self.observer.observe(
            shared.navigation, shared.statistics, robot.pose, robot.steps, None, elapsed
        )
        if index != sim.deciding and not sim.ended:
            sim.plan_for(sim.deciding)
        return layers

    def _row(self, index: int) -> list[float]:
        """Robot ``index``'s row (:data:`ROBOT_COLUMNS`)."""
        sim = self.sim
        robot, pending = sim.robots[index], sim.pending[index]
        goal = robot.pose if pending is None else pending[0]
        half = sim.shared.goal_grid.high[:2]
        left = 0.0 if pending is None else float(sim.ready_s[index] - sim.time_s)
        return [robot.pose.x / half[0], robot.pose.y / half[1], goal.x / half[0],
                goal.y / half[1], sim.budget.share(left), float(not sim.stopped[index])]  # fmt: skip

    def _observations(self, agents: list[str]) -> dict[str, dict[str, np.ndarray]]:
        rows = np.array([self._row(k) for k in range(len(self.possible_agents))], np.float32)
        out = {}
        for agent in agents:
            k = self._index(agent)
            out[agent] = {
                **{name: layer.copy() for name, layer in self._layers[k].items()},
                "teammates": np.delete(rows, k, axis=0).reshape(-1, len(ROBOT_COLUMNS)),
                "action_mask": self._mask(k).astype(np.int8),
            }
        return out

    def _rewards(self, agents: list[str]) -> dict[str, float]:
        """Each robot's rewards of the scans taken since the last step."""
        rewards = dict.fromkeys(agents, 0.0)
        for scan in self.sim.scans[self._rewarded :]:
            name = self.possible_agents[scan.robot]
            if name in rewards:
                rewards[name] += scan.reward
        self._rewarded = len(self.sim.scans)
        return rewards

    def _infos(self, agents: list[str]) -> dict[str, dict[str, Any]]:
        sim, summary = self.sim, self.sim.shared.summary
        grid = sim.shared.goal_grid
        team = {
            "world": sim.shared.world.name,
            "discovered": sim.shared.navigation.discovered_fraction,
            "q": summary.q,
            "q_paper": summary.q_paper,
            "q_observed": summary.q_observed,
            "team_elapsed_s": sim.time_s,
            "goal_grid_shape": grid.shape[:2],
            "goal_cell_m": grid.res,
            "cost_range_m": self.config.simulator.mapping.navigation.cost_range_m,
        }
        infos, deciding = {}, sim.deciding_now()
        for agent in agents:
            k = self._index(agent)
            robot = sim.robots[k]
            infos[agent] = {
                **team,
                "busy": sim.busy(k),
                "decides_now": k in deciding,
                "action_mask": self._mask(k).astype(np.int8),
                "goal": robot.goal,
                "teammate_goals": sim.teammates_goals(k),
                "steps": robot.steps,
                "path_length_m": robot.path_length_m,
                "elapsed_s": robot.elapsed_s(sim.effort),
                "remaining_s": sim.remaining_s(k),
                "end_reason": sim.stopped[k],
            }
        return infos


def _observation_space(env: TeamEnv, cost_range_m: float) -> spaces.Dict:
    """A robot's observation space: the single robot's, ``teammates`` and ``action_mask``."""
    n_goals, n = env.sim.n_goals, len(env.possible_agents)
    base = observation.observation_space(n_goals, {}, env.observer.cost_high(cost_range_m))
    return spaces.Dict(
        {
            **base.spaces,
            "teammates": spaces.Box(-2.0, 2.0, (n - 1, len(ROBOT_COLUMNS)), np.float32),
            "action_mask": spaces.MultiBinary(n_goals + 1),
        }
    )


def _check_supported(config: EnvConfig) -> None:
    """ConfigError for what the team env does not run yet: a world distribution and optional
    observation layers."""
    if is_distribution(config.simulator.world):
        raise ConfigError(
            f"world: the team env explores one world, got the distribution "
            f"{config.simulator.world!r}; give a world name or spec file"
        )
    if config.observation_layers:
        raise ConfigError(
            f"observation_layers: the team env computes the base layers only, got "
            f"{list(config.observation_layers)}"
        )
