"""The exploration state: the occupancy map, the statistics grid G and the navigation layer, updated
together by one call per scan (work proportional to what the scan changed)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from nbv_gym.arrays import FloatArray
from nbv_gym.config import check
from nbv_gym.errors import NbvGymError
from nbv_gym.grid import GridSpec
from nbv_gym.lidar import Scan
from nbv_gym.mapping.navigation import NavigationConfig, NavigationLayer
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap, ScanUpdate
from nbv_gym.mapping.statistics import StatisticsConfig, ViewpointStatistics
from nbv_gym.mapping.tally import CellTally


@dataclass(frozen=True)
class MappingConfig:
    """Map, statistics and navigation configs, and the sensor range they share (metres)."""

    sensor_range_m: float = 20.0
    map: MapConfig = field(default_factory=MapConfig)
    statistics: StatisticsConfig = field(default_factory=StatisticsConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)

    def __post_init__(self) -> None:
        check(self.sensor_range_m > 0, "sensor_range_m", f"must be > 0, got {self.sensor_range_m}")
        inside = np.all(np.asarray(self.statistics.low_m) >= np.asarray(self.map.low_m)) and np.all(
            np.asarray(self.statistics.high_m) <= np.asarray(self.map.high_m)
        )
        check(
            bool(inside),
            "statistics",
            f"the box {self.statistics.low_m}–{self.statistics.high_m} must lie inside the map box "
            f"{self.map.low_m}–{self.map.high_m}",
        )
        voxels = np.asarray(self.statistics.low_m) - np.asarray(self.map.low_m)
        voxels = np.append(voxels, self.statistics.cell_m) / self.map.resolution_m
        check(
            bool(np.all(np.abs(voxels - np.rint(voxels)) < 1e-6)),
            "statistics",
            f"G (low_m {self.statistics.low_m}, cell_m {self.statistics.cell_m}) must be aligned "
            f"to the map's {self.map.resolution_m} m voxels from {self.map.low_m}: its corner "
            "and cell size whole numbers of voxels",
        )


class ExplorationState:
    """The state every policy reads: ``occupancy``, ``statistics`` and ``navigation``.

    Insertion flags the cells of G, extended downwards to cover the navigation bands, that hold
    a changed voxel: G's part says which cuboids to re-evaluate, the band's part which navigation
    columns to re-project. Given an ``unobserved_band`` (low, high) of probabilities, the state
    also keeps per-cell totals of the map over G (:meth:`cell_totals`) for the quality metrics.
    """

    def __init__(
        self,
        occupancy: OccupancyMap,
        statistics: ViewpointStatistics,
        navigation: NavigationLayer,
        unobserved_band: tuple[float, float] | None = None,
    ):
        self.occupancy = occupancy
        self.statistics = statistics
        self.navigation = navigation
        self._region, self._below, self._band = _insertion_region(
            statistics.grid, navigation, occupancy.grid.res
        )
        self._nav_factor = round(statistics.grid.res / navigation.grid.res)
        self._tally = None
        if unobserved_band is not None:
            voxels = round(statistics.grid.res / occupancy.grid.res)
            p_min = occupancy.params["p_clamp_min"]
            self._tally = CellTally(self._region.shape, voxels, unobserved_band, p_min)

    @classmethod
    def from_config(
        cls, config: MappingConfig, unobserved_band: tuple[float, float] | None = None
    ) -> ExplorationState:
        """An empty state as ``config`` describes (with cell totals for ``unobserved_band``)."""
        occupancy = OccupancyMap.from_config(config.map, config.sensor_range_m)
        statistics = ViewpointStatistics.from_config(config.statistics, config.sensor_range_m)
        navigation = NavigationLayer.from_config(config.navigation, statistics.grid)
        state = cls(occupancy, statistics, navigation, unobserved_band)
        state.update_navigation(np.zeros(2))  # also checks that the grids fit together
        return state

    def apply(self, scan: Scan, robot_xy: FloatArray | None = None) -> ScanUpdate:
        """Insert ``scan`` (its map-frame points, seen from ``scan.origin``) into the map and the
        statistics, then update the navigation layer — re-projecting only the columns the scan
        changed — and plan once for the robot at ``robot_xy`` (2,) metres (default: the scan's
        sensor position).

        Raises:
            PoseError: the sensor lies outside the map box.
        """
        inserted = self.occupancy.insert(scan.origin, scan.points_map, self._region, self._tally)
        self.statistics.update(scan.origin, scan.points_map)
        columns = self._nav_columns(inserted.touched[:, :, self._band].any(axis=2))
        self._project(np.argwhere(columns))
        self.navigation.plan(scan.origin[:2] if robot_xy is None else robot_xy)
        touched = np.ascontiguousarray(inserted.touched[:, :, self._below :])
        return replace(inserted, touched=touched, columns=columns)

    def update_navigation(self, robot_xy: FloatArray) -> None:
        """Re-project the whole map onto the navigation grid and re-plan from ``robot_xy`` (2,)
        metres."""
        self._project(None)
        self.navigation.plan(robot_xy)

    def cell_totals(self) -> tuple[np.ndarray, np.ndarray]:
        """Views of G's shape (gx, gy, gz): float64 Σ p of each cell's map voxels (unknown = 0.5)
        and int32 the number of them outside the unobserved band; NbvGymError without a band."""
        if self._tally is None:
            raise NbvGymError("this state keeps no cell totals: build it with unobserved_band")
        below = self._below
        return self._tally.sums[:, :, below:], self._tally.outside[:, :, below:]

    def clear(self) -> None:
        """Forget everything (an empty state, as :meth:`from_config` builds), reusing the
        arrays."""
        if self._tally is not None:
            self._tally.clear()
        self.occupancy.clear()
        self.statistics.clear()
        self.navigation.clear()

    def _nav_columns(self, columns: np.ndarray) -> np.ndarray:
        """(nx, ny) bool nav cells of the (gx, gy) bool columns of G."""
        f = self._nav_factor
        return np.repeat(np.repeat(columns, f, axis=0), f, axis=1)

    def _project(self, cells: np.ndarray | None) -> None:
        """Re-project the (m, 2) nav ``cells`` (all when None) and recompute the layers derived
        from the projection."""
        nav = self.navigation
        self.occupancy.project_into(
            nav.grid, nav.known_band_m, nav.occupied_band_m, nav.known, nav.occupied, cells
        )
        nav.reproject()


def _insertion_region(
    grid: GridSpec, navigation: NavigationLayer, voxel_m: float
) -> tuple[GridSpec, int, slice]:
    """G extended downwards by whole cells until it covers the navigation bands, the number of
    cells added below, and the slice of its z layers holding the bands' voxels."""
    bands = (*navigation.known_band_m, *navigation.occupied_band_m)
    low, high = min(bands) - voxel_m, max(bands) + voxel_m  # voxels whose centre is in a band
    below = max(0, math.ceil((grid.low[2] - low) / grid.res - 1e-9))
    origin = (grid.origin[0], grid.origin[1], grid.origin[2] - below * grid.res)
    nz = grid.shape[2] + below
    region = GridSpec(origin, grid.res, (grid.shape[0], grid.shape[1], nz))
    k0 = max(0, math.floor((low - origin[2]) / grid.res))
    k1 = min(nz, math.ceil((high - origin[2]) / grid.res))
    return region, below, slice(k0, max(k0, k1))
