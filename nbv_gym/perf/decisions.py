"""Decision time of the field's reference policies (``ig-unknown``, ``ig-entropy``,
``frontier-tour``, ``oracle-greedy``) and of the time task's teacher (``oracle-time``).

Keys of :func:`run`, each a median over a few decisions on ``pp1-trees`` (budget task, noise 1,
seed 0) after :data:`WARMUP_STEPS` steps of ``ig-unknown``, compilation excluded, single thread
unless said:
- ``ig_unknown_decision_ms``, ``ig_entropy_decision_ms``: the policy's observation layers for
  the last scan (the per-cell unknown/entropy totals of the cells it touched, the candidates and
  their volumetric gains) and its ``act``;
- ``frontier_tour_decision_ms``: ``act`` (clusters, path costs, exact tour);
- ``oracle_greedy_decision_s``: the oracle's ``gain_unknown`` layers and its ``act`` (64 trial
  scans, each inserted, scored and undone);
- ``oracle_time_decision_s``: the teacher's ``gain_unknown`` layers and its ``act`` (64 trial
  scans, each tried on the map without writing it, in two threads);
- ``oracle_time_candidate_ms``: its look-ahead alone, per candidate (the ΔQ of the decision's 64
  candidates, in two threads, divided by 64);
- ``lookahead_reference_candidate_ms``: the insert-score-undo look-ahead (the reference the
  teacher's equals bit for bit) on the same candidates, per candidate.

Those are wall times; each has a twin ``…_cpu_ms`` / ``…_cpu_s``: the process CPU time of the
same work, which is what it costs the cores whatever else the machine runs (the single-threaded
decisions' cost to one core), so the steadier figure on a shared machine.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable

import numpy as np

from nbv_gym.perf import PERF_WORLD

WARMUP_STEPS = 4
REPEATS = 5
ORACLE_REPEATS = 3


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Measure the reference policies' perf keys; progress messages go to ``progress``."""
    results: dict[str, float] = {}
    for name, key, scale, repeats in (
        ("ig-unknown", "ig_unknown_decision_ms", 1e3, REPEATS),
        ("ig-entropy", "ig_entropy_decision_ms", 1e3, REPEATS),
        ("frontier-tour", "frontier_tour_decision_ms", 1e3, REPEATS),
        ("oracle-greedy", "oracle_greedy_decision_s", 1.0, ORACLE_REPEATS),
        ("oracle-time", "oracle_time_decision_s", 1.0, ORACLE_REPEATS),
    ):
        progress(f"{name}: {WARMUP_STEPS} steps on {PERF_WORLD}, then {repeats} decisions")
        policy, env, decide = _prepared(name)
        _record(results, key, scale, _median_times(decide, repeats))
        if name == "oracle-time":
            progress("oracle-time's look-ahead and the reference's, per candidate")
            _lookahead_keys(results, policy, env)
    return results


def _record(results: dict[str, float], key: str, scale: float, times: tuple[float, float]):
    """Set ``key`` to the wall time and its ``…_cpu_<unit>`` twin to the CPU time, × ``scale``."""
    stem, _, unit = key.rpartition("_")
    results[key], results[f"{stem}_cpu_{unit}"] = scale * times[0], scale * times[1]


def _lookahead_keys(results: dict[str, float], policy, env) -> None:
    """The per-candidate keys: the teacher's look-ahead and the reference on the candidates of
    its last decision."""
    from nbv_gym.simulator import Lookahead

    goals = policy.last_evaluation["goals"]
    for key, lookahead in (
        ("oracle_time_candidate_ms", policy.lookahead),
        ("lookahead_reference_candidate_ms", Lookahead(env.unwrapped.sim)),
    ):
        times = _median_times(functools.partial(lookahead.delta_q, goals), ORACLE_REPEATS)
        _record(results, key, 1e3 / len(goals), times)


def _median_times(work: Callable[[], object], repeats: int) -> tuple[float, float]:
    """Median wall and process CPU seconds of ``repeats`` calls of ``work``."""
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        work()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return float(np.median(wall)), float(np.median(cpu))


def _prepared(name: str):
    """Policy ``name``, its environment after the warm-up steps and its compiled decision
    (module docstring)."""
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.episode import make_env
    from nbv_gym.policies import is_oracle, load_policy

    policy, warmup = load_policy(name), load_policy("ig-unknown")
    config = ExploreEnv(
        world=PERF_WORLD,
        task="budget",
        budget_scans=12,
        observation_layers=warmup.observation_layers,
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
    return policy, env, decide
