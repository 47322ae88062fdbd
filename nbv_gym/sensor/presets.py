"""Named lidar presets: published beam patterns as :class:`~nbv_gym.sensor.lidar.LidarConfig` s.

A preset changes the beam pattern only — channels, vertical field of view (channels evenly
spaced over it) and azimuth samples per revolution — from its datasheet. The rest is the
benchmark robot's and stays as in the default: the mount height (0.42 m), the near-return filter
(0.3 m) and the range-noise model. Every preset's datasheet range (``range_m``, ≥ 100 m) exceeds
the mapping range (20 m) and the farthest hit in a benchmark world, so the simulated lidar keeps
every hit; a scene larger than the preset's range would see hits a real sensor misses.

``os1-16`` is the default and the benchmark's sensor: the Ouster OS1-16 as the authors of the
benchmark's paper simulated it (±0.26 rad, 512 azimuth samples). Look a preset up with
:func:`lidar_config`; ``nbv-gym configs lidars`` lists them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from nbv_gym.core.errors import UnknownNameError
from nbv_gym.sensor.lidar import LidarConfig

#: The preset of the benchmark (``LidarConfig()``).
DEFAULT_LIDAR = "os1-16"


@dataclass(frozen=True)
class LidarPreset:
    """A named beam pattern: ``config`` (channels, elevations, azimuth samples), its datasheet
    range ``range_m`` (metres, documented, not simulated) and ``source`` (the datasheet)."""

    name: str
    description: str
    config: LidarConfig
    range_m: float
    source: str

    @property
    def vertical_fov_deg(self) -> tuple[float, float]:
        """(lowest, highest) beam elevation, degrees."""
        low, high = self.config.elevation_min_rad, self.config.elevation_max_rad
        return math.degrees(low), math.degrees(high)

    @property
    def rays(self) -> int:
        """Rays per scan (channels × azimuth samples)."""
        return self.config.n_channels * self.config.n_azimuth


def _pattern(channels: int, low_deg: float, high_deg: float, azimuth: int) -> LidarConfig:
    return replace(
        LidarConfig(),
        n_channels=channels,
        elevation_min_rad=math.radians(low_deg),
        elevation_max_rad=math.radians(high_deg),
        n_azimuth=azimuth,
    )


_OS1 = "Ouster OS1 datasheet (Gen 1): 16 or 64 beams over +16.6° to -16.6°, 128 over ±22.5°; "
_OS1 += "512, 1024 or 2048 azimuth samples; range 0.8-120 m at 80 % reflectivity"
_VLP = "Velodyne VLP-16 user manual (63-9243): 16 lasers from -15° to +15° in 2° steps; 0.2° "
_VLP += "azimuth resolution at 10 Hz (1800 samples); range 100 m"
_HDL = "Velodyne HDL-32E user manual: 32 lasers over +10.67° to -30.67° (41.3°); a firing every "
_HDL += "46.08 µs, 2170 per revolution at 10 Hz (0.166°); range 100 m"

LIDAR_PRESETS: dict[str, LidarPreset] = {
    preset.name: preset
    for preset in (
        LidarPreset(
            "os1-16",
            "Ouster OS1-16 as the benchmark's authors simulated it (the default)",
            LidarConfig(),
            120.0,
            "Aravecchia et al., IROS 2023 (the authors' simulated sensor); " + _OS1,
        ),
        LidarPreset(
            "os1-64",
            "Ouster OS1-64, 1024 × 10 Hz mode",
            _pattern(64, -16.6, 16.6, 1024),
            120.0,
            _OS1,
        ),
        LidarPreset(
            "os1-128",
            "Ouster OS1-128, 1024 × 10 Hz mode",
            _pattern(128, -22.5, 22.5, 1024),
            120.0,
            _OS1,
        ),
        LidarPreset(
            "vlp-16",
            "Velodyne VLP-16 (Puck) at 10 Hz",
            _pattern(16, -15.0, 15.0, 1800),
            100.0,
            _VLP,
        ),
        LidarPreset(
            "hdl-32e", "Velodyne HDL-32E at 10 Hz", _pattern(32, -30.67, 10.67, 2170), 100.0, _HDL
        ),
    )
}


def lidar_preset(name: str) -> LidarPreset:
    """The preset ``name``; :class:`UnknownNameError` (with the near miss) otherwise."""
    if name not in LIDAR_PRESETS:
        raise UnknownNameError("lidar", str(name), LIDAR_PRESETS)
    return LIDAR_PRESETS[name]


def lidar_config(name: str) -> LidarConfig:
    """The :class:`LidarConfig` of the preset ``name`` (see :func:`lidar_preset`)."""
    return lidar_preset(name).config


#: The keys of :class:`LidarConfig` a preset sets (its beam pattern).
PATTERN_KEYS = ("n_channels", "elevation_min_rad", "elevation_max_rad", "n_azimuth")


def beam_pattern(name: str) -> dict[str, float]:
    """The beam-pattern keys (:data:`PATTERN_KEYS`) of preset ``name`` with their values: plain
    data for a config table such as a sweep's ``[env.simulator.lidar]``."""
    config = lidar_config(name)
    return {key: getattr(config, key) for key in PATTERN_KEYS}
