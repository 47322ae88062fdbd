"""Decision time of the field's reference policies (``ig-unknown``, ``ig-entropy``,
``frontier-tour``, ``oracle-greedy``).

Keys of :func:`run`, each a median over a few decisions on ``pp1-trees`` (budget task, noise 1,
seed 0) after :data:`WARMUP_STEPS` steps of ``ig-unknown``, compilation excluded, single thread:
- ``ig_unknown_decision_ms``, ``ig_entropy_decision_ms``: the policy's observation layers for
  the last scan (the per-cell unknown/entropy totals of the cells it touched, the candidates and
  their volumetric gains) and its ``act``;
- ``frontier_tour_decision_ms``: ``act`` (clusters, path costs, exact tour);
- ``oracle_greedy_decision_s``: the oracle's ``gain_unknown`` layers and its ``act`` (64 trial
  scans, each inserted, scored and undone).

Those are wall times; each has a twin ``…_cpu_ms`` / ``…_cpu_s``: the process CPU time of the
same decisions, which is what a decision costs one core whatever else the machine runs (the
decisions are single-threaded), so the steadier figure on a shared machine.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from nbv_gym.perf import PERF_WORLD

WARMUP_STEPS = 4
REPEATS = 5
ORACLE_REPEATS = 3


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Measure the reference policies' perf keys; progress messages go to ``progress``."""
    results = {}
    for name, key, scale, repeats in (
        ("ig-unknown", "ig_unknown_decision_ms", 1e3, REPEATS),
        ("ig-entropy", "ig_entropy_decision_ms", 1e3, REPEATS),
        ("frontier-tour", "frontier_tour_decision_ms", 1e3, REPEATS),
        ("oracle-greedy", "oracle_greedy_decision_s", 1.0, ORACLE_REPEATS),
    ):
        progress(f"{name}: {WARMUP_STEPS} steps on {PERF_WORLD}, then {repeats} decisions")
        wall, cpu = _decision_times(name, repeats)
        results[key] = scale * wall
        stem, _, unit = key.rpartition("_")
        results[f"{stem}_cpu_{unit}"] = scale * cpu
    return results


def _decision_times(name: str, repeats: int) -> tuple[float, float]:
    """Median wall and CPU seconds of one decision of policy ``name`` (module docstring)."""
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.episode import make_env
    from nbv_gym.policies import is_oracle, load_policy

    policy, warmup = load_policy(name), load_policy("ig-unknown")
    config = ExploreEnv(
        world=PERF_WORLD, task="budget", max_steps=12, observation_layers=warmup.observation_layers
    ).config
    env = make_env(config, policy)
    observation, info = env.reset(seed=0)
    attach = getattr(policy, "attach", None)  # an oracle reads the environment
    if is_oracle(policy) and callable(attach):
        attach(env)
    for seed_policy in (warmup, policy):
        seed_policy.reset(0)
    for _ in range(WARMUP_STEPS):
        observation, *_, info = env.step(warmup.act(observation, info))

    def decide() -> int:  # the layers the policy reads (none for frontier-tour), then act
        layers = env.optional.compute(env._outcome) if policy.observation_layers else {}
        return policy.act({**observation, **layers}, info)

    decide()  # compilation
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        decide()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return float(np.median(wall)), float(np.median(cpu))
