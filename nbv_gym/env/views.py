"""What a policy may read of the environment's ``info``: the agent view and the privileged keys.

The environment's ``info`` holds two kinds of values. **Agent keys** are what a robot could know
on its own: its action mask, its estimated pose, its step count and odometry, its map's discovered
fraction, the goal it ran, why its episode ended and its own gain predictions. **Privileged keys**
are computed from what a robot cannot know — the world's ground truth or the true pose — or name
the world (from which ``load_world(name).ground_truth`` gives every occupied voxel). Map quality
(Q and its parts) is privileged: it compares the map with the ground truth.

The policy harness (:func:`nbv_gym.episode.run_episode`, and through it ``nbv-gym run``,
``sweep``, ``record`` and ``score``) hands a policy :func:`agent_view` of ``info``; reading a
privileged key there raises :class:`PrivilegedInfoError`. A policy that declares
``privileged = True`` is an *oracle*: it gets the full ``info``, and results mark it and rank it
apart. The Gymnasium environment itself keeps the full ``info`` (learners' rewards, logging).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from nbv_gym.core.errors import NbvGymError

#: Info keys a policy may read, each with why a robot could know it.
AGENT_KEYS: dict[str, str] = {
    "action_mask": "the valid goals, planned on the robot's own navigation map",
    "goal": "the goal the robot ran (its own action, after snapping)",
    "snapped": "whether the robot's own action was snapped to a valid goal",
    "discovered": "the known share of the robot's own navigation map",
    "steps": "the number of scans the robot took",
    "step_path_length_m": "the length of the path the robot planned and drove on its map",
    "path_length_m": "the robot's odometry: the path lengths it drove, summed",
    "path_penalty": "the configured cost per metre times the path the robot drove",
    "elapsed_s": "the robot's clock: its odometry and its scan count under the effort model",
    "remaining_s": "the time task's budget minus the robot's clock",
    "estimated_pose": "the pose the robot maps with (its localisation, noise included)",
    "end_reason": "the step limit, the discovered target or no valid goal: all on its own map",
    "goal_grid_shape": "the (nx, ny) goal grid the robot plans on (its own map's extent)",
    "goal_cell_m": "the goal grid's cell size, metres (a setting of the robot's planner)",
    "cost_range_m": "the path length at which the cost layer saturates at 1 (a planner setting)",
    "predicted_gain": "the NBV layers' prediction, computed from the robot's own map",
    "realised_gain": "the same statistic on the robot's own statistics before and after the scan",
    "busy": "whether the robot decides now or drives, scans or waits its turn (the team task)",
    "decides_now": "whether the robot decides at this moment or waits its turn at it (the team task)",
    "teammate_goals": "the goals the robot's teammates announced (a team shares its plans)",
    "team_elapsed_s": "the team's clock, which every robot of a team shares",
}
#: Info keys only an oracle may read, each with why: ground truth, true pose or the world's name.
PRIVILEGED_KEYS: dict[str, str] = {
    "world": "it names the world, whose ground truth gives every occupied voxel",
    "q": "map quality compares the map with the ground truth",
    "q_paper": "map quality compares the map with the ground truth",
    "q_observed": "map quality compares the map with the ground truth",
    "cov": "surface coverage counts ground-truth voxels the map reconstructs",
    "l1": "L1 is summed over the cuboids the ground truth holds empty",
    "delta_q": "the change of the ground-truth map quality Q",
    "true_pose": "the sensor's true pose, which localisation noise hides from the robot",
}
#: The rule a :class:`PrivilegedInfoError` states.
RULE = "policies see the agent view; declare privileged = True to be an oracle"


class PrivilegedInfoError(NbvGymError):
    """A policy read a privileged (or unclassified) key of the agent view of ``info``;
    ``reader`` names the policy when known."""

    def __init__(self, key: str, reader: str = ""):
        why = PRIVILEGED_KEYS.get(key, "it is not one of the agent keys")
        who = f"Policy {reader} read info[{key!r}], which" if reader else f"info[{key!r}]"
        super().__init__(f"{who} is privileged ({why}): {RULE}.")
        self.key = key


class AbsentInfoError(NbvGymError, KeyError):
    """A policy read an agent key that this task's ``info`` does not hold (the time task's clock
    under another task); a :class:`KeyError`, so ``info.get(key)`` still gives its default."""

    def __init__(self, key: str, reader: str = ""):
        who = f"Policy {reader} read" if reader else "read"
        self.message = (
            f"{who} info[{key!r}] ({AGENT_KEYS[key]}), which this task does not give; run a task "
            f"that gives it, or read it with info.get({key!r})"
        )
        super().__init__(self.message)
        self.key = key

    def __str__(self) -> str:  # KeyError would quote the message
        return self.message


class AgentView(Mapping):
    """The agent values of ``info``, copied: the view holds its :data:`AGENT_KEYS`' values (arrays
    as read-only copies, nested dicts as read-only copies) and the names of the other keys, and
    no reference to ``info`` — so neither its attributes, a copy nor a pickle of it reaches a
    privileged value, and no change to what it hands out reaches the environment's arrays.
    Reading another key of ``info`` (``[]``, ``get``) raises :class:`PrivilegedInfoError`; ``in``,
    ``len``, iteration and ``keys()`` see the agent keys only."""

    __slots__ = ("_reader", "_values", "_withheld")

    def __init__(self, info: Mapping[str, Any], reader: str = ""):
        self._values = {key: _copy(info[key]) for key in info if key in AGENT_KEYS}
        self._withheld = frozenset(key for key in info if key not in AGENT_KEYS)
        self._reader = reader

    def __getitem__(self, key: str) -> Any:
        if key in self._values:
            return self._values[key]
        if key in PRIVILEGED_KEYS or key in self._withheld:
            raise PrivilegedInfoError(key, self._reader)
        if key in AGENT_KEYS:
            raise AbsentInfoError(key, self._reader)
        raise KeyError(key)

    def get(self, key: str, default: Any = None) -> Any:
        """``self[key]``, or ``default`` if the view has no ``key``."""
        try:
            return self[key]
        except KeyError:
            return default

    def __contains__(self, key: object) -> bool:
        return key in self._values

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"AgentView({sorted(self)})"


def agent_view(info: Mapping[str, Any], reader: str = "") -> AgentView:
    """The agent view of an environment ``info`` dict (module docstring); ``reader`` (a policy's
    name) is named in the error a privileged read raises."""
    return AgentView(info, reader)


def _copy(value: Any) -> Any:
    """``value`` as the policy may see it: an array as a read-only copy (writing to it, even
    after making it writeable again, changes nothing of the environment's), a dict as a
    read-only mapping of copies."""
    if isinstance(value, np.ndarray):
        copy = value.copy()
        copy.flags.writeable = False
        return copy
    if isinstance(value, dict):
        return ReadOnlyMapping({key: _copy(item) for key, item in value.items()})
    return value


class ReadOnlyMapping(Mapping):
    """A mapping that cannot be changed (unlike ``MappingProxyType``, it copies and pickles)."""

    __slots__ = ("_data",)

    def __init__(self, data: dict[str, Any]):
        self._data = data

    def __getitem__(self, key: str) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return repr(self._data)
