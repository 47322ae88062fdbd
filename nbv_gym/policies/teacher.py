"""``oracle-time``: the time task's teacher — of a set of candidate goals, the one whose step earns
the most reward per second of robot time. A privileged oracle (it reads the ground truth,
``privileged = True``; results mark it and rank it apart), built to label states for learning:
:meth:`OracleTime.values` gives the value of every candidate, not only the best.

Formula, over the candidates C of ``oracle-greedy`` (:mod:`nbv_gym.policies.oracle`: the 32 best
goals by the ``ig-unknown`` utility and 32 drawn uniformly from the other ``ig-unknown``
candidates, seeded by :meth:`OracleTime.reset`):

    goal = argmax over g ∈ C of  value(g) = r(g) / c(g)^β
    r(g) = ΔQ(g) · h(g) − penalty · path(g),   c(g) = path(g) / speed + scan time

r(g) is the environment's exact reward of stepping to g: in the time task ΔQ(g) weighted by h(g),
the share of the time budget left after the step (the robot holds the gain that long, so an
episode's rewards sum to its area under Q(t)); c(g) is the seconds the step costs under the effort
model (docs/protocol.md#effort). β = 1 is the weighted-shortest-processing-time rule (Smith's
rule: ordering independent jobs of gain r and duration c by r / c maximises the area under the
gain curve); β = 0 is the greedy reward. β = :data:`DEFAULT_BETA` = 0.1 was chosen on the
training pools, with the references' tuning budget (docs/references.md#tuning-oracle-time): the
highest mean area under Q(t) of the grid 0, 0.1, 0.25, 0.5, 1, ahead of ``oracle-greedy`` in each
of the 8 episodes; β = 1 was the worst. Ties go to the first candidate; without candidates the goal
is a uniformly random valid goal.

ΔQ(g) is the exact ΔQ of stepping to g — the very scan the step would take (the same pose and
generator state, so the same localisation and range noise), scored without committing it
(:class:`~nbv_gym.policies.lookahead.FastLookahead`, bit for bit the insert-score-undo reference
:class:`~nbv_gym.simulator.Lookahead`); the environment's map, statistics, quality and generator
are left bit-identical.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.policies.information_gain import DEFAULT_LAMBDA
from nbv_gym.policies.lookahead import THREADS, FastLookahead
from nbv_gym.policies.nbv import uniform_choice
from nbv_gym.policies.oracle import OracleGreedy
from nbv_gym.simulator import Simulator

#: β: the exponent of the step's cost in seconds that its reward is divided by (tuned on the
#: training pools, docs/references.md#tuning-oracle-time).
DEFAULT_BETA = 0.1


class OracleTime:
    """Argmax of ``r(g) / c(g)^β`` over ``oracle-greedy``'s candidates (module docstring).

    Args:
        n_best: candidates taken by the ``ig-unknown`` utility.
        n_random: candidates drawn uniformly from the rest.
        lam: λ of the ``ig-unknown`` ranking, per metre.
        beta: the exponent β of the step's cost (≥ 0; 0: the greedy reward).
        threads: threads the candidates are evaluated in (the results are the same).
    """

    privileged = True
    variant_parameter = "beta"

    def __init__(
        self,
        n_best: int = 32,
        n_random: int = 32,
        lam: float = DEFAULT_LAMBDA,
        beta: float = DEFAULT_BETA,
        threads: int = THREADS,
    ):
        self.beta, self.threads = _number(beta), int(threads)
        if not (math.isfinite(self.beta) and self.beta >= 0):
            raise ConfigError(f"oracle-time's beta must be a finite number ≥ 0, got {beta!r}")
        if self.threads < 1:
            raise ConfigError(f"oracle-time's threads must be ≥ 1, got {threads!r}")
        self.sampler = OracleGreedy(n_best, n_random, lam)  # its candidates
        self.observation_layers = self.sampler.observation_layers
        self.lookahead: FastLookahead | None = None
        #: the last evaluation: the candidates ``goals`` and each one's ``delta_q``, ``reward``,
        #: ``cost_s`` and ``value`` ((m,) arrays)
        self.last_evaluation: dict[str, np.ndarray] = {}

    def reset(self, seed: int | None = None) -> None:
        """Start an episode: the candidate draw's generator is seeded with ``seed``."""
        self.sampler.reset(seed)
        self.last_evaluation = {}

    def attach(self, env: Any) -> None:
        """Read the true map quality through ``env`` (the unwrapped ``ExploreEnv``, after its
        reset)."""
        self.lookahead = FastLookahead(env.sim, self.threads)

    def values(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> np.ndarray:
        """(n_goals,) float64: each candidate's value r(g) / c(g)^β, −inf for every other goal.
        Each call draws the candidates (two calls on one state may draw different random
        ones)."""
        if self.lookahead is None:
            raise NbvGymError(
                "oracle-time needs the environment: call policy.attach(env.unwrapped) after "
                "every env.reset() (the harness does)"
            )
        goals = self.sampler.candidates(observation, info)
        out = np.full(np.asarray(info["action_mask"]).size, -np.inf)
        if len(goals):
            delta_q = self.lookahead.delta_q(goals)
            reward, cost = step_rewards(self.lookahead.sim, goals, delta_q)
            out[goals] = reward / cost**self.beta
            self.last_evaluation = {"goals": goals, "delta_q": delta_q, "reward": reward,
                                    "cost_s": cost, "value": out[goals]}  # fmt: skip
        return out

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The candidate of the highest value (the first one on a tie)."""
        values = self.values(observation, info)
        if not np.isfinite(values).any():
            mask = np.asarray(info["action_mask"], bool)
            return uniform_choice(self.sampler.rng, np.flatnonzero(mask))
        goals = self.last_evaluation["goals"]
        return int(goals[int(np.argmax(values[goals]))])


def step_rewards(
    sim: Simulator, goals: np.ndarray, delta_q: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The environment's reward of stepping to each of the (m,) ``goals``, given each one's
    (m,) ``delta_q``, and the step's cost in seconds: (m,) float64 each, computed as
    :meth:`Simulator.step <nbv_gym.simulator.Simulator.step>` computes them."""
    episode, navigation = sim.config.episode, sim.navigation
    path = navigation.goal_path_length()[goals].astype(np.float64)
    cost = np.asarray(episode.effort.elapsed_s(path, 1), np.float64)
    spent = episode.effort.elapsed_s(sim.path_length_m + path, sim.steps + 1)
    held = episode.budget.held(episode.budget.remaining_s(spent))
    return delta_q * held - episode.path_penalty_per_m * path, cost


def _number(text: object) -> float:
    """``text`` as a float (NaN for what is no number: refused by the caller's range check)."""
    try:
        return float(str(text))
    except ValueError:
        return math.nan
