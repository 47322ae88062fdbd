"""The simulated lidar against analytic geometry and the protocol's noise model (docs/protocol.md#lidar)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from nbv_gym.core.errors import PoseError
from nbv_gym.core.pose import LocalisationNoise, Pose
from nbv_gym.sensor.lidar import Lidar, LidarConfig, RangeNoise, RayScene
from nbv_gym.worlds import shapes


def make_lidar(mesh, noise=None, localisation=None, bounds=None) -> Lidar:
    config = LidarConfig()
    return Lidar(
        RayScene(*mesh),
        config.directions(),
        config.mount_height_m,
        config.min_range_m,
        config.min_horizontal_m,
        noise,
        localisation or LocalisationNoise(),
        bounds,
    )


def wall_mesh(x_m: float):
    """A 40 m × 40 m vertical wall facing −x at ``x = x_m``."""
    vertices = np.array([[x_m, -20, -20], [x_m, 20, -20], [x_m, 20, 20], [x_m, -20, 20.0]])
    return vertices, np.array([[0, 1, 2], [0, 2, 3]])


def test_beam_pattern_is_the_os1_16():
    directions = LidarConfig().directions()
    assert directions.shape == (16 * 512, 3)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
    elevation = np.arcsin(directions[::512, 2])
    np.testing.assert_allclose(elevation, np.linspace(-0.26, 0.26, 16), atol=1e-12)
    azimuth = np.arctan2(directions[:512, 1], directions[:512, 0]) % (2 * np.pi)
    np.testing.assert_allclose(np.diff(azimuth), 2 * np.pi / 512, atol=1e-9)


def test_rays_against_a_box_return_the_analytic_distance_without_noise():
    box = shapes.place(shapes.cuboid(), np.array([6.0, 0.0]), 0.0, 1.0, 1.0)  # faces x = 5, 7
    scan = make_lidar(box).scan(Pose(0, 0, 0, 0), np.random.default_rng(0))
    directions = LidarConfig().directions()[scan.ray_index]
    expected = 5.0 / directions[:, 0]  # every return hits the face x = 5
    assert len(scan) > 100
    np.testing.assert_allclose(scan.ranges, expected, rtol=1e-6)
    np.testing.assert_allclose(scan.points_map[:, 0], 5.0, atol=1e-5)


def test_yaw_turns_the_beam_pattern():
    wall = wall_mesh(5.0)
    ahead = make_lidar(wall).scan(Pose(0, 0, 0, 0.0), np.random.default_rng(0))
    turned = make_lidar(wall).scan(Pose(0, 0, 0, np.pi), np.random.default_rng(0))
    # facing away, the wall is seen by the rays of azimuth π instead of 0: same hits, shifted index
    assert sorted((ahead.ray_index + 256) % 512 + 512 * (ahead.ray_index // 512)) == sorted(
        turned.ray_index
    )
    np.testing.assert_allclose(np.sort(ahead.ranges), np.sort(turned.ranges), rtol=1e-6)


def test_returns_closer_than_the_minimum_range_are_dropped():
    near = make_lidar(wall_mesh(0.25)).scan(Pose(0, 0, 0, 0), np.random.default_rng(0))
    assert len(near) > 0  # the oblique rays hit farther than 0.3 m and stay
    assert near.ranges.min() > 0.3
    horizontal = np.hypot(near.points_sensor[:, 0], near.points_sensor[:, 1])
    assert horizontal.min() >= 0.3


def test_no_hit_means_no_return():
    scan = make_lidar(wall_mesh(5.0)).scan(Pose(0, 0, 0, 0), np.random.default_rng(0))
    d = LidarConfig().directions()
    with np.errstate(divide="ignore"):
        t = np.where(d[:, 0] > 0, 5.0 / d[:, 0], np.inf)  # where each ray meets the plane x = 5
        on_wall = (np.abs(t * d[:, 1]) < 20) & (np.abs(0.42 + t * d[:, 2]) < 20)
    assert set(scan.ray_index) == set(np.flatnonzero(on_wall))


def mixture_cdf(error: np.ndarray, true_range: np.ndarray, noise: RangeNoise) -> np.ndarray:
    """The protocol's mixture CDF of (noisy − true) range, evaluated per ray."""
    gaussian = stats.norm.cdf(error, scale=noise.sigma_m)
    half_normal = 2 * stats.norm.cdf(
        np.minimum(error, 0), scale=noise.short_sigma_per_m * true_range
    )
    low, high = noise.outlier_min_m - true_range, noise.outlier_margin_m
    uniform = np.clip((error - low) / (high - low), 0, 1)
    return noise.p_gaussian * gaussian + noise.p_short * half_normal + noise.p_outlier * uniform


def test_range_noise_on_a_plane_follows_the_mixture():
    noise = RangeNoise()
    wall = wall_mesh(4.0)
    exact, noisy = make_lidar(wall), make_lidar(wall, noise)
    rng = np.random.default_rng(1)
    errors, truths = [], []
    for yaw in np.linspace(-0.5, 0.5, 32):
        truth = exact.scan(Pose(0, 0, 0, yaw), rng)
        scan = noisy.scan(Pose(0, 0, 0, yaw), rng)
        assert np.array_equal(truth.ray_index, scan.ray_index)
        errors.append(scan.ranges - truth.ranges)
        truths.append(truth.ranges)
    error, true_range = np.concatenate(errors), np.concatenate(truths)
    assert len(error) > 90_000
    # probability integral transform: uniform iff the errors follow the mixture
    assert stats.kstest(mixture_cdf(error, true_range, noise), "uniform").pvalue > 1e-3
    # the share of large negative errors (short returns and outliers) is the mixture's
    far_short = np.mean(error < -0.25)
    expected = np.mean(mixture_cdf(np.full_like(error, -0.25), true_range, noise))
    assert abs(far_short - expected) < 4 * np.sqrt(expected / len(error))
    central = error[np.abs(error) < 5 * noise.sigma_m]
    assert np.std(central[central > 0]) == pytest.approx(
        noise.sigma_m * np.sqrt(1 - 2 / np.pi), rel=0.03
    )


def test_localisation_noise_moves_the_map_points_not_the_rays():
    box = shapes.place(shapes.cuboid(), np.array([6.0, 0.0]), 0.3, 1.0, 1.0)
    perfect = make_lidar(box, RangeNoise())
    noisy = make_lidar(box, RangeNoise(), LocalisationNoise.level(2))
    a = perfect.scan(Pose(1, 2, 0, 0.1), np.random.default_rng(5))
    b = noisy.scan(Pose(1, 2, 0, 0.1), np.random.default_rng(5))
    np.testing.assert_array_equal(a.points_sensor, b.points_sensor)  # true pose casts the rays
    assert a.pose == a.true_pose == Pose(1, 2, 0.42, 0.1)
    assert b.true_pose == a.true_pose and b.pose != b.true_pose
    np.testing.assert_allclose(b.points_map, b.pose.to_map(b.points_sensor))


def test_localisation_noise_has_the_papers_spread():
    noise, rng = LocalisationNoise.level(2), np.random.default_rng(3)
    poses = [noise.perturb(Pose(0, 0, 0, 0), rng) for _ in range(4000)]
    xyz_yaw = np.array([[p.x, p.y, p.z, p.yaw] for p in poses])
    np.testing.assert_allclose(xyz_yaw.std(axis=0), [0.05, 0.05, 0.05, 0.01], rtol=0.06)


def test_same_seed_same_scan():
    box = shapes.place(shapes.cross(), np.array([4.0, 1.0]), 0.7, 1.1, 0.9)
    lidar = make_lidar(box, RangeNoise(), LocalisationNoise.level(1))
    a = lidar.scan(Pose(0, 0, 0, 0), np.random.default_rng(9))
    b = lidar.scan(Pose(0, 0, 0, 0), np.random.default_rng(9))
    c = lidar.scan(Pose(0, 0, 0, 0), np.random.default_rng(10))
    np.testing.assert_array_equal(a.points_map, b.points_map)
    assert not np.array_equal(a.ranges, c.ranges)


def test_map_points_are_the_scans_origin_and_map_points_bit_for_bit_with_the_same_draws():
    box = shapes.place(shapes.cross(), np.array([4.0, 1.0]), 0.7, 1.1, 0.9)
    lidar = make_lidar(box, RangeNoise(), LocalisationNoise.level(2))
    for pose in (Pose(0, 0, 0, 0), Pose(0.5, -1.0, 0.1, 2.3)):
        a_rng, b_rng = np.random.default_rng(9), np.random.default_rng(9)
        scan = lidar.scan(pose, a_rng)
        origin, points = lidar.map_points(pose, b_rng)
        assert len(scan) > 100 and points.dtype == scan.points_map.dtype
        assert origin.tobytes() == scan.origin.tobytes()
        assert points.tobytes() == scan.points_map.tobytes()
        assert a_rng.random() == b_rng.random()  # the same numbers drawn


@pytest.mark.parametrize("pose", [Pose(40, 0, 0, 0), Pose(0, -33, 0, 0), Pose(np.nan, 0, 0, 0)])
def test_a_pose_outside_the_world_is_refused(pose):
    lidar = make_lidar(wall_mesh(5.0), bounds=((-32.0, -32.0), (32.0, 32.0)))
    with pytest.raises(PoseError, match=r"outside the world|finite"):
        lidar.scan(pose, np.random.default_rng(0))


def test_the_first_poses_cast_is_reused_bit_for_bit():
    mesh = shapes.concatenate([shapes.place(shapes.helicoid(), (4.0, 1.0), 0.3, 1.0, 1.0)])
    start, other = Pose(0.0, 0.0, 0.0, 0.2), Pose(1.0, -0.5, 0.0, 1.1)
    lidar, fresh = make_lidar(mesh, RangeNoise()), make_lidar(mesh, RangeNoise())
    first = lidar.scan(start, np.random.default_rng(5))
    first.points_sensor[:] = 0.0  # a caller's edits do not reach what is kept
    lidar.scan(other, np.random.default_rng(6))
    again = lidar.scan(start, np.random.default_rng(7))
    expected = fresh.scan(start, np.random.default_rng(7))
    assert len(again) > 100
    for name in ("points_sensor", "ranges", "ray_index", "points_map"):
        np.testing.assert_array_equal(getattr(again, name), getattr(expected, name))


@pytest.mark.parametrize("beams", [{"n_channels": 200_000, "n_azimuth": 200_000},
                                   {"n_channels": 2048, "n_azimuth": 513}])  # fmt: skip
def test_a_beam_pattern_beyond_the_ray_bound_is_refused_naming_its_keys(beams):
    """L07/L10 of the fourth round: 200,000 × 200,000 beams asked 298 GiB of a scan."""
    from nbv_gym.core.errors import ConfigError
    from nbv_gym.sensor.lidar import MAX_RAYS

    with pytest.raises(
        ConfigError, match=rf"n_channels: n_channels × n_azimuth = .* more than {MAX_RAYS:,}"
    ):
        LidarConfig(**beams)
    assert len(LidarConfig(n_channels=2048, n_azimuth=512).directions()) == MAX_RAYS
