"""The exploration state: the occupancy map, the statistics grid G and the navigation layer, updated
together by one call per scan."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from nbv_gym.arrays import BoolArray, FloatArray
from nbv_gym.config import check
from nbv_gym.lidar import Scan
from nbv_gym.mapping.navigation import NavigationConfig, NavigationLayer
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap
from nbv_gym.mapping.statistics import StatisticsConfig, ViewpointStatistics


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


@dataclass(frozen=True)
class ScanUpdate:
    """What :meth:`ExplorationState.apply` did with one scan.

    Attributes:
        n_points: returns in the scan.
        n_dropped: returns dropped for a NaN or infinite coordinate.
        n_occupied: map voxels that received a hit.
        touched: (nx, ny, nz) bool over G: cells holding a map voxel this scan changed.
    """

    n_points: int
    n_dropped: int
    n_occupied: int
    touched: BoolArray

    @property
    def touched_cells(self) -> np.ndarray:
        """(k,) int64 flat (C-order) indices over G of the touched cells."""
        return np.flatnonzero(self.touched)


class ExplorationState:
    """The state every policy reads: ``occupancy``, ``statistics`` and ``navigation``."""

    def __init__(
        self, occupancy: OccupancyMap, statistics: ViewpointStatistics, navigation: NavigationLayer
    ):
        self.occupancy = occupancy
        self.statistics = statistics
        self.navigation = navigation

    @classmethod
    def from_config(cls, config: MappingConfig) -> ExplorationState:
        """An empty state as ``config`` describes."""
        occupancy = OccupancyMap.from_config(config.map, config.sensor_range_m)
        statistics = ViewpointStatistics.from_config(config.statistics, config.sensor_range_m)
        navigation = NavigationLayer.from_config(config.navigation, statistics.grid)
        state = cls(occupancy, statistics, navigation)
        state.update_navigation(np.zeros(2))  # also checks that the grids fit together
        return state

    def apply(self, scan: Scan, robot_xy: FloatArray | None = None) -> ScanUpdate:
        """Insert ``scan`` (its map-frame points, seen from ``scan.origin``) into the map and the
        statistics, then update the navigation layer for the robot at ``robot_xy`` (2,) metres
        (default: the scan's sensor position).

        Raises:
            PoseError: the sensor lies outside the map box.
        """
        inserted = self.occupancy.insert(scan.origin, scan.points_map, region=self.statistics.grid)
        self.statistics.update(scan.origin, scan.points_map)
        self.update_navigation(scan.origin[:2] if robot_xy is None else robot_xy)
        return ScanUpdate(
            inserted.n_points, inserted.n_dropped, inserted.n_occupied, inserted.touched
        )

    def update_navigation(self, robot_xy: FloatArray) -> None:
        """Re-project the map onto the navigation grid and re-plan from ``robot_xy`` (2,) metres."""
        nav = self.navigation
        known, occupied = self.occupancy.project(nav.grid, nav.known_band_m, nav.occupied_band_m)
        nav.update(known, occupied, robot_xy)
