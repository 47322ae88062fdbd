"""A team policy from a model trained with ``robots`` ≥ 2 (docs/rl.md#team): every robot runs
the one shared network on its own view (decentralised execution)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from nbv_gym.rl.algorithms import MaskablePPO
from nbv_gym.rl.teamvec import robot_view
from nbv_gym.team.policies import DecidingRobot


class SharedTeamAgent(DecidingRobot):
    """The deciding robot's goal: the shared network's most likely action on that robot's own
    observation and info (:func:`~nbv_gym.rl.teamvec.robot_view`) under its own mask; carry on
    for the others. Reads nothing of a teammate's observation or info.

    Args:
        path: a model zip saved by ``nbv-gym train`` with ``robots`` ≥ 2 (a model zip is code:
            SB3 unpickles it; load only models you trust).
        deterministic: the most likely goal (True) or one drawn from the policy.
    """

    def __init__(self, path: str | Path, deterministic: bool = True, device: str = "cpu"):
        self.model = MaskablePPO.load(path, device=device)
        self.deterministic = deterministic

    def _goal(self, agent: str, observations: Mapping, infos: Mapping) -> int:
        view = robot_view(observations[agent], infos[agent])
        mask = np.asarray(infos[agent]["action_mask"], bool)
        action, _ = self.model.predict(view, action_masks=mask, deterministic=self.deterministic)
        return int(action)
