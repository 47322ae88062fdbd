"""The robot's scan poses of a run as a CSV file (``trajectory.csv`` in a run folder)."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.inputs import MAX_TABLE_BYTES, read_input

TRAJECTORY_NAME = "trajectory.csv"
TRAJECTORY_COLUMNS = ("step", "x_m", "y_m", "z_m", "yaw_rad")


def write_trajectory(path: str | Path, poses) -> Path:
    """Write the scan poses (objects with ``x``, ``y``, ``z``, ``yaw``; step 0 = the first scan)
    to a CSV of :data:`TRAJECTORY_COLUMNS`."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(TRAJECTORY_COLUMNS)
        for step, pose in enumerate(poses):
            writer.writerow([step, f"{pose.x:.6f}", f"{pose.y:.6f}", f"{pose.z:.6f}",
                             f"{pose.yaw:.6f}"])  # fmt: skip
    return path


def read_trajectory(path: str | Path) -> FloatArray:
    """(k, 4) x, y, z (m) and yaw (rad) of each scan from a :func:`write_trajectory` CSV (a
    regular file: a FIFO or device is refused, :class:`~nbv_gym.core.inputs.InputFileError`)."""
    data = read_input(path, "trajectory", MAX_TABLE_BYTES)
    table = np.loadtxt(io.BytesIO(data), delimiter=",", skiprows=1, ndmin=2)
    return table[:, 1:5]
