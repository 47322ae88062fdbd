"""Where the assets stand: a seeded Poisson cluster process and per-asset poses (docs/protocol.md#worlds)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from nbv_gym.core.arrays import FloatArray, IntArray
from nbv_gym.worlds.spec import ASSET_TYPES, AssetConfig, PlacementConfig


@dataclass(frozen=True)
class Layout:
    """The placed assets: ``xy`` (n, 2) float metres, ``yaw`` (n,) radians, ``scale_xy`` and
    ``scale_z`` (n,) factors, ``kind`` (n,) int index into ``ASSET_TYPES``, ``variant`` (n,) int
    (which tree of the library)."""

    xy: FloatArray
    yaw: FloatArray
    scale_xy: FloatArray
    scale_z: FloatArray
    kind: IntArray
    variant: IntArray


def empty_layout() -> Layout:
    """The layout of a world without procedural assets."""
    none = np.empty(0)
    return Layout(np.empty((0, 2)), none, none, none, none.astype(np.int64), none.astype(np.int64))


def cluster_points(placement: PlacementConfig, rng: np.random.Generator) -> FloatArray:
    """(n_assets, 2) points of pointpats' Poisson cluster process in the window."""
    from pointpats.random import cluster_poisson

    with warnings.catch_warnings():  # pointpats calls the deprecated numpy.row_stack
        warnings.simplefilter("ignore", DeprecationWarning)
        points = cluster_poisson(
            np.asarray(placement.window_m, dtype=float),
            size=placement.n_assets,
            n_seeds=placement.parents,
            cluster_radius=placement.cluster_radius_m,
            rng=rng,
        )
    return np.asarray(points, dtype=float).reshape(placement.n_assets, 2)


def layout(placement: PlacementConfig, assets: AssetConfig) -> Layout:
    """The seeded layout. Positions and poses come from independent streams of
    ``placement.seed``, and every asset draws the same numbers whatever its type, so worlds that
    differ only in their asset mix share positions, yaws and scales."""
    points_rng, pose_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(placement.seed).spawn(2)
    )
    xy = cluster_points(placement, points_rng)
    n = placement.n_assets
    draws = pose_rng.random((n, 5))
    yaw = 2 * np.pi * draws[:, 0]
    scale_xy = _in_range(draws[:, 1], assets.scale_horizontal)
    scale_z = _in_range(draws[:, 2], assets.scale_vertical)
    weights = np.array([assets.mix.get(t, 0.0) for t in ASSET_TYPES])
    cumulative = np.cumsum(weights / weights.sum())
    kind = np.minimum(np.searchsorted(cumulative, draws[:, 3], side="right"), len(ASSET_TYPES) - 1)
    variant = (draws[:, 4] * assets.tree_library_size).astype(np.int64)
    return Layout(xy, yaw, scale_xy, scale_z, kind.astype(np.int64), variant)


def clear_start(xy: FloatArray, footprint_m: FloatArray, clear_radius_m: float) -> FloatArray:
    """(n, 2) positions with every asset whose footprint disc (radius ``footprint_m`` (n,))
    enters the start disc pushed radially outward until it just clears it."""
    distance = np.hypot(xy[:, 0], xy[:, 1])
    needed = clear_radius_m + footprint_m
    direction = np.where(distance[:, None] > 0, xy / np.maximum(distance, 1e-12)[:, None], [1, 0])
    return np.where((distance < needed)[:, None], direction * needed[:, None], xy)


def _in_range(unit: FloatArray, bounds: tuple[float, float]) -> FloatArray:
    return bounds[0] + unit * (bounds[1] - bounds[0])
