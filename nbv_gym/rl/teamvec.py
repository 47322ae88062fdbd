"""Parameter sharing on the team task: the PettingZoo team env as a stable-baselines3 ``VecEnv``
with one slot per robot (docs/rl.md#team).

:class:`TeamVecEnv` holds ``len(envs)`` :class:`~nbv_gym.team.TeamEnv` of ``N`` robots each and
shows SB3 ``len(envs) · N`` slots: slot ``i · N + k`` is robot ``k`` of team env ``i``. One
network acts for every robot (parameter sharing) from that robot's own view alone
(:func:`robot_view`: decentralised execution). Every ``step`` runs each team env one event on
(:meth:`TeamEnv.step`: exactly one robot decides), so:

- **Samples.** Every slot steps at every event. The deciding robot's slot takes its sampled goal;
  a busy robot's mask allows only "carry on" (``TeamEnv.carry_on`` = ``n_goals``), so its step
  is a forced no-op sample: its masked distribution holds one action, of probability 1, so it
  adds nothing to PPO's policy gradient or entropy — only its value target trains the critic,
  and it counts in SB3's step count (``num_timesteps`` = events · slots) and in the batch mean.
  A robot that stopped before its team stays a busy slot (carry on) until the episode ends.
  Whatever a busy slot is sent is ignored (carry on).
- **Reward: shared.** Each slot's reward at an event is the **team's**: the sum over the scans
  that entered the map during the event of ΔQ weighted by the share of the budget left
  (the team env's per-robot rewards summed), times ``reward_scale``; an episode's return is the
  area under the team's Q(t) (less the first scans'), every robot's the same. Credit is not
  split among the robots: a decision's advantage (GAE over the events that follow it, through
  the busy samples' values) is the team's return after it, teammates' scans included.
- **Episodes.** A team env's episode ends for all its slots at once (every robot stopped, or
  the discovered target reached: terminated, no bootstrap); the slots' infos hold
  ``terminal_observation`` and the team env resets. Slot ``i · N``'s info also holds
  ``episode`` (``r``: the scaled team return, ``l``: events, ``t``: seconds) and the team's
  ``q``, ``discovered``, ``path_length_m`` (summed), ``q_time_auc`` and ``end_reason``, one row
  per team episode in ``episodes.csv``.

Masks: :meth:`TeamVecEnv.env_method` ``("action_masks")`` gives each slot's (n_goals + 1,) bool
mask, which sb3-contrib's MaskablePPO reads; no SuperSuit.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

from nbv_gym.core.errors import ConfigError
from nbv_gym.team.env import TeamEnv
from nbv_gym.team.episode import Q_TARGET, team_result

#: The network's layer of the teammates' goals: 1 at each teammate's goal cell (where it drives
#: to, or where it stands), else 0.
TEAMMATE_GOALS = "teammate_goals"
#: The team env's observation keys the network does not read as layers.
TEAM_KEYS = ("teammates", "action_mask")


def robot_view(observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> dict:
    """What the shared network reads of one robot: its own observation and info only.

    The single-robot base layers as they are, :data:`TEAMMATE_GOALS` ((n_goals,) float32 from
    ``info["teammate_goals"]``), and ``state``: the robot's state followed by its
    ``teammates`` rows, flattened ((6 + 6 (N − 1),) float32)."""
    layers = {k: np.asarray(v) for k, v in observation.items() if k not in (*TEAM_KEYS, "state")}
    n_goals = len(next(iter(layers.values())))
    goals = np.zeros(n_goals, np.float32)
    goals[np.asarray(info["teammate_goals"], np.int64)] = 1.0
    state = np.concatenate([np.ravel(observation["state"]), np.ravel(observation["teammates"])])
    return {**layers, TEAMMATE_GOALS: goals, "state": state.astype(np.float32)}


def robot_view_space(env: TeamEnv) -> spaces.Dict:
    """The space of :func:`robot_view` for ``env``'s robots."""
    team = env.observation_space(env.possible_agents[0])
    state, mates = team["state"], team["teammates"]
    assert isinstance(state, spaces.Box) and isinstance(mates, spaces.Box)
    entries = {k: s for k, s in team.spaces.items() if k not in (*TEAM_KEYS, "state")}
    entries[TEAMMATE_GOALS] = spaces.Box(0.0, 1.0, (env.sim.n_goals,), np.float32)
    low = np.concatenate([state.low.ravel(), mates.low.ravel()])
    high = np.concatenate([state.high.ravel(), mates.high.ravel()])
    entries["state"] = spaces.Box(low, high, dtype=np.float32)
    return spaces.Dict(entries)


class RobotSlot:
    """One slot of a :class:`TeamVecEnv` (what SB3's ``get_attr`` and ``env_method`` reach):
    robot ``robot`` of team env ``env``; other attributes are the team env's."""

    def __init__(self, vec: TeamVecEnv, slot: int):
        self.vec, self.slot = vec, slot
        self.env = vec.envs[slot // vec.n_robots]
        self.robot = slot % vec.n_robots

    def action_masks(self) -> np.ndarray:
        """(n_goals + 1,) bool: the robot's valid actions (carry on only while it is busy)."""
        return self.vec.masks[self.slot].copy()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.env, name)


class TeamVecEnv(VecEnv):
    """Team envs of one team size as one SB3 ``VecEnv``, a slot per robot (module docstring).

    Args:
        envs: the team envs (each its own world and robots; all of one team size and goal grid).
        reward_scale: every slot's reward is ``reward_scale`` · the team's reward.
    """

    def __init__(self, envs: Sequence[TeamEnv], reward_scale: float = 1.0):
        if not envs:
            raise ConfigError("TeamVecEnv: give at least one team env")
        sizes = {(len(e.possible_agents), e.sim.n_goals) for e in envs}
        if len(sizes) != 1:
            raise ConfigError(f"TeamVecEnv: team envs of one size and goal grid, got {sizes}")
        self.envs = list(envs)
        self.n_robots = len(envs[0].possible_agents)
        self.reward_scale = float(reward_scale)
        n_slots, n_actions = len(envs) * self.n_robots, envs[0].carry_on + 1
        self.slots = [RobotSlot(self, s) for s in range(n_slots)]
        self.views: list[dict[str, np.ndarray]] = [{} for _ in range(n_slots)]
        self.masks = np.zeros((n_slots, n_actions), bool)
        self._returns = np.zeros(len(envs))
        self._events = np.zeros(len(envs), np.int64)
        self._actions = np.zeros(n_slots, np.int64)
        self._started = time.time()
        super().__init__(n_slots, robot_view_space(envs[0]), spaces.Discrete(n_actions))

    def reset(self):
        """Reset every team env (with the seeds of :meth:`seed`, slot ``i · N``'s for env
        ``i``); the stacked views."""
        for i, env in enumerate(self.envs):
            seed = self._seeds[i * self.n_robots]
            self._start(i, *env.reset(seed=seed))
        self._reset_seeds()
        self.reset_infos = [{} for _ in self.slots]
        return self._stacked()

    def step_async(self, actions: np.ndarray) -> None:
        """Keep ``actions`` ((n_slots,) int) for :meth:`step_wait`."""
        self._actions = np.asarray(actions, np.int64).reshape(self.num_envs)

    def step_wait(self):
        """Run each team env one event on: the deciding robot's action, carry on for the
        others; the stacked views, the shared rewards, dones and infos (module docstring)."""
        rewards = np.zeros(self.num_envs, np.float32)
        dones = np.zeros(self.num_envs, bool)
        infos: list[dict[str, Any]] = [{} for _ in self.slots]
        for i, env in enumerate(self.envs):
            part = slice(i * self.n_robots, (i + 1) * self.n_robots)
            agent = env.possible_agents[env.sim.deciding]
            goal = int(self._actions[part][env.sim.deciding])
            observations, team_rewards, _, _, step_infos = env.step({agent: goal})
            reward = self.reward_scale * float(sum(team_rewards.values()))
            self._returns[i] += reward
            self._events[i] += 1
            rewards[part] = reward
            self._update(i, observations, step_infos)
            for k, name in enumerate(env.possible_agents):
                infos[part.start + k] = dict(step_infos.get(name, {}))
            if not env.agents:
                dones[part] = True
                self._end(i, infos[part])
        return self._stacked(), rewards, dones, infos

    def close(self) -> None:
        """Close every team env."""
        for env in self.envs:
            env.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """``attr_name`` of each slot in ``indices`` (:class:`RobotSlot`, else its team env)."""
        return [getattr(self.slots[s], attr_name) for s in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """Set ``attr_name`` on the team env of each slot in ``indices``."""
        for s in self._get_indices(indices):
            setattr(self.slots[s].env, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        """Call ``method_name`` of each slot in ``indices`` (``action_masks``: its mask)."""
        return [getattr(self.slots[s], method_name)(*method_args, **method_kwargs)
                for s in self._get_indices(indices)]  # fmt: skip

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        """No slot is wrapped (a team env is no ``gymnasium.Env``)."""
        return [False for _ in self._get_indices(indices)]

    # ------------------------------------------------------------------ parts

    def _start(self, i: int, observations: dict, infos: dict) -> None:
        self._returns[i], self._events[i] = 0.0, 0
        self._update(i, observations, infos)

    def _update(self, i: int, observations: Mapping, infos: Mapping) -> None:
        """The views and masks of team env ``i``'s robots in ``observations``; a robot that
        stopped keeps its last view and may only carry on."""
        env = self.envs[i]
        for k, name in enumerate(env.possible_agents):
            slot = i * self.n_robots + k
            if name in observations:
                self.views[slot] = robot_view(observations[name], infos[name])
            mask = np.zeros(env.carry_on + 1, bool)
            if name in env.agents:
                mask[:] = np.asarray(infos[name]["action_mask"], bool)
            mask[env.carry_on] |= not mask.any()
            self.masks[slot] = mask

    def _end(self, i: int, infos: list[dict[str, Any]]) -> None:
        """Team env ``i``'s episode ended: terminal views into ``infos`` (its slots'), the
        team's episode row into its first slot's, then a reset."""
        env = self.envs[i]
        for k, info in enumerate(infos):
            info["terminal_observation"] = self.views[i * self.n_robots + k]
        figures = team_result(env.sim, Q_TARGET, 0.0).figures
        infos[0].update(
            {key: figures[key] for key in
             ("q", "discovered", "path_length_m", "q_time_auc", "end_reason")},
            world=env.sim.shared.world.name,
            episode={"r": round(float(self._returns[i]), 6), "l": int(self._events[i]),
                     "t": round(time.time() - self._started, 6)},
        )  # fmt: skip
        self._start(i, *env.reset())

    def _stacked(self) -> dict[str, np.ndarray]:
        """The slots' views stacked: each key (n_slots, …)."""
        return {key: np.stack([view[key] for view in self.views]) for key in self.views[0]}


def make_team_envs(
    worlds: Sequence[str], n_envs: int, n_robots: int, **env_kwargs: Any
) -> list[TeamEnv]:
    """``n_envs`` team envs of ``n_robots``, env ``i`` exploring ``worlds[i % len(worlds)]``
    in every episode; ``env_kwargs``: :class:`TeamEnv`'s shortcuts (noise, time_budget_s,
    speed_mps, scan_time_s, lidar)."""
    return [TeamEnv(world=worlds[i % len(worlds)], n_robots=n_robots, **env_kwargs)
            for i in range(n_envs)]  # fmt: skip
