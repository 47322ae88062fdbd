"""The simulated Ouster OS1-16 lidar (docs/protocol.md#lidar): beam pattern, Embree ray casting, range noise.

A :class:`Lidar` casts its rays from the *true* sensor pose against the world mesh, perturbs the
ranges with the mixture noise model, drops the returns the real sensor would drop, and expresses the
points in the map frame under the *noisy* pose that mapping will use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from nbv_gym.core import libm
from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.core.config import check
from nbv_gym.core.errors import PoseError
from nbv_gym.core.pose import LocalisationNoise, Pose
from nbv_gym.worlds.raycast import RayScene

if TYPE_CHECKING:
    from nbv_gym.worlds import World


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


@dataclass(frozen=True)
class RangeNoise:
    """The per-ray range-noise mixture of the authors' simulated lidar (docs/protocol.md#lidar).

    With probability ``p_gaussian`` add N(0, ``sigma_m``); with ``p_short`` add
    −|N(0, ``short_sigma_per_m`` · r)| (always shorter); otherwise replace r by
    U(``outlier_min_m``, r + ``outlier_margin_m``).
    """

    sigma_m: float = 0.008
    p_gaussian: float = 0.96
    p_short: float = 0.039
    short_sigma_per_m: float = 0.01
    outlier_min_m: float = 0.3
    outlier_margin_m: float = 0.03

    def __post_init__(self) -> None:
        check(self.sigma_m >= 0, "sigma_m", "must be ≥ 0")
        check(0 <= self.p_gaussian <= 1, "p_gaussian", "must be a probability")
        check(
            0 <= self.p_short <= 1 - self.p_gaussian, "p_short", "p_gaussian + p_short must be ≤ 1"
        )
        check(self.short_sigma_per_m >= 0, "short_sigma_per_m", "must be ≥ 0")

    @property
    def p_outlier(self) -> float:
        """Probability that a return is replaced by a uniform outlier."""
        return 1.0 - self.p_gaussian - self.p_short

    def apply(self, ranges: FloatArray, rng: np.random.Generator) -> FloatArray:
        """(n,) noisy ranges of (n,) true ranges in metres; draws 3n numbers from ``rng``."""
        n = len(ranges)
        choice, gauss, uniform = rng.random(n), rng.standard_normal(n), rng.random(n)
        noisy = ranges + self.sigma_m * gauss
        short = (choice >= self.p_gaussian) & (choice < self.p_gaussian + self.p_short)
        noisy[short] = ranges[short] - np.abs(gauss[short]) * self.short_sigma_per_m * ranges[short]
        outlier = choice >= self.p_gaussian + self.p_short
        low, high = self.outlier_min_m, ranges[outlier] + self.outlier_margin_m
        noisy[outlier] = low + uniform[outlier] * (high - low)
        return noisy


#: The sensor range for mapping and statistics, metres (the NBV paper): returns beyond it carve free
#: space and observe nothing. :class:`~nbv_gym.mapping.state.MappingConfig` holds it; the NBV
#: candidate radius and the navigation cost's range default to it.
SENSOR_RANGE_M: float = 20.0


#: The most rays of one scan (``n_channels`` · ``n_azimuth``): 8 × the densest preset's
#: (os1-128, 131,072). A scan holds ~100 bytes a ray (directions, distances, returns), and the
#: ray casting's time grows with them.
MAX_RAYS = 1 << 20


@dataclass(frozen=True)
class LidarConfig:
    """The Ouster OS1-16 as simulated by the authors (docs/protocol.md#lidar).

    ``n_channels`` elevation channels evenly spaced over [``elevation_min_rad``,
    ``elevation_max_rad``], ``n_azimuth`` samples over 360°, mounted ``mount_height_m`` above the
    robot's ground pose. Returns closer than ``min_range_m`` or nearer than ``min_horizontal_m``
    horizontally are dropped. ``range_noise = None`` turns range noise off.
    """

    n_channels: int = 16
    elevation_min_rad: float = -0.26
    elevation_max_rad: float = 0.26
    n_azimuth: int = 512
    mount_height_m: float = 0.42
    min_range_m: float = 0.3
    min_horizontal_m: float = 0.3
    range_noise: RangeNoise | None = field(default_factory=RangeNoise)

    def __post_init__(self) -> None:
        check(self.n_channels >= 1, "n_channels", "must be ≥ 1")
        check(self.n_azimuth >= 1, "n_azimuth", "must be ≥ 1")
        rays = self.n_channels * self.n_azimuth
        check(
            rays <= MAX_RAYS,
            "n_channels",
            f"n_channels × n_azimuth = {self.n_channels:,} × {self.n_azimuth:,} = {rays:,} rays a "
            f"scan, more than {MAX_RAYS:,} (nbv_gym.sensor.lidar.MAX_RAYS); use fewer channels "
            "or azimuth samples",
        )
        check(
            self.elevation_min_rad <= self.elevation_max_rad,
            "elevation_min_rad",
            "must be ≤ elevation_max_rad",
        )
        check(
            abs(self.elevation_max_rad) < np.pi / 2 and abs(self.elevation_min_rad) < np.pi / 2,
            "elevation_max_rad",
            "elevations must lie strictly within ±π/2",
        )
        check(self.min_range_m >= 0 and self.min_horizontal_m >= 0, "min_range_m", "must be ≥ 0")

    def directions(self) -> FloatArray:
        """(n_channels · n_azimuth, 3) float64 unit ray directions in the sensor frame, ordered
        channel-major (ray ``c * n_azimuth + a``), azimuth 0 along +x, counter-clockwise."""
        elevation = np.linspace(self.elevation_min_rad, self.elevation_max_rad, self.n_channels)
        azimuth = np.arange(self.n_azimuth) * (2 * np.pi / self.n_azimuth)
        el, az = np.meshgrid(elevation, azimuth, indexing="ij")
        return np.stack(
            [libm.cos(el) * libm.cos(az), libm.cos(el) * libm.sin(az), libm.sin(el)], axis=-1
        ).reshape(-1, 3)


class Lidar:
    """A lidar in a scene: casts its beam pattern from a robot pose and returns a :class:`Scan`.

    Args:
        scene: the world's :class:`RayScene`.
        directions: (m, 3) unit ray directions in the sensor frame.
        mount_height_m: sensor height above the robot's ground pose.
        min_range_m, min_horizontal_m: returns closer than these (metres) are dropped.
        range_noise: the range-noise model, or None for exact ranges.
        localisation: noise on the pose used for mapping (the true pose is used for ray casting).
        bounds_xy: ((x_min, y_min), (x_max, y_max)) the region a robot pose must lie in, or None.
    """

    def __init__(
        self,
        scene: RayScene,
        directions: FloatArray,
        mount_height_m: float,
        min_range_m: float,
        min_horizontal_m: float,
        range_noise: RangeNoise | None,
        localisation: LocalisationNoise,
        bounds_xy: tuple[tuple[float, float], tuple[float, float]] | None = None,
    ):
        self.scene = scene
        self.directions = np.asarray(directions, dtype=np.float64)
        self.mount_height_m = mount_height_m
        self.min_range_m = min_range_m
        self.min_horizontal_m = min_horizontal_m
        self.range_noise = range_noise
        self.localisation = localisation
        self.bounds_xy = bounds_xy
        #: (3, m) float64 the directions' x, y and z rows (the returns' coordinates gather them)
        self._rows = np.ascontiguousarray(self.directions.T)
        #: the true sensor pose of the first scan and its hits: an episode's first scan is
        #: taken from the start pose, and every reset casts the same rays again
        self._first_cast: tuple[tuple[float, ...], tuple[IntArray, FloatArray]] | None = None

    @classmethod
    def for_world(
        cls,
        world: World,
        config: LidarConfig | None = None,
        noise: LocalisationNoise | int = 0,
    ) -> Lidar:
        """The lidar of ``config`` in ``world``, with localisation noise (level 0–2 or a model)."""
        config = config or LidarConfig()
        if isinstance(noise, int):
            noise = LocalisationNoise.level(noise)
        return cls(
            world.ray_scene(),
            config.directions(),
            config.mount_height_m,
            config.min_range_m,
            config.min_horizontal_m,
            config.range_noise,
            noise,
            world.ground_bounds_xy,
        )

    def sensor_pose(self, robot: Pose) -> Pose:
        """The sensor pose of a robot standing at ``robot`` (mount height added to z)."""
        return Pose(robot.x, robot.y, robot.z + self.mount_height_m, robot.yaw)

    def scan(self, robot: Pose, rng: np.random.Generator) -> Scan:
        """Scan from the robot's ground pose ``robot``; all randomness is drawn from ``rng``."""
        ray_index, ranges, true_pose, noisy_pose = self._measure(robot, rng)
        return self._returns(ray_index, ranges, true_pose, noisy_pose)

    def map_points(self, robot: Pose, rng: np.random.Generator) -> tuple[FloatArray, FloatArray]:
        """The (3,) float64 ``origin`` and (n, 3) float64 ``points_map`` of the :meth:`scan`
        from ``robot`` with ``rng`` — the same bits and draws — without its sensor-frame arrays
        (a look-ahead's trial scans need only these)."""
        ray_index, ranges, _, noisy_pose = self._measure(robot, rng)
        keep, x, y = self._kept(ray_index, ranges)
        c, s = math.cos(noisy_pose.yaw), math.sin(noisy_pose.yaw)  # as Pose.to_map turns them
        x, y, origin = x[keep], y[keep], noisy_pose.position
        points = np.empty((len(keep), 3))
        points[:, 0], points[:, 1] = c * x - s * y, s * x + c * y
        points[:, 2] = ranges[keep] * self._rows[2][ray_index[keep]]
        points += origin
        return origin, points

    def _measure(
        self, robot: Pose, rng: np.random.Generator
    ) -> tuple[IntArray, FloatArray, Pose, Pose]:
        """The scan's hits before the sensor drops any: (k,) int64 ray indices, (k,) float64
        noisy ranges, the true and the noisy sensor pose (draws the scan's numbers from
        ``rng``)."""
        self._check_pose(robot)
        true_pose = self.sensor_pose(robot)
        ray_index, ranges = self._cast(true_pose)
        if self.range_noise is not None:
            ranges = self.range_noise.apply(ranges, rng)
        return ray_index, ranges, true_pose, self.localisation.perturb(true_pose, rng)

    def _cast(self, true_pose: Pose) -> tuple[IntArray, FloatArray]:
        """The rays from the sensor at ``true_pose`` that hit: (k,) int64 their indices and (k,)
        float64 the distances to the first hit; the first pose's are kept and given again for
        that pose."""
        key = (true_pose.x, true_pose.y, true_pose.z, true_pose.yaw)
        if self._first_cast is not None and self._first_cast[0] == key:
            return self._first_cast[1][0].copy(), self._first_cast[1][1].copy()
        origins, directions = np.empty((2, *self.directions.shape), np.float32)  # per call:
        origins[:] = true_pose.position  # look-aheads scan on several threads
        true_pose.rotate(self.directions, out=directions)  # no BLAS: same bits on every CPU
        ray_index, distance = self.scene.hits(origins, directions)
        if self._first_cast is None:
            self._first_cast = (key, (ray_index.copy(), distance.copy()))
        return ray_index, distance

    def _returns(
        self, ray_index: IntArray, ranges: FloatArray, true_pose: Pose, noisy_pose: Pose
    ) -> Scan:
        """The scan of the hits ``ray_index`` at ``ranges``, less those the sensor drops."""
        keep, x, y = self._kept(ray_index, ranges)
        ray_index, ranges = ray_index[keep], ranges[keep]
        points = np.empty((len(keep), 3))
        points[:, 0], points[:, 1], points[:, 2] = (
            x[keep],
            y[keep],
            ranges * self._rows[2][ray_index],
        )
        return Scan(points, ranges, ray_index, true_pose, noisy_pose, noisy_pose.to_map(points))

    def _kept(
        self, ray_index: IntArray, ranges: FloatArray
    ) -> tuple[IntArray, FloatArray, FloatArray]:
        """(j,) int64 the hits the sensor keeps (positions in ``ray_index``), and (k,) float64
        every hit's sensor-frame x and y, metres."""
        x, y = ranges * self._rows[0][ray_index], ranges * self._rows[1][ray_index]
        keep = (ranges > self.min_range_m) & (np.hypot(x, y) >= self.min_horizontal_m)
        return np.flatnonzero(keep), x, y

    def _check_pose(self, robot: Pose) -> None:
        values = (robot.x, robot.y, robot.z, robot.yaw)
        if not all(np.isfinite(values)):
            raise PoseError(f"Robot pose must be finite, got {robot}.")
        if self.bounds_xy is None:
            return
        (x0, y0), (x1, y1) = self.bounds_xy
        if not (x0 <= robot.x <= x1 and y0 <= robot.y <= y1):
            raise PoseError(
                f"Robot pose ({robot.x:.3f}, {robot.y:.3f}) lies outside the world's ground "
                f"x ∈ [{x0}, {x1}], y ∈ [{y0}, {y1}] m."
            )
