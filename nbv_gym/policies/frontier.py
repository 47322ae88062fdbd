"""The frontier and random baselines of the NBV paper (docs/protocol.md#baselines, the authors' code).

- ``random-free``: a uniformly random valid goal anywhere.
- ``random-frontier``: a uniformly random frontier goal.
- ``closest-frontier``: the frontier goal nearest in straight line (ties: the lowest index).

With no frontier goal left, the frontier policies fall back to ``random-free``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


class RandomFree:
    """A uniformly random valid goal."""

    observation_layers: tuple[str, ...] = ()

    def __init__(self) -> None:
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the goal draw's generator is seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """A valid goal drawn uniformly."""
        return self._uniform(np.asarray(info["action_mask"], bool))

    def _uniform(self, mask: np.ndarray) -> int:
        choices = np.flatnonzero(mask)
        if len(choices) == 0:
            raise ValueError("no valid goal to choose from")
        return int(self.rng.choice(choices))


class RandomFrontier(RandomFree):
    """A uniformly random frontier goal (random-free when there is none)."""

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """A frontier goal drawn uniformly (any valid goal when there is no frontier)."""
        frontier = frontier_goals(observation, info)
        return self._uniform(frontier if frontier.any() else np.asarray(info["action_mask"], bool))


class ClosestFrontier(RandomFree):
    """The frontier goal nearest to the robot in straight line (random-free when there is none)."""

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The frontier goal nearest to the robot in straight line (a random valid goal when
        there is none)."""
        frontier = frontier_goals(observation, info)
        if not frontier.any():
            return super().act(observation, info)
        distance = np.where(frontier, np.asarray(observation["distance"]).ravel(), np.inf)
        return int(np.argmin(distance))


def frontier_goals(observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> np.ndarray:
    """(n_goals,) bool: valid goals on the frontier."""
    return (np.asarray(observation["frontier"]).ravel() > 0) & np.asarray(info["action_mask"], bool)
