"""Recipes of generated worlds: the ranges a world's numbers are drawn from, as plain data.

A :class:`Recipe` holds a range per number of a world spec — asset count, cluster count, cluster
radius, window side, the scale ranges' ends — and the asset mixes it uses. :meth:`Recipe.draw`
fixes the numbers of one world from a text key with SHA-256 (:func:`unit`), so a generated world
is the same on every machine and with every numpy. The test split, the shift split
(:mod:`nbv_gym.benchmark`) and the ``random:wide`` training distribution
(:mod:`nbv_gym.worlds.pools`) are recipes; a test compares their ranges, so "outside the
training distribution" is a statement about these numbers.

This module is data only (no world spec class): the spec module builds specs from what
:meth:`Recipe.draw` returns.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from itertools import combinations
from typing import Any

from nbv_gym.core.config import check

ASSET_TYPES = ("cuboids", "crosses", "helicoids", "trees")
#: The asset types one at a time, then every mix of two, three and all four (equal weights).
EVERY_MIX = tuple(c for n in range(1, len(ASSET_TYPES) + 1) for c in combinations(ASSET_TYPES, n))
#: The numeric ranges a recipe holds (:data:`Recipe.ranges`), in the order tables show them.
AXES = ("n_assets", "n_parents", "cluster_radius_m", "window_side_m", "scale_low", "scale_high")


@dataclass(frozen=True)
class Recipe:
    """Ranges (low, high), both ends included, of the numbers of a generated world.

    ``n_assets`` and ``n_parents`` (clusters) are whole numbers; ``cluster_radius_m`` is drawn
    to 0.1 m; ``window_side_m``: the side of the square placement window centred on the start,
    drawn to whole metres (the benchmark's 60 m keeps the default 60 × 60 goals); ``scale_low``
    / ``scale_high``: the ends of each asset's horizontal and vertical scale-factor range,
    drawn to 0.05 for each axis. ``mixes``: the asset mixes (equal weights) a world draws from,
    unless the caller fixes its mix.
    """

    n_assets: tuple[int, int]
    n_parents: tuple[int, int]
    cluster_radius_m: tuple[float, float]
    window_side_m: tuple[float, float] = (60.0, 60.0)
    scale_low: tuple[float, float] = (0.7, 0.7)
    scale_high: tuple[float, float] = (1.3, 1.3)
    mixes: tuple[tuple[str, ...], ...] = (ASSET_TYPES,)

    def __post_init__(self) -> None:
        for axis in AXES:
            low, high = getattr(self, axis)
            check(0 < low <= high < math.inf, axis, f"expected 0 < low ≤ high, got {(low, high)}")
        check(self.n_parents[0] >= 2, "n_parents", "must be ≥ 2 (two clusters at least)")
        check(self.n_parents[1] <= self.n_assets[0], "n_parents", "must not exceed n_assets")
        check(self.scale_low[1] <= self.scale_high[0], "scale_low", "must not exceed scale_high")
        check(bool(self.mixes), "mixes", "name at least one asset mix")
        for mix in self.mixes:
            check(
                bool(mix) and set(mix) <= set(ASSET_TYPES),
                "mixes",
                f"each mix names asset types from {list(ASSET_TYPES)}, got {mix}",
            )

    @property
    def ranges(self) -> dict[str, tuple[float, float]]:
        """The numeric ranges by axis (:data:`AXES`)."""
        return {axis: getattr(self, axis) for axis in AXES}

    def draw(self, key: str, seed: int, mix: tuple[str, ...] | None = None) -> dict[str, Any]:
        """The ``placement`` and ``assets`` tables of the world keyed ``key`` (numbers from
        :func:`unit` of ``"{key}/{field}"``) with placement and tree-library seed ``seed``; its
        mix is ``mix`` if given, else one of :attr:`mixes` drawn by the key."""
        if mix is None:
            mix = self.mixes[min(int(len(self.mixes) * unit(f"{key}/mix")), len(self.mixes) - 1)]
        half = _whole(self.window_side_m, unit(f"{key}/window_side_m")) / 2
        placement = {
            "seed": seed,
            "n_assets": _whole(self.n_assets, unit(f"{key}/n_assets")),
            "n_parents": _whole(self.n_parents, unit(f"{key}/n_parents")),
            "cluster_radius_m": round(
                _between(self.cluster_radius_m, f"{key}/cluster_radius_m"), 1
            ),
            "window_m": (-half, -half, half, half),
        }
        assets = {
            "mix": {kind: 1.0 for kind in mix},
            "scale_horizontal": self._scale_range(key, "horizontal"),
            "scale_vertical": self._scale_range(key, "vertical"),
            "tree_library_seed": seed,
        }
        return {"placement": placement, "assets": assets}

    def _scale_range(self, key: str, axis: str) -> tuple[float, float]:
        """A scale-factor range: its ends in :attr:`scale_low` and :attr:`scale_high`, to 0.05."""
        low = _between(self.scale_low, f"{key}/scale_{axis}_low")
        high = _between(self.scale_high, f"{key}/scale_{axis}_high")
        return round(low * 20) / 20, round(high * 20) / 20


def describe(numbers: dict[str, Any]) -> str:
    """``"56 cuboids + trees in 8 clusters of radius 10.1 m (placement seed 7)"``: a world's
    :meth:`Recipe.draw` tables in words."""
    placement = numbers["placement"]
    return (
        f"{placement['n_assets']} {' + '.join(numbers['assets']['mix'])} in "
        f"{placement['n_parents']} clusters of radius {placement['cluster_radius_m']:g} m "
        f"(placement seed {placement['seed']})"
    )


def unit(text: str) -> float:
    """A number in [0, 1) fixed by ``text`` (the first 53 bits of its SHA-256)."""
    digest = hashlib.sha256(text.encode()).digest()
    return (int.from_bytes(digest[:8], "big") >> 11) / 2**53


def outside(inner: tuple[float, float], outer: tuple[float, float]) -> bool:
    """Whether the range ``inner`` shares no value with ``outer`` (both ends included)."""
    return inner[1] < outer[0] or inner[0] > outer[1]


def _between(bounds: tuple[float, float], text: str) -> float:
    return bounds[0] + (bounds[1] - bounds[0]) * unit(text)


def _whole(bounds: tuple[float, float], u: float) -> int:
    """A whole number from ``bounds`` (both ends included) for ``u`` in [0, 1)."""
    low, high = int(bounds[0]), int(bounds[1])
    return low + int((high - low + 1) * u)
