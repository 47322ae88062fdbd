"""Throughput of the statistic-based NBV decision.

Keys of :func:`run`:
- ``nbv_decision_ms``: one decision on ``pp1-trees`` after a few scans near the start — the
  occlusion update for the cells the last scan touched, all four gain layers for every candidate
  within 20 m, and the argmax of the ``nbv-nobs`` utility; median of a few repetitions, single
  thread, compilation excluded.
- ``nbv_decision_<stat>_ms`` for ``<stat>`` in nobs, rmin, nomega, sigma: the same decision
  computing only that statistic's gain layer (the decision of the policy ``nbv-<stat>``).
- ``nbv_candidates``, ``nbv_visible_cells_per_candidate``: the size of that decision.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from nbv_gym.mapping import ExplorationState, MappingConfig
from nbv_gym.nbv.config import NbvConfig
from nbv_gym.nbv.gains import GAIN_LAYERS, predict_gains
from nbv_gym.nbv.predictor import CANDIDATES_LAYER, GainPredictor

#: Robot ground poses (x, y, yaw) of the scans before the decision.
PERF_POSES = ((0.0, 0.0, 0.0), (2.0, 0.0, 0.5), (4.0, 1.0, 1.0), (3.0, 3.0, 1.5))
REPEATS = 5


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Measure the NBV perf keys; progress messages go to ``progress``."""
    from nbv_gym.core.pose import Pose
    from nbv_gym.sensor.lidar import Lidar
    from nbv_gym.worlds import load_world

    progress("loading pp1-trees")
    lidar = Lidar.for_world(load_world("pp1-trees"), noise=1)
    rng = np.random.default_rng(0)
    state = ExplorationState.from_config(MappingConfig())
    progress(f"{len(PERF_POSES)} scans near the start")
    updates = [state.apply(lidar.scan(Pose(x, y, 0.0, yaw), rng)) for x, y, yaw in PERF_POSES]
    predictor = GainPredictor(state.statistics.grid, NbvConfig(), state.occupancy.grid.res)
    for update in updates[:-1]:
        predictor.observe(state.occupancy, update.touched)
    robot_xy = np.array(PERF_POSES[-1][:2])
    cost = state.navigation.goal_cost()

    def decide(gains: tuple[str, ...] = GAIN_LAYERS) -> dict[str, np.ndarray]:
        predictor.observe(state.occupancy, updates[-1].touched)
        mask = state.navigation.goal_mask()
        layers = predictor.predict(state.statistics, robot_xy, mask, (*gains, CANDIDATES_LAYER))
        utility = layers[gains[0]].ravel() - 2.0 * cost
        utility[layers[CANDIDATES_LAYER].ravel() == 0] = -np.inf
        layers["choice"] = np.array(int(np.argmax(utility)))
        return layers

    progress("compiling")
    layers = decide()
    progress(f"timing {REPEATS} decisions of all four gains, and of each alone")
    figures = {"nbv_decision_ms": _median_ms(decide)}
    for gain in GAIN_LAYERS:
        key = f"nbv_decision_{gain.removeprefix('gain_')}_ms"
        figures[key] = _median_ms(functools.partial(decide, (gain,)))
    n_candidates = int(layers[CANDIDATES_LAYER].sum())
    n_visible = _visible_per_candidate(state, predictor, robot_xy)
    return {
        **figures,
        "nbv_candidates": float(n_candidates),
        "nbv_visible_cells_per_candidate": n_visible,
    }


def _median_ms(work: Callable[[], object]) -> float:
    """Median wall time of :data:`REPEATS` calls of ``work``, milliseconds."""
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def _visible_per_candidate(state: ExplorationState, predictor: GainPredictor, robot_xy) -> float:
    """Mean number of cells visible from a candidate: the ratio of the summed to the mean n_obs
    gain (every visible cell gains > 0). Kept out of the timed decision."""
    candidates = predictor.candidates(state.navigation.goal_mask(), robot_xy)
    args = (state.statistics, predictor.occlusion.mask, robot_xy, candidates)
    sensor = predictor.sensor
    total = predict_gains(*args, predictor.config, ("gain_nobs",), sensor)["gain_nobs"].ravel()
    mean_config = replace(predictor.config, aggregate="mean")
    mean = predict_gains(*args, mean_config, ("gain_nobs",), sensor)["gain_nobs"].ravel()
    seen = candidates & (mean > 0)
    counts = np.rint(total[seen].astype(np.float64) / mean[seen])
    return float(counts.sum() / max(int(candidates.sum()), 1))
