"""Volumetric information-gain references: ``ig-unknown`` and ``ig-entropy``.

- ``ig-unknown``: the unknown voxels visible from a candidate view, occlusion-aware — "An
  information gain formulation for active volumetric 3D reconstruction" (S. Isler,
  R. Sabzevari, J. Delmerico, D. Scaramuzza, ICRA 2016) and "Receding horizon 'next-best-view'
  planner for 3D exploration" (A. Bircher, M. Kamel, K. Alexis, H. Oleynikova, R. Siegwart,
  ICRA 2016).
- ``ig-entropy``: the occupancy entropy along the visible rays — "A comparison of volumetric
  information gain metrics for active 3D object reconstruction" (J. Delmerico, S. Isler,
  R. Sabzevari, D. Scaramuzza, Autonomous Robots 2018).

Both choose, among the candidates (valid goals within the search range, layer
``nbv_candidates``, the same as the statistic NBV's), the goal maximising Bircher et al.'s
trade-off

    utility(T) = gain(T) · exp(−λ · path length(T))

with gain(T) the layer ``gain_unknown`` or ``gain_entropy`` (what exactly is counted:
:mod:`nbv_gym.nbv.volumetric`) and the path length of the robot's planner, read from the
``cost`` layer: cost · search range, so paths longer than the 20 m search range count as 20 m.
λ = :data:`DEFAULT_LAMBDA` per metre, chosen by a measured sweep on the ``random:`` training pools
(``experiments/ig-lambda.toml``; the table is in ``docs/references.md``). Ties are broken
uniformly at random; without candidates the goal is a uniformly random valid goal.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from nbv_gym.core import libm
from nbv_gym.core.errors import ConfigError
from nbv_gym.nbv.predictor import CANDIDATES_LAYER
from nbv_gym.policies.nbv import observation_layer, uniform_choice

#: λ of the trade-off, per metre of path (``experiments/ig-lambda.toml``).
DEFAULT_LAMBDA = 0.5
#: The largest λ, per metre: exp(−100 · 1 m) ≈ 4e-44 already makes distance decide alone, and
#: larger values overflow the product λ · path length.
MAX_LAMBDA = 100.0


class InformationGain:
    """Argmax of gain · exp(−λ · path length) over the candidates, for one gain layer.

    Args:
        layer: ``"gain_unknown"`` or ``"gain_entropy"``.
        lam: λ, per metre (a string is parsed: ``ig-unknown@0.25``).

    The ``cost`` layer is a path length over the planner's ``info["cost_range_m"]``.
    """

    #: ``ig-unknown@0.25`` names ``IgUnknown(lam="0.25")``.
    variant_parameter = "lam"

    def __init__(
        self,
        layer: str,
        lam: float | str = DEFAULT_LAMBDA,
    ):
        try:
            lam = float(lam)
        except ValueError:
            raise ConfigError(
                f"lam: expected a number from 0 to {MAX_LAMBDA:g}, got {lam!r}"
            ) from None
        if not (math.isfinite(lam) and 0 <= lam <= MAX_LAMBDA):
            raise ConfigError(
                f"lam: expected a number from 0 to {MAX_LAMBDA:g} (per metre; larger values "
                f"change no decision and overflow), got {lam:g}"
            )
        self.gain_layer = layer
        self.lam = lam
        self.observation_layers: tuple[str, ...] = (layer, CANDIDATES_LAYER)
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the policy's generator is seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)

    def utility(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> np.ndarray:
        """(n_goals,) float64 gain · exp(−λ · path length) of the candidates; −inf elsewhere."""
        valid = np.asarray(info["action_mask"], bool).ravel()
        candidates = (observation_layer(observation, CANDIDATES_LAYER) > 0) & valid
        gain = observation_layer(observation, self.gain_layer).astype(np.float64)
        path_m = observation_layer(observation, "cost").astype(np.float64) * info["cost_range_m"]
        return np.where(candidates, gain * libm.exp(-self.lam * path_m), -np.inf)

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The goal index of the best candidate (module docstring)."""
        utility = self.utility(observation, info)
        best = np.max(utility)
        if best == -np.inf:
            return uniform_choice(self.rng, np.flatnonzero(np.asarray(info["action_mask"], bool)))
        return uniform_choice(self.rng, np.flatnonzero(utility == best))


class IgUnknown(InformationGain):
    """``ig-unknown``: the unknown voxels a scan would see (Isler et al.; Bircher et al.)."""

    def __init__(self, lam: float | str = DEFAULT_LAMBDA) -> None:
        super().__init__("gain_unknown", lam)


class IgEntropy(InformationGain):
    """``ig-entropy``: the occupancy entropy a scan would see (Delmerico et al.)."""

    def __init__(self, lam: float | str = DEFAULT_LAMBDA) -> None:
        super().__init__("gain_entropy", lam)
