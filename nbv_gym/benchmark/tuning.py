"""Tuning the references for the time task, with the same budget for every policy.

A reference with a parameter (λ of ``ig-*`` and ``oracle-greedy``, α of the ``nbv-*`` policies)
is scored at each value of a fixed grid on the same episodes of a ``random:`` training pool —
never the benchmark or test worlds — under the time task, and keeps the value of the highest mean
score (the headline's: the area under Q(t) over the budget, divided by it). Every policy gets the
same budget: :data:`GRID_SIZE` values × ``episodes`` episodes, on the same seeds (so the same
worlds and starts). A policy without a parameter (``closest-frontier``, ``frontier-tour``, …) has
nothing to tune and keeps its definition.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nbv_gym.core.config import check
from nbv_gym.core.errors import UnknownNameError
from nbv_gym.core.protocol import TIME_BUDGET_S, check_effort, check_noise_level
from nbv_gym.metrics.effort import area_under

#: Values per tuned parameter: every policy is tuned on this many values.
GRID_SIZE = 5
#: λ of the information-gain policies, per metre (a first grid of 0.02–0.5 peaked at its edge).
LAMBDA_GRID = (0.1, 0.25, 0.5, 1.0, 2.0)
#: α of the nbv-* policies: their gain layers count hundreds to thousands (the statistic's gain
#: summed over the cells a view would see) while the cost layer is about 0–2, so α spans the
#: gains' scale (a first grid of 0.5–8 changed no decision).
ALPHA_GRID = (2.0, 20.0, 200.0, 2000.0, 20000.0)
#: β of ``oracle-time``: the exponent of the step's cost in seconds its reward is divided by (0:
#: the greedy reward, 1: reward per second, Smith's rule).
BETA_GRID = (0.0, 0.1, 0.25, 0.5, 1.0)
#: The tunable references: (constructor keyword, the grid of values); the chosen values are the
#: time task's defaults (``DEFAULT_LAMBDA`` of the ``ig-*`` policies and ``oracle-greedy``,
#: ``TIME_ALPHA`` of the ``nbv-*`` policies).
#: λ is per metre of path (the information-gain utility gain · exp(−λ · path)); α weighs the
#: cost layer, path / 20 m (the NBV utility gain − α · cost).
TUNABLE: dict[str, tuple[str, tuple[float, ...]]] = {
    "ig-unknown": ("lam", LAMBDA_GRID),
    "ig-entropy": ("lam", LAMBDA_GRID),
    "nbv-nobs": ("alpha", ALPHA_GRID),
    "nbv-rmin": ("alpha", ALPHA_GRID),
    "nbv-nomega": ("alpha", ALPHA_GRID),
    "nbv-sigma": ("alpha", ALPHA_GRID),
    "oracle-greedy": ("lam", LAMBDA_GRID),
    "oracle-time": ("beta", BETA_GRID),
}


@dataclass(frozen=True)
class TuningConfig:
    """Where and how long each value is scored.

    Args:
        pool: a ``random:`` world distribution (the training pools; never the benchmark or test
            worlds).
        episodes: episodes per value (each a fresh world of the pool, drawn by its seed).
        noise: the localisation-noise level.
        time_budget_s: the time task's budget, s.
        seed: the first episode's seed; episode i uses ``seed + i`` for every value and policy.
    """

    pool: str = "random:mixed"
    episodes: int = 8
    noise: int = 1
    time_budget_s: float = TIME_BUDGET_S
    seed: int = 9000

    def __post_init__(self) -> None:
        check(
            self.pool.startswith("random:"), "pool", f"expected a random: pool, got {self.pool!r}"
        )
        check(self.episodes >= 1, "episodes", f"must be ≥ 1, got {self.episodes}")
        check_noise_level(self.noise)
        check_effort("time_budget_s", self.time_budget_s)


@dataclass
class Tuning:
    """The outcome of :func:`tune`: per value of ``parameter``, the (episodes,) scores."""

    policy: str
    parameter: str
    config: TuningConfig
    scores: dict[float, list[float]] = field(default_factory=dict)

    @property
    def best(self) -> float:
        """The value of the highest mean score (the smaller value on a tie)."""
        return max(sorted(self.scores), key=lambda value: np.mean(self.scores[value]))

    def table(self) -> list[dict[str, Any]]:
        """One row per value: the mean and standard error of the score, and the chosen one."""
        rows = []
        for value, scores in sorted(self.scores.items()):
            sem = np.std(scores, ddof=1) / np.sqrt(len(scores)) if len(scores) > 1 else np.nan
            rows.append({self.parameter: value, "mean": float(np.mean(scores)),
                         "sem": float(sem), "chosen": value == self.best})  # fmt: skip
        return rows


def tunable(name: str) -> tuple[str, tuple[float, ...]]:
    """The (keyword, grid) of the reference ``name``; UnknownNameError otherwise."""
    if name not in TUNABLE:
        raise UnknownNameError("tunable policy", name, TUNABLE)
    return TUNABLE[name]


def tune(
    name: str, config: TuningConfig | None = None, say: Callable[[str], None] = print
) -> Tuning:
    """Score the reference ``name`` at each value of its grid (:data:`TUNABLE`) on the same
    ``config.episodes`` episodes of the time task; the scores per value."""
    config = config or TuningConfig()
    parameter, grid = tunable(name)
    result = Tuning(name, parameter, config)
    for value in grid:
        result.scores[value] = [episode_score(name, {parameter: value}, config, i)
                                for i in range(config.episodes)]  # fmt: skip
        say(f"{name} {parameter}={value:g}: mean score {np.mean(result.scores[value]):.4f}")
    return result


def episode_score(name: str, kwargs: dict[str, float], config: TuningConfig, index: int) -> float:
    """The area under Q(t) over the budget (divided by it) of one time-task episode of policy
    ``name`` built with ``kwargs``, on the pool's world of seed ``config.seed + index``."""
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.episode import run_episode
    from nbv_gym.policies import load_policy, required_layers

    policy = load_policy(name, **kwargs)
    env = ExploreEnv(
        task="time", world=config.pool, noise=config.noise,
        observation_layers=required_layers(policy), time_budget_s=config.time_budget_s,
    )  # fmt: skip
    result = run_episode(env, policy, seed=config.seed + index)
    elapsed = np.array([row["elapsed_s"] for row in result.steps])
    q = np.array([row["q"] for row in result.steps])
    return area_under(elapsed, q, config.time_budget_s)


def tuning_markdown(tunings: list[Tuning]) -> str:
    """The tuning tables as Markdown: per policy, the mean score (± its standard error) at each
    value, the chosen value in bold."""
    from nbv_gym.reporting.formatting import markdown_table

    lines = []
    for t in tunings:
        c = t.config
        lines += [f"`{t.policy}` ({t.parameter}; {c.episodes} episodes of {c.pool} per value, "
                  f"noise {c.noise}, {c.time_budget_s:g} s, seeds {c.seed}…):", ""]  # fmt: skip
        rows = [[f"**{r[t.parameter]:g}**" if r["chosen"] else f"{r[t.parameter]:g}",
                 f"{r['mean']:.4f} ± {r['sem']:.4f}"] for r in t.table()]  # fmt: skip
        lines += [markdown_table([t.parameter, "area under Q(t) / budget"], rows), ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """``python -m nbv_gym.benchmark.tuning NAME ... [--episodes N] [--out DIR]``: tune the
    named references (all of :data:`TUNABLE` by default); ``DIR/<name>.json`` and the tables."""
    import argparse
    import json
    from pathlib import Path

    parser = argparse.ArgumentParser(prog="python -m nbv_gym.benchmark.tuning")
    parser.add_argument("names", nargs="*", help="references to tune [default: every tunable]")
    parser.add_argument("--episodes", type=int, default=TuningConfig.episodes)
    parser.add_argument("--out", type=Path, default=Path("tuning"))
    args = parser.parse_args(argv)
    config = TuningConfig(episodes=args.episodes)
    args.out.mkdir(parents=True, exist_ok=True)
    tunings = []
    for name in args.names or list(TUNABLE):
        tuning = tune(name, config)
        record = {"policy": name, "parameter": tuning.parameter, "best": tuning.best,
                  "config": vars(config), "scores": {str(v): s for v, s in tuning.scores.items()}}  # fmt: skip
        (args.out / f"{name}.json").write_text(
            json.dumps(record, indent=1) + "\n", encoding="utf-8"
        )
        tunings.append(tuning)
    print(tuning_markdown(tunings))


if __name__ == "__main__":
    main()
