"""Robot and sensor poses, and the localisation noise of the benchmark (docs/protocol.md#lidar)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.config import check
from nbv_gym.core.protocol import NOISE_LEVELS, check_noise_level


@dataclass(frozen=True)
class Pose:
    """A pose in the map frame: position ``(x, y, z)`` in metres and heading ``yaw`` in radians
    (rotation about +z; roll and pitch are zero)."""

    x: float
    y: float
    z: float
    yaw: float = 0.0

    @property
    def position(self) -> FloatArray:
        """(3,) float: x, y, z in metres."""
        return np.array([self.x, self.y, self.z])

    def rotation(self) -> FloatArray:
        """(3, 3) float: the rotation from this pose's frame to the map frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def rotate(self, vectors: FloatArray, out: np.ndarray | None = None) -> np.ndarray:
        """(n, 3) float: the (n, 3) ``vectors`` of this pose's frame turned into the map frame
        (by the yaw; z unchanged), written into ``out`` when given (an (n, 3) array of any float
        dtype: each value computed in float64, then rounded to it). Written elementwise, not as
        a matrix product: a product goes to the BLAS library, whose kernel (chosen by the CPU)
        may fuse multiply and add and change the last bit, so results would differ between
        machines."""
        vectors = np.asarray(vectors, dtype=float)
        c, s = math.cos(self.yaw), math.sin(self.yaw)  # the C library's: numpy's varies by CPU
        x, y = vectors[:, 0], vectors[:, 1]
        out = np.empty(vectors.shape) if out is None else out
        out[:, 0], out[:, 1], out[:, 2] = c * x - s * y, s * x + c * y, vectors[:, 2]
        return out

    def to_map(self, points: FloatArray) -> FloatArray:
        """(n, 3) map-frame points of (n, 3) points given in this pose's frame."""
        out = self.rotate(points)
        out += self.position
        return out


@dataclass(frozen=True)
class LocalisationNoise:
    """White Gaussian noise on the pose used for mapping (the true pose is used for ray casting).

    ``sigma_position_m`` applies independently to x, y and z; ``sigma_yaw_rad`` to the heading.
    """

    sigma_position_m: float = 0.0
    sigma_yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        check(self.sigma_position_m >= 0, "sigma_position_m", "must be ≥ 0")
        check(self.sigma_yaw_rad >= 0, "sigma_yaw_rad", "must be ≥ 0")

    @classmethod
    def level(cls, level: int) -> LocalisationNoise:
        """The paper's noise level ``level`` (0: perfect; :data:`~nbv_gym.core.protocol.NOISE_LEVELS`)."""
        check_noise_level(level)
        return cls(*NOISE_LEVELS[level])

    def perturb(self, pose: Pose, rng: np.random.Generator) -> Pose:
        """``pose`` with noise drawn from ``rng`` (four normal draws, even when σ is 0)."""
        dx, dy, dz = rng.normal(0.0, 1.0, 3) * self.sigma_position_m
        dyaw = rng.normal(0.0, 1.0) * self.sigma_yaw_rad
        return Pose(pose.x + dx, pose.y + dy, pose.z + dz, pose.yaw + dyaw)
