"""The stable-baselines3 algorithms ``nbv-gym train`` runs, saving lean model files.

SB3 saves the last observation of every training environment with a model (0.23 MB per
environment for ``Explore-v0``), though loading a model resets its environments and never
reads them back: these subclasses leave them out, so a model file's size does not grow with
``n_envs`` (≈ 2 MB with the default network). They load any SB3 file of their algorithm.
"""

from __future__ import annotations

from sb3_contrib import MaskablePPO as _MaskablePPO
from stable_baselines3 import A2C as _A2C
from stable_baselines3 import PPO as _PPO
from stable_baselines3.common.base_class import BaseAlgorithm

#: Attributes of the last rollout step, rebuilt by ``learn`` after every load.
LAST_STEP = ("_last_obs", "_last_original_obs")


class _LeanSave(BaseAlgorithm):
    """Saves an algorithm without :data:`LAST_STEP` (mixed in before the SB3 class)."""

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), *LAST_STEP]


class MaskablePPO(_LeanSave, _MaskablePPO):
    """sb3-contrib's MaskablePPO, saved without the environments' last observations."""


class PPO(_LeanSave, _PPO):
    """SB3's PPO, saved without the environments' last observations."""


class A2C(_LeanSave, _A2C):
    """SB3's A2C, saved without the environments' last observations."""
