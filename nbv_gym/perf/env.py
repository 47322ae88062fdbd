"""Perf suite of the environment on pp1-trees, noise 1, no optional layers, single thread.

Keys of :func:`run`:
- ``env_step_ms``: one env step (median over random valid goals).
- ``env_lidar_ms``, ``env_insert_ms``, ``env_statistics_ms``, ``env_navigation_ms``,
  ``env_quality_ms``, ``env_observation_ms``: the parts of that step (medians of the same steps):
  the scan, its insertion into the map, the viewpoint statistics update, the navigation
  re-projection and plan, the quality update (probability blocks and cuboid metrics), and the
  observation with ``info``.
- ``env_raw_cast_ms``: one raw Embree cast of the rays of a step's scan (the embreex call alone,
  its float32 arrays made beforehand; CPU time of the process): the unit of the ``_raw`` keys, which
  divide each step's CPU time by that of the raw cast of its own scan (medians over the
  steps), so that they compare across machines and hold on a shared one.
- ``env_step_raw``: the step in raw casts; its parts ``env_postprocess_raw`` (the lidar's work
  besides the cast: noise, filtering, frames), ``env_insert_raw``, ``env_quality_raw``,
  ``env_statistics_raw``, ``env_navigation_raw``, ``env_observation_raw`` and
  ``env_python_raw`` (the rest of the step: the environment's and simulator's own code).
- ``env_lidar_raw``, ``env_cast_raw``, ``env_reproject_raw``, ``env_plan_raw``,
  ``env_summary_raw``: details of those parts in raw casts (medians over the same steps): the
  whole scan (the raw cast and the post-processing; its inverse is the share of a scan's CPU
  time that Embree's cast takes), the lidar's cast with its arrays (the rotation into the map
  frame, the float32 rays, the hits' distances), the navigation's re-projection and its plan
  (the path search), and the quality's summary (the means over the comparison volume).
- ``env_reset_raw``: a reset in raw casts of the start pose's scan; its parts
  ``env_reset_clear_raw`` (the previous episode's map, statistics, quality and navigation
  cleared) and ``env_reset_insert_raw`` (the first scan's insertion into the map).
- ``env_insert_ns_per_update``: the insertion's CPU time per voxel updated (a hit or a
  miss each; ``ScanUpdate.n_updated``), nanoseconds.
- ``env_step_os1_64_ms``, ``env_lidar_os1_64_ms``: the same step and its scan with the OS1-64
  preset (``lidar="os1-64"``: 64 beams × 1024 azimuth samples, 8 × the default's rays).
- ``env_reset_ms``: one reset after the first (median of a few; it takes the first scan).
- ``env_rss_mb``: resident memory (VmRSS, MiB) of a fresh process holding one environment after
  3 resets and 20 steps; ``env_rss_anon_mb`` its anonymous part (without the shared libraries'
  mapped files).
- ``episode_s``, ``episode_steps``: one full closest-frontier episode.
"""

from __future__ import annotations

import functools
import json
import subprocess
import sys
import time
from collections.abc import Callable

import numpy as np

from nbv_gym.perf import PERF_WORLD

STEPS = 20
RESETS = 5

#: The suffix of a part's key in the dict of :func:`_time_parts` under which its CPU time is.
CPU = ":cpu"
#: Step parts: key → the (object path from the env, method name) pairs whose times add up to it.
PARTS = {
    "env_lidar_ms": (("sim.lidar", "scan"),),
    "env_insert_ms": (("sim.state.occupancy", "insert"),),
    "env_statistics_ms": (("sim.state.statistics", "update"),),
    "env_navigation_ms": (
        ("sim.state.navigation", "reproject"),
        ("sim.state", "update_navigation"),
        ("sim.state.navigation", "plan"),
    ),
    "env_quality_ms": (("sim", "_update_quality"),),
    "env_observation_ms": (("", "_observation"), ("", "_info")),
}
#: Details of the parts (their times are inside the parts'): key → method pairs, as in
#: :data:`PARTS`.
DETAILS = {
    "env_cast_ms": (("sim.lidar", "_cast"),),
    "env_reproject_ms": (("sim.state.navigation", "reproject"),),
    "env_plan_ms": (("sim.state.navigation", "plan"),),
    "env_summary_ms": (("sim.quality", "summary"),),
}
#: Parts of a reset, as in :data:`PARTS`.
RESET_PARTS = {
    "env_reset_clear_ms": (("sim", "clear"),),
    "env_reset_insert_ms": (("sim.state.occupancy", "insert"),),
}


def run(progress: Callable[[str], None]) -> dict[str, float]:
    """Step, reset and memory figures of one environment, and a closest-frontier episode."""
    from nbv_gym.env import ExploreEnv
    from nbv_gym.episode import run_episode
    from nbv_gym.policies import load_policy

    env = ExploreEnv(world=PERF_WORLD, noise=1, max_steps=STEPS + 5)
    progress(f"{RESETS} resets and {STEPS} env steps on {PERF_WORLD}")
    env.reset(seed=0)  # compiles and builds everything once
    resets = [_seconds(functools.partial(env.reset, seed=seed)) for seed in range(1, RESETS + 1)]
    reset_cpu, reset_parts = _reset_cpu(env)
    raw = float(np.median([raw_cast_s(env.sim) for _ in range(RESETS)]))  # the start pose's
    figures = {
        "env_reset_ms": 1e3 * float(np.median(resets)),
        "env_reset_raw": float(np.median(reset_cpu)) / raw,
        **{
            key.removesuffix("_ms") + "_raw": _median_of(reset_parts, key + CPU) / raw
            for key in RESET_PARTS
        },
        **_steps(env),
    }
    progress(f"{STEPS} env steps on {PERF_WORLD} with the OS1-64 preset")
    dense = ExploreEnv(world=PERF_WORLD, noise=1, max_steps=STEPS + 5, lidar="os1-64")
    dense.reset(seed=0)
    os1_64 = _steps(dense)
    figures.update(
        env_step_os1_64_ms=os1_64["env_step_ms"], env_lidar_os1_64_ms=os1_64["env_lidar_ms"]
    )
    progress("memory of one environment in a fresh process")
    figures.update(_memory())
    progress(f"a closest-frontier episode on {PERF_WORLD}")
    episode = ExploreEnv(world=PERF_WORLD, noise=1)
    result = run_episode(episode, load_policy("closest-frontier"), seed=0)
    figures.update(episode_s=result.wall_time_s, episode_steps=float(len(result.steps) - 1))
    return figures


def _steps(env) -> dict[str, float]:
    """Median step time and the median time of each part (:data:`PARTS`) over the steps; the
    same in raw casts of each step's scan, and the insertion's time per voxel updated."""
    _, info = env.reset(seed=1)
    spent, updated = _time_parts(env), _count_updates(env)
    rng, steps, parts, raws, per_update = np.random.default_rng(0), [], [], [], []
    for _ in range(STEPS):
        goal = int(rng.choice(np.flatnonzero(info["action_mask"])))
        spent.clear()
        updated.clear()
        start, start_cpu = time.perf_counter(), time.process_time()
        _, _, terminated, truncated, info = env.step(goal)
        steps.append((time.perf_counter() - start, time.process_time() - start_cpu))
        parts.append(dict(spent))
        raws.append(raw_cast_s(env.sim))
        per_update.append(spent.get("env_insert_ms" + CPU, 0.0) / max(sum(updated), 1))
        if terminated or truncated:
            _, info = env.reset(seed=len(steps))
            _time_parts(env, spent)
            _count_updates(env, updated)
    wall, cpu = np.array(steps).T
    figures = {"env_step_ms": 1e3 * float(np.median(wall))}
    for key in PARTS:
        figures[key] = 1e3 * float(np.median([p.get(key, 0.0) for p in parts]))
    figures["env_raw_cast_ms"] = 1e3 * float(np.median(raws))
    figures["env_insert_ns_per_update"] = 1e9 * float(np.median(per_update))
    for key, share in _raw_shares(list(cpu), parts, raws).items():
        figures[key] = float(np.median(share))
    for key in ("env_lidar_ms", *DETAILS):
        share = [p.get(key + CPU, 0.0) / raw for p, raw in zip(parts, raws, strict=True)]
        figures[key.removesuffix("_ms") + "_raw"] = float(np.median(share))
    return figures


def _median_of(parts: list[dict[str, float]], key: str) -> float:
    """The median of ``key`` over ``parts`` (0 where a part lacks it)."""
    return float(np.median([p.get(key, 0.0) for p in parts]))


def _reset_cpu(env) -> tuple[list[float], list[dict[str, float]]]:
    """CPU seconds of :data:`RESETS` resets, and of their parts (:data:`RESET_PARTS`, under
    the key + :data:`CPU`); the parts' timers are taken off after."""
    spent: dict[str, float] = {}
    _time_parts(env, spent, RESET_PARTS)
    cpu, parts = [], []
    for seed in range(RESETS):
        spent.clear()
        cpu.append(_cpu_seconds(functools.partial(env.reset, seed=seed)))
        parts.append(dict(spent))
    _untime_parts(env, RESET_PARTS)
    return cpu, parts


def _raw_shares(steps: list[float], parts: list[dict[str, float]], raws: list[float]):
    """Per step, the step and its parts in raw casts of its scan (CPU times): ``env_step_raw``
    and the ``env_<part>_raw`` keys, the lidar's part less the cast itself
    (``env_postprocess_raw``) and the rest of the step (``env_python_raw``)."""
    spent = {key: np.array([p.get(key + CPU, 0.0) for p in parts]) for key in PARTS}
    raw, step = np.array(raws), np.array(steps)
    shares = {"env_step_raw": step / raw, "env_postprocess_raw": spent["env_lidar_ms"] / raw - 1}
    for key in PARTS:
        if key != "env_lidar_ms":
            shares[key.removesuffix("_ms") + "_raw"] = spent[key] / raw
    shares["env_python_raw"] = (step - sum(spent.values())) / raw
    return shares


def raw_cast_s(sim) -> float:
    """CPU seconds (the process's) of one raw Embree cast of the rays of the scan from ``sim``'s current
    robot pose: the embreex call alone (as the lidar makes it), its float32 arrays made
    beforehand."""
    lidar = sim.lidar
    pose = lidar.sensor_pose(sim.pose)
    directions = np.ascontiguousarray(pose.rotate(lidar.directions), np.float32)
    origins = np.ascontiguousarray(np.broadcast_to(pose.position, directions.shape), np.float32)
    start = time.process_time()
    lidar.scene._scene.run(origins, directions, query="DISTANCE")
    return time.process_time() - start


def _count_updates(env, counts: list[int] | None = None) -> list[int]:
    """Wrap the map's ``insert`` (again after a reset that replaced it) to append each scan's
    ``n_updated`` to the list returned."""
    counts = [] if counts is None else counts
    occupancy = env.sim.occupancy
    insert = occupancy.insert
    if not getattr(insert, "perf_counted", False):

        def counted(*args, **kwargs):
            update = insert(*args, **kwargs)
            counts.append(update.n_updated)
            return update

        counted.__dict__["perf_counted"] = True
        counted.__dict__["perf_timed"] = getattr(insert, "perf_timed", False)
        occupancy.insert = counted
    return counts


def _time_parts(
    env, spent: dict[str, float] | None = None, parts: dict | None = None
) -> dict[str, float]:
    """Wrap the methods of ``parts`` (default: :data:`PARTS` and :data:`DETAILS`) that exist on
    their instances (again after a reset that replaced them); returns the dict the wrappers add
    their seconds to (wall, and the process's CPU under the key + :data:`CPU`). A part's time is
    counted once when its methods call each other; a method may count in several parts."""
    spent = {} if spent is None else spent
    running: dict[str, int] = {}
    keys: dict[tuple[str, str], list[str]] = {}
    for key, methods in (parts or PARTS | DETAILS).items():
        for method in methods:
            keys.setdefault(method, []).append(key)
    for (path, name), method_keys in keys.items():
        owner = _owner(env, path)
        method = getattr(owner, name, None)
        if method is not None and not getattr(method, "perf_timed", False):
            setattr(owner, name, _timed(method, tuple(method_keys), spent, running))
    return spent


def _untime_parts(env, parts: dict) -> None:
    """Take the wrappers of :func:`_time_parts` for ``parts`` off their instances."""
    for methods in parts.values():
        for path, name in methods:
            owner = _owner(env, path)
            if getattr(getattr(owner, name, None), "perf_timed", False):
                delattr(owner, name)


def _owner(env, path: str):
    """The object at the dotted ``path`` from ``env`` ("": the env; None if missing)."""
    owner = env
    for attribute in filter(None, path.split(".")):
        owner = getattr(owner, attribute, None)
    return owner


def _timed(method, keys: tuple[str, ...], spent: dict[str, float], running: dict[str, int]):
    """``method`` adding its seconds to ``spent[key]``, and its CPU seconds to
    ``spent[key + CPU]``, for each of ``keys``."""

    def timed(*args, **kwargs):
        start, start_cpu = time.perf_counter(), time.process_time()
        for key in keys:
            running[key] = running.get(key, 0) + 1
        try:
            return method(*args, **kwargs)
        finally:
            wall, cpu = time.perf_counter() - start, time.process_time() - start_cpu
            for key in keys:
                running[key] -= 1
                if not running[key]:
                    spent[key] = spent.get(key, 0.0) + wall
                    spent[key + CPU] = spent.get(key + CPU, 0.0) + cpu

    timed.__dict__["perf_timed"] = True
    timed.__dict__["perf_counted"] = getattr(method, "perf_counted", False)
    return timed


def _memory() -> dict[str, float]:
    """``env_rss_mb`` and ``env_rss_anon_mb`` measured in a fresh Python process."""
    code = "from nbv_gym.perf.env import one_env_memory; one_env_memory()"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def one_env_memory() -> None:
    """Print (JSON) this process's memory after one environment's 3 resets and 20 steps."""
    from nbv_gym.env import ExploreEnv

    env = ExploreEnv(world=PERF_WORLD, noise=1, max_steps=STEPS + 5)
    for seed in range(3):
        _, info = env.reset(seed=seed)
    rng = np.random.default_rng(0)
    for _ in range(STEPS):
        goal = int(rng.choice(np.flatnonzero(info["action_mask"])))
        _, _, terminated, truncated, info = env.step(goal)
        if terminated or truncated:
            _, info = env.reset(seed=3)
    print(
        json.dumps({"env_rss_mb": _status_mib("VmRSS"), "env_rss_anon_mb": _status_mib("RssAnon")})
    )


def _status_mib(key: str) -> float:
    """A memory figure of /proc/self/status in MiB (NaN where there is no /proc, e.g. macOS)."""
    try:
        with open("/proc/self/status", encoding="utf-8") as status:
            lines = dict(line.split(":", 1) for line in status)
    except OSError:
        return float("nan")
    return int(lines[key].split()[0]) / 1024


def _seconds(work: Callable[[], object]) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def _cpu_seconds(work: Callable[[], object]) -> float:
    start = time.process_time()
    work()
    return time.process_time() - start
