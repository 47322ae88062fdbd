"""Exploration runs for the informative-share study: episodes that keep their scans.

The WD paper builds, from one drive through each world, two maps at 0.05 m and 0.1 m. Here an
episode (any policy, budget protocol: no early termination) writes an ordinary run folder
(:func:`nbv_gym.episode.write_run_folder`: ``summary.json``, ``map.npz`` at the run's resolution, …)
plus ``scans.npz``, the scans as the map received them (sensor origin and map-frame points under the
noisy pose). Replaying them into an :class:`~nbv_gym.mapping.OccupancyMap` of another resolution
gives the same drive mapped at that resolution; at the run's own resolution it gives the run's map
back exactly.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from nbv_gym.core.arrayfiles import read_npz
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import GRID_ARRAYS, GridSpec
from nbv_gym.core.inputs import read_json
from nbv_gym.mapping.mapfile import load_map
from nbv_gym.studies import StudyError

SCANS_NAME = "scans.npz"
MAP_NAME = "map.npz"
SUMMARY_NAME = "summary.json"


class ScanLog:
    """A lidar that keeps every scan it returns: wraps ``lidar`` (anything with ``scan(robot,
    rng)``) and forwards every other attribute to it."""

    def __init__(self, lidar):
        self._lidar = lidar
        self.origins: list[np.ndarray] = []
        self.points: list[np.ndarray] = []

    def scan(self, robot, rng):
        """Scan with the wrapped lidar and keep the scan's origin and points."""
        scan = self._lidar.scan(robot, rng)
        self.origins.append(np.asarray(scan.origin, np.float64))
        self.points.append(np.asarray(scan.points_map, np.float64))
        return scan

    def __getattr__(self, name):
        return getattr(self._lidar, name)

    def save(self, path: Path, occupancy) -> None:
        """Write the scans and the map ``occupancy``'s box and sensor model to ``path`` (.npz)."""
        counts = np.array([len(p) for p in self.points], np.int64)
        np.savez_compressed(
            path,
            origins=np.stack(self.origins),
            points=np.concatenate(self.points),
            counts=counts,
            low_m=occupancy.grid.low,
            high_m=occupancy.grid.high,
            params=json.dumps(occupancy.params),
        )


def make_run(world: str, noise: int, policy: str, seed: int, max_steps: int, out: Path) -> Path:
    """Run ``policy`` for ``max_steps`` scans after the first (no early termination) on ``world``
    at localisation noise ``noise`` from ``seed``; write the run folder and its scans to ``out``."""
    from nbv_gym.core.protocol import EpisodeConfig
    from nbv_gym.env.explore import EnvConfig
    from nbv_gym.episode import make_env, run_episode, write_run_folder
    from nbv_gym.policies import load_policy
    from nbv_gym.sensor.lidar import Lidar
    from nbv_gym.simulator import SimulatorConfig

    agent = load_policy(policy)
    episode = EpisodeConfig(max_steps=max_steps, discovered_target=1.0)
    env = make_env(EnvConfig(SimulatorConfig(world=world, noise=noise, episode=episode)), agent)
    log = ScanLog(env.sim.lidar)
    env.sim.lidar = cast(Lidar, log)  # a ScanLog scans like the lidar it wraps
    result = run_episode(env, agent, seed)
    meta = {"world": world, "policy": policy, "noise": noise, "seed": seed}
    write_run_folder(out, env, result, meta)
    log.save(out / SCANS_NAME, env.sim.occupancy)
    return out


@dataclass(frozen=True)
class RunFolder:
    """A run folder (``nbv-gym run --out``): its ``path``, ``world`` and ``noise`` level."""

    path: Path
    world: str
    noise: int

    @property
    def has_scans(self) -> bool:
        """Whether the folder keeps its scans (so it can be mapped at another resolution)."""
        return (self.path / SCANS_NAME).is_file()


def find_runs(root: Path) -> list[RunFolder]:
    """Every run folder under ``root`` (a ``summary.json`` beside a ``map.npz``), sorted by path."""
    if not root.is_dir():
        kind = "is a file" if root.exists() else "does not exist"
        raise StudyError(f"{root} {kind}; --runs takes a folder of `nbv-gym run --out` folders")
    runs = []
    for summary in sorted(root.rglob(SUMMARY_NAME)):
        if (summary.parent / MAP_NAME).is_file():
            try:
                data = read_json(summary, "Run summary")
                runs.append(RunFolder(summary.parent, str(data["world"]), int(data["noise"])))
            except (ValueError, KeyError, TypeError, OSError, NbvGymError) as error:
                raise StudyError(f"{summary}: not a run's summary ({error!r})") from None
    if not runs:
        raise StudyError(
            f"{root} holds no run folder (summary.json beside map.npz). A sweep folder keeps no "
            "maps: give a folder of `nbv-gym run --out` folders, or leave --runs out to make runs"
        )
    return runs


def run_map(run: RunFolder, resolution_m: float):
    """The :class:`~nbv_gym.mapping.OccupancyMap` of ``run`` at ``resolution_m``: its saved map when
    that has this resolution, else its scans replayed into a new map; None when it has no scans."""
    path = run.path / MAP_NAME
    saved_res = GridSpec.from_arrays(read_npz(path, names=GRID_ARRAYS), str(path)).res
    if np.isclose(saved_res, resolution_m):
        return load_map(run.path / MAP_NAME)
    return replay(run.path / SCANS_NAME, resolution_m) if run.has_scans else None


def replay(path: Path, resolution_m: float):
    """A new :class:`~nbv_gym.mapping.OccupancyMap` at ``resolution_m`` over the recorded map box,
    with the recorded sensor model, holding the scans of ``path`` (.npz) inserted in order."""
    from nbv_gym.mapping import OccupancyMap

    data = read_npz(path)  # sizes checked against the file before anything is allocated
    origins, points, counts = data["origins"], data["points"], data["counts"]
    grid = GridSpec.from_bounds(tuple(data["low_m"]), tuple(data["high_m"]), resolution_m)
    params = json.loads(str(data["params"]))
    occupancy = OccupancyMap(grid, **params)
    for origin, chunk in zip(origins, np.split(points, np.cumsum(counts)[:-1]), strict=True):
        occupancy.insert(origin, chunk)
    return occupancy
