"""``oracle-greedy``: the one-step ground-truth oracle — of a set of candidate goals, the one whose
scan raises the true map quality Q most. An upper reference for one-step (greedy) policies, not
a robot policy: it reads the ground truth (``privileged = True``), and results mark it apart.

Formula: goal = argmax over g ∈ C of ΔQ(g), ΔQ(g) = Q(map after the scan from g) − Q(map now),
Q the benchmark's map quality against the ground truth (the reward). The candidates C are at
most ``n_best + n_random`` = 64 goals: the 32 best by the ``ig-unknown`` utility (gain ·
exp(−λ · path), :mod:`nbv_gym.policies.information_gain`) and 32 drawn uniformly (without
replacement, from the policy's generator seeded by :meth:`OracleGreedy.reset`) from the other
``ig-unknown`` candidates (valid goals within the search range); fewer when there are fewer.

Evaluation (:class:`~nbv_gym.policies.lookahead.FastLookahead`): the scan from g is the very scan
the environment's step to g would take — the same pose and the simulator's generator state, so
the same localisation noise (the robot's noisy pose model) and range noise — tried on the map
without writing it, and Q after it summed as the quality tracker would, bit for bit the ΔQ of
inserting it into a scratch copy of the map and scoring a scratch quality tracker
(:class:`~nbv_gym.simulator.Lookahead`, the reference it is tested against). So ΔQ(g) is the
exact reward of stepping to g, the environment's map, statistics, quality and generator are left
bit-identical, and the episode is what it would be without the evaluation. Ties of ΔQ go to the
first candidate in the order above. Without candidates the goal is a uniformly random valid goal.

The harness calls :meth:`OracleGreedy.attach` with the unwrapped environment after every reset;
:attr:`OracleGreedy.last_evaluation` keeps the last decision's goals and ΔQ for inspection.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from nbv_gym.core.errors import NbvGymError
from nbv_gym.policies.information_gain import DEFAULT_LAMBDA, IgUnknown
from nbv_gym.policies.lookahead import FastLookahead
from nbv_gym.policies.nbv import uniform_choice


class OracleGreedy:
    """Argmax of the true ΔQ over at most ``n_best + n_random`` candidates (module docstring).

    Args:
        n_best: candidates taken by the ``ig-unknown`` utility.
        n_random: candidates drawn uniformly from the rest.
        lam: λ of the ``ig-unknown`` ranking, per metre.
    """

    privileged = True

    def __init__(self, n_best: int = 32, n_random: int = 32, lam: float = DEFAULT_LAMBDA):
        self.ranking = IgUnknown(lam)
        self.observation_layers = self.ranking.observation_layers
        self.n_best, self.n_random = int(n_best), int(n_random)
        self.rng = np.random.default_rng()
        self.lookahead: FastLookahead | None = None
        self.last_evaluation: dict[str, np.ndarray] = {}

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the candidate draw's generator is seeded with ``seed``."""
        self.rng = np.random.default_rng(seed)
        self.last_evaluation = {}

    def attach(self, env: Any) -> None:
        """Read the true map quality through ``env`` (the unwrapped ``ExploreEnv``, after its
        reset)."""
        self.lookahead = FastLookahead(env.sim)

    def candidates(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]):
        """(m,) int64 goals to evaluate: the best by ``ig-unknown``, then the uniform draw."""
        utility = self.ranking.utility(observation, info)
        ranked = np.flatnonzero(np.isfinite(utility))
        ranked = ranked[np.argsort(-utility[ranked], kind="stable")]
        best, rest = ranked[: self.n_best], ranked[self.n_best :]
        drawn = self.rng.choice(rest, size=min(self.n_random, len(rest)), replace=False)
        return np.concatenate([best, drawn]).astype(np.int64)

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The candidate whose scan raises Q most."""
        if self.lookahead is None:
            raise NbvGymError(
                "oracle-greedy needs the environment: call policy.attach(env.unwrapped) after "
                "every env.reset() (the harness does)"
            )
        goals = self.candidates(observation, info)
        if len(goals) == 0:
            return uniform_choice(self.rng, np.flatnonzero(np.asarray(info["action_mask"], bool)))
        delta_q = self.lookahead.delta_q(goals)
        self.last_evaluation = {"goals": goals, "delta_q": delta_q}
        return int(goals[int(np.argmax(delta_q))])
