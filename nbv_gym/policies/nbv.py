"""The statistic-based Next-Best-View policies of the paper (docs/protocol.md#visibility, paper §III-C, authors' code).

``nbv-nobs``, ``nbv-rmin``, ``nbv-nomega`` and ``nbv-sigma`` choose, among the candidates (valid
goals within the search range, layer ``nbv_candidates``), the goal maximising the utility
E[I(a_T)] − α · cost(a_T), with E[I] the predicted gain of one viewpoint statistic (layer
``gain_<statistic>``) and cost = path length / search range (layer ``cost``; clipped at 1 but in
the time task).

α is the paper's 2 (:data:`PAPER_ALPHA`) in the explore and budget tasks, and in the time task
the value tuned for it on the ``random:`` training pools (:data:`TIME_ALPHA`, docs/references.md;
the time task is the one whose ``info`` holds ``remaining_s``), unless the policy is given one.

- Near-uniform gains: if max / min − 1 ≤ ``uniform_tolerance`` over the candidates' gains, the goal is
  a uniformly random candidate instead. Gains are ≥ 0; when the smallest is ≤ 0 the ratio is
  undefined and the gains count as near-uniform only if they are all equal (e.g. all zero).
- Ties of the utility are broken uniformly at random.
- Without candidates the goal is a uniformly random valid goal (``info["action_mask"]``).

All randomness comes from the generator seeded by :meth:`NbvPolicy.reset`.

A policy may fix the visibility model its gains are predicted with (``nbv-nobs@fov`` names
``NbvNobs(visibility="fov")``); by default it uses the environment's ``NbvConfig.visibility``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.nbv.visibility import VISIBILITY_MODELS

#: The statistics an NBV policy can use, as in the layer names ``gain_<statistic>``.
STATISTICS: tuple[str, ...] = ("nobs", "rmin", "nomega", "sigma")
#: α, the weight of the travel cost (the cost layer: path length / the planner's cost range), of
#: the paper's protocol (the authors' code): the explore and budget tasks' default.
PAPER_ALPHA = 2.0
#: α per statistic tuned for the time task (5 values × 8 episodes of ``random:mixed``,
#: :mod:`nbv_gym.benchmark.tuning`): the time task's default. The gains count hundreds to
#: thousands, so these let the cost decide and the gain break near-ties.
TIME_ALPHA: dict[str, float] = {"nobs": 20000.0, "rmin": 2000.0, "nomega": 20000.0,
                                "sigma": 20000.0}  # fmt: skip


class NbvPolicy:
    """Argmax of gain − α · cost over the NBV candidates for one statistic.

    Args:
        statistic: one of :data:`STATISTICS`.
        alpha: weight of the travel cost; None: the task's (:data:`PAPER_ALPHA`, or
            :data:`TIME_ALPHA` in the time task).
        uniform_tolerance: near-uniform threshold of max / min − 1 over the candidates' gains.
        visibility: the visibility model of the gain prediction
            (:data:`~nbv_gym.nbv.visibility.VISIBILITY_MODELS`), or None for the environment's.
    """

    def __init__(
        self,
        statistic: str,
        alpha: float | None = None,
        uniform_tolerance: float = 0.05,
        visibility: str | None = None,
    ):
        if statistic not in STATISTICS:
            raise ConfigError(
                f"statistic: expected one of {', '.join(STATISTICS)}, got {statistic!r}"
            )
        if alpha is not None and not alpha >= 0:
            raise ConfigError(f"alpha: must be ≥ 0, got {alpha}")
        if not uniform_tolerance >= 0:
            raise ConfigError(f"uniform_tolerance: must be ≥ 0, got {uniform_tolerance}")
        if visibility is not None and visibility not in VISIBILITY_MODELS:
            raise ConfigError(
                f"visibility: expected one of {', '.join(VISIBILITY_MODELS)}, got {visibility!r}"
            )
        self.statistic = statistic
        self.visibility = visibility
        self.alpha = None if alpha is None else float(alpha)
        self.uniform_tolerance = float(uniform_tolerance)
        self.gain_layer = f"gain_{statistic}"
        self.observation_layers: tuple[str, ...] = (self.gain_layer, "nbv_candidates")
        self.rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the policy's generator is seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The goal index (row-major over the goal grid) of the next best view."""
        valid = _action_mask(info)
        candidates = np.flatnonzero((observation_layer(observation, "nbv_candidates") > 0) & valid)
        if len(candidates) == 0:
            return self._uniform(np.flatnonzero(valid))
        gains = observation_layer(observation, self.gain_layer)[candidates].astype(np.float64)
        if near_uniform(gains, self.uniform_tolerance):
            return self._uniform(candidates)
        cost = observation_layer(observation, "cost")[candidates].astype(np.float64)
        utility = gains - self.task_alpha(info) * cost
        return self._uniform(candidates[utility == utility.max()])

    def task_alpha(self, info: Mapping[str, Any]) -> float:
        """α for the episode ``info`` belongs to: the policy's own, else the task's."""
        if self.alpha is not None:
            return self.alpha
        return TIME_ALPHA[self.statistic] if "remaining_s" in info else PAPER_ALPHA

    def _uniform(self, choices: np.ndarray) -> int:
        return uniform_choice(self.rng, choices)


class NbvNobs(NbvPolicy):
    """``nbv-nobs``: gain in the number of observations."""

    def __init__(self, visibility: str | None = None, alpha: float | None = None) -> None:
        super().__init__("nobs", alpha=alpha, visibility=visibility)


class NbvRmin(NbvPolicy):
    """``nbv-rmin``: gain in the smallest observation range."""

    def __init__(self, visibility: str | None = None, alpha: float | None = None) -> None:
        super().__init__("rmin", alpha=alpha, visibility=visibility)


class NbvNomega(NbvPolicy):
    """``nbv-nomega``: gain in the number of azimuth sectors observed from."""

    def __init__(self, visibility: str | None = None, alpha: float | None = None) -> None:
        super().__init__("nomega", alpha=alpha, visibility=visibility)


class NbvSigma(NbvPolicy):
    """``nbv-sigma``: gain in the spherical variance of the viewing directions."""

    def __init__(self, visibility: str | None = None, alpha: float | None = None) -> None:
        super().__init__("sigma", alpha=alpha, visibility=visibility)


def near_uniform(gains: np.ndarray, tolerance: float) -> bool:
    """Whether the (m,) float ``gains`` (m ≥ 1) are near-uniform: max / min − 1 ≤ ``tolerance``
    when min > 0, otherwise (ratio undefined) all equal."""
    low, high = float(np.min(gains)), float(np.max(gains))
    if low > 0:
        return high <= (1.0 + tolerance) * low  # max / min − 1 ≤ tolerance, without the division
    return high == low


def observation_layer(observation: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    """The observation layer ``name`` flattened to one entry per goal."""
    if name not in observation:
        raise NbvGymError(
            f"the observation has no layer {name!r}; make the environment with the policy's "
            f"observation_layers (it has: {', '.join(sorted(observation))})"
        )
    return np.asarray(observation[name]).ravel()


def uniform_choice(rng: np.random.Generator, choices: np.ndarray) -> int:
    """A uniformly random entry of the (m,) int ``choices`` (the only one without drawing);
    NbvGymError when there is none."""
    if len(choices) == 0:
        raise NbvGymError("no valid goal to choose from: info['action_mask'] is all False")
    return int(choices[0]) if len(choices) == 1 else int(rng.choice(choices))


def _action_mask(info: Mapping[str, Any]) -> np.ndarray:
    if "action_mask" not in info:
        raise NbvGymError("info has no 'action_mask': pass the info dict the environment returned")
    return np.asarray(info["action_mask"], bool).ravel()
