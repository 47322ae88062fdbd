"""Map files: an :class:`~nbv_gym.mapping.occupancy.OccupancyMap` saved to and read from a
``.npz`` file (the known voxels' flat indices and log-odds, the grid, the sensor model's
parameters, the ``NAME@DIGEST`` of the world it maps and, for a scene world, how the world's
frame lies in the scene file's)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.core.arrayfiles import array_of, read_npz, read_saved
from nbv_gym.core.errors import ConfigError, DataFileError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap

FORMAT = "nbv_gym.OccupancyMap/1"
_PARAM_KEYS = ("p_hit", "p_miss", "p_clamp_min", "p_clamp_max", "p_occupied", "max_range_m")
#: The largest map :func:`load_map` reads (voxels; 4 bytes each, a few copies while
#: loading): 8 × the default 0.1 m map, the default box at 0.05 m.
MAX_LOAD_VOXELS = 1 << 28


def save_map(
    occupancy: OccupancyMap, path: str | Path, world: str = "", frame: dict | None = None
) -> None:
    """Write ``occupancy`` to a ``.npz`` file (known voxels only); ``world`` (``NAME@DIGEST`` of
    the world it maps, see :func:`recorded_world`) is recorded so that scoring it against
    another world can be refused, and ``frame`` (a scene world's, see :func:`recorded_frame`)
    so that a cloud in the scene file's frame can be scored against it."""
    index, logodds = occupancy.voxels_at_least(0.0)
    arrays: dict[str, Any] = {
        "format": np.array(FORMAT),
        "world": np.array(world),
        "frame": np.array(json.dumps(frame or {})),
        **occupancy.grid.to_arrays(),
        "params": np.array([occupancy.params[k] for k in _PARAM_KEYS]),
        "index": occupancy.grid.ravel(index).astype(np.int64),
        "logodds": logodds,
    }
    np.savez_compressed(Path(path), **arrays)


def recorded_world(path: str | Path) -> str:
    """The ``NAME@DIGEST`` of the world the saved map at ``path`` maps ("" when it records
    none: maps saved before it was recorded, or without a world)."""
    world = read_npz(path, names=("world",)).get("world")
    return str(world) if world is not None and world.shape == () else ""


def recorded_frame(path: str | Path) -> dict[str, Any]:
    """How the frame of the world a saved map maps lies in its scene file's: ``offset_m`` (3,)
    metres, ``scale`` and ``up`` (world = the file's points scaled to metres, turned z up, less
    ``offset_m``); {} for a map of a procedural world, or one saved before frames were
    recorded. :class:`DataFileError` for a record that is not such a frame."""
    value = read_npz(path, names=("frame",)).get("frame")
    if value is None or value.shape != () or not str(value) or str(value) == "{}":
        return {}
    try:
        frame = json.loads(str(value))
        offset = [float(x) for x in frame["offset_m"]]
        scale, up = float(frame["scale"]), frame["up"]
        valid = len(offset) == 3 and all(map(math.isfinite, [*offset, scale])) and scale > 0
    except (ValueError, TypeError, KeyError):
        valid = False
    if not valid or up not in ("z", "y"):
        raise DataFileError(f"{path}: its scene frame record is not one nbv-gym writes: {value}")
    return {"offset_m": offset, "scale": scale, "up": up}


def load_map(path: str | Path) -> OccupancyMap:
    """Read a map written by :func:`save_map`; :class:`DataFileError` for any other file, or a
    grid of more than :data:`MAX_LOAD_VOXELS` voxels (checked before allocating)."""
    data = read_saved(path, FORMAT, "occupancy map")
    grid = GridSpec.from_arrays(data, str(path))
    if math.prod(grid.shape) > MAX_LOAD_VOXELS:
        raise DataFileError(
            f"{path}: a map of {grid.shape} voxels is larger than {MAX_LOAD_VOXELS} voxels"
        )
    values = array_of(data, "params", "f", (len(_PARAM_KEYS),), path)
    params = dict(zip(_PARAM_KEYS, values.tolist(), strict=True))
    _check_params(params, path)
    index = array_of(data, "index", "iu", (None,), path)
    if index.size and not (0 <= index.min() and index.max() < grid.size):
        raise DataFileError(f"{path}: voxel indices outside the {grid.shape} grid")
    logodds = np.full(grid.shape, np.nan, np.float32)
    logodds.ravel()[index] = array_of(data, "logodds", "f", index.shape, path)
    return OccupancyMap.from_logodds(grid, logodds, **params)


def _check_params(params: dict[str, float], path: str | Path) -> None:
    """:class:`DataFileError` unless a saved map's sensor-model parameters are valid."""
    try:
        model: dict[str, Any] = {k: v for k, v in params.items() if k != "max_range_m"}
        MapConfig(**model)
    except ConfigError as error:
        raise DataFileError(f"{path}: {error}") from None
    if not 0 < params["max_range_m"] < math.inf:
        raise DataFileError(
            f"{path}: max_range_m must be finite and > 0, got {params['max_range_m']}"
        )
