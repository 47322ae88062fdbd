"""Strict configs: unknown keys and bad values are refused with their dotted path."""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest

from nbv_gym.core.config import check, from_dict, to_dict
from nbv_gym.core.errors import ConfigError
from nbv_gym.sensor.lidar import LidarConfig, RangeNoise


@dataclass(frozen=True)
class Inner:
    rate_hz: float = 10.0
    mode: str = "fast"

    def __post_init__(self) -> None:
        check(self.rate_hz > 0, "rate_hz", "must be > 0")


@dataclass(frozen=True)
class Outer:
    inner: Inner = field(default_factory=Inner)
    window: tuple[float, float] = (0.0, 1.0)
    weights: dict[str, float] = field(default_factory=dict)
    maybe: Inner | None = None


def test_nested_values_are_converted():
    config = from_dict(Outer, {"inner": {"rate_hz": 5}, "window": [1, 2], "weights": {"a": 1}})
    assert config == Outer(Inner(5.0), (1.0, 2.0), {"a": 1.0})
    assert isinstance(config.inner.rate_hz, float)
    assert from_dict(Outer, to_dict(config)) == config


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"inner": {"rate": 5}}, r"Unknown key inner\.rate\. Valid keys here: mode, rate_hz"),
        ({"inner": {"rate_hz": "fast"}}, r"inner\.rate_hz: expected float, got str"),
        ({"inner": {"rate_hz": -1}}, r"inner: rate_hz: must be > 0"),
        ({"window": [1, 2, 3]}, r"window: expected 2 values, got 3"),
        ({"weights": {"a": "x"}}, r"weights\.a: expected float"),
        ({"maybe": {"bogus": 1}}, r"Unknown key maybe\.bogus"),
        ({"inner": 3}, r"inner: expected a table"),
    ],
)
def test_bad_values_name_their_key(data, message):
    with pytest.raises(ConfigError, match=message):
        from_dict(Outer, data)


def test_lidar_config_defaults_are_the_specs():
    config = LidarConfig()
    assert (config.n_channels, config.n_azimuth, config.mount_height_m) == (16, 512, 0.42)
    assert config.range_noise == RangeNoise(0.008, 0.96, 0.039, 0.01, 0.3, 0.03)
    assert config.range_noise.p_outlier == pytest.approx(0.001)
    no_noise = from_dict(LidarConfig, {"range_noise": None})
    assert no_noise.range_noise is None
    with pytest.raises(ConfigError, match="p_short"):
        from_dict(LidarConfig, {"range_noise": {"p_short": 0.5}})
