"""The simulated Ouster OS1-16 lidar (SPEC §2): beam pattern, Embree ray casting, range noise.

A :class:`Lidar` casts its rays from the *true* sensor pose against the world mesh, perturbs the
ranges with the mixture noise model, drops the returns the real sensor would drop, and expresses the
points in the map frame under the *noisy* pose that mapping will use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.arrays import FloatArray, IntArray
from nbv_gym.pose import Pose


@dataclass(frozen=True)
class Scan:
    """One lidar scan.

    Attributes:
        points_sensor: (n, 3) float64 returns in the sensor frame, metres.
        ranges: (n,) float64 measured range of each return, metres.
        ray_index: (n,) int64 index of each return's ray in the beam pattern
            (``channel * n_azimuth + azimuth``).
        true_pose: the sensor pose the rays were cast from.
        pose: the noisy sensor pose used to express the points in the map frame.
        points_map: (n, 3) float64 returns in the map frame under ``pose``, metres.
    """

    points_sensor: FloatArray
    ranges: FloatArray
    ray_index: IntArray
    true_pose: Pose
    pose: Pose
    points_map: FloatArray

    @property
    def origin(self) -> FloatArray:
        """(3,) float: the sensor position used for mapping (the noisy pose), metres."""
        return self.pose.position

    def __len__(self) -> int:
        return len(self.ranges)
