"""The exploration state: the occupancy map, the statistics grid G and the navigation layer, updated
together by one call per scan (work proportional to what the scan changed)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.config import check
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import MAX_WINDOW_M, GridSpec
from nbv_gym.mapping.navigation import NavigationConfig, NavigationLayer
from nbv_gym.mapping.occupancy import MapConfig, OccupancyMap, ScanUpdate
from nbv_gym.mapping.statistics import StatisticsConfig, ViewpointStatistics
from nbv_gym.mapping.tally import CellTally
from nbv_gym.sensor.lidar import SENSOR_RANGE_M, Scan


@dataclass(frozen=True)
class MappingConfig:
    """Map, statistics and navigation configs, and the sensor range they share (metres).

    ``fit_to_world``: the simulator grows G's x, y box (and with it the goals, the navigation
    grid and the map box, which keeps its margins around G) to hold the world's placement window
    (:meth:`for_window`); the configured boxes are the least it uses, so every world of a 60 m
    window keeps the default 60 × 60 goals. False: a world outside the configured boxes is
    refused. ``max_window_m``: the longest side (metres) G grows to; a world whose window needs
    more is refused (G's per-cell arrays and the navigation grid are dense: ~1 GB at 500 m).
    """

    sensor_range_m: float = SENSOR_RANGE_M
    map: MapConfig = field(default_factory=MapConfig)
    statistics: StatisticsConfig = field(default_factory=StatisticsConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    fit_to_world: bool = True
    max_window_m: float = MAX_WINDOW_M

    def __post_init__(self) -> None:
        check(self.sensor_range_m > 0, "sensor_range_m", f"must be > 0, got {self.sensor_range_m}")
        check(self.max_window_m > 0, "max_window_m", f"must be > 0, got {self.max_window_m}")
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

    def scored_grid(self) -> GridSpec:
        """G's box at the map's voxels: where map quality is scored against the ground truth."""
        grid = self.statistics.grid()
        return GridSpec.from_bounds(tuple(grid.low), tuple(grid.high), self.map.resolution_m)

    def fitted(self, window_m: tuple[float, float, float, float]) -> MappingConfig:
        """The config the simulator uses for a world placing assets in ``window_m``:
        :meth:`for_window` if ``fit_to_world`` and G's sides stay within ``max_window_m``, else
        this config (which the simulator then checks the window against)."""
        if not self.fit_to_world:
            return self
        fitted = self.for_window(window_m)
        grid = fitted.statistics.grid()
        sides = np.asarray(grid.shape[:2]) * grid.res
        return fitted if sides.max() <= self.max_window_m + 1e-9 else self

    def for_window(self, window_m: tuple[float, float, float, float]) -> MappingConfig:
        """This config with G's x, y box grown by whole cells of G until it holds ``window_m``
        (x_min, y_min, x_max, y_max metres) and the map box moved with it (same margins around
        G); the z extents and everything else unchanged. The config itself when G holds it."""
        stats, cell = self.statistics, self.statistics.cell_m
        low, high = np.asarray(stats.low_m, float), np.asarray(stats.high_m, float)
        grow_low = np.ceil(np.maximum(low[:2] - window_m[:2], 0.0) / cell - 1e-9) * cell
        grow_high = np.ceil(np.maximum(np.asarray(window_m[2:]) - high[:2], 0.0) / cell - 1e-9)
        grow_high = grow_high * cell
        if not (grow_low.any() or grow_high.any()):
            return self
        shift_low, shift_high = np.append(-grow_low, 0.0), np.append(grow_high, 0.0)

        def moved(box_low, box_high) -> dict:
            return {
                "low_m": tuple((np.asarray(box_low, float) + shift_low).tolist()),
                "high_m": tuple((np.asarray(box_high, float) + shift_high).tolist()),
            }

        return replace(
            self,
            map=replace(self.map, **moved(self.map.low_m, self.map.high_m)),
            statistics=replace(stats, **moved(stats.low_m, stats.high_m)),
        )


class ExplorationState:
    """The state every policy reads: ``occupancy``, ``statistics`` and ``navigation``.

    Insertion flags the cells of G that hold a changed voxel (which cuboids to re-evaluate) and
    keeps per-column counts of the known and occupied voxels of the navigation bands
    (:class:`~nbv_gym.mapping.columns.ColumnCounts`): the navigation cells whose counts changed
    are re-projected from them, without reading the map. Given an ``unobserved_band`` (low,
    high) of probabilities, the state also keeps per-cell totals of the map over G
    (:meth:`cell_totals`) for the quality metrics, and flags the cells where a voxel's
    probability crossed one of the ``coverage_thresholds`` (:meth:`take_crossed`).
    """

    def __init__(
        self,
        occupancy: OccupancyMap,
        statistics: ViewpointStatistics,
        navigation: NavigationLayer,
        unobserved_band: tuple[float, float] | None = None,
        coverage_thresholds: tuple[float, ...] = (),
    ):
        self.occupancy = occupancy
        self.statistics = statistics
        self.navigation = navigation
        self._columns = occupancy.column_counts(
            navigation.grid, navigation.known_band_m, navigation.occupied_band_m
        )
        self._tally = None
        if unobserved_band is not None:
            voxels = round(statistics.grid.res / occupancy.grid.res)
            p_min = occupancy.params["p_clamp_min"]
            self._tally = CellTally(
                statistics.grid.shape, voxels, unobserved_band, p_min, coverage_thresholds
            )

    @classmethod
    def from_config(
        cls,
        config: MappingConfig,
        unobserved_band: tuple[float, float] | None = None,
        coverage_thresholds: tuple[float, ...] = (),
    ) -> ExplorationState:
        """An empty state as ``config`` describes (with cell totals for ``unobserved_band`` and
        ``coverage_thresholds``)."""
        occupancy = OccupancyMap.from_config(config.map, config.sensor_range_m)
        statistics = ViewpointStatistics.from_config(config.statistics, config.sensor_range_m)
        navigation = NavigationLayer.from_config(config.navigation, statistics.grid)
        state = cls(occupancy, statistics, navigation, unobserved_band, coverage_thresholds)
        state.update_navigation(np.zeros(2))  # also checks that the grids fit together
        return state

    def apply(self, scan: Scan, robot_xy: FloatArray | None = None) -> ScanUpdate:
        """Insert ``scan`` (its map-frame points, seen from ``scan.origin``) into the map and the
        statistics, then update the navigation layer — re-projecting the cells whose column
        counts the scan changed — and plan once for the robot at ``robot_xy`` (2,) metres
        (default: the scan's sensor position).

        Raises:
            PoseError: the sensor lies outside the map box.
        """
        inserted = self.occupancy.insert(
            scan.origin, scan.points_map, self.statistics.grid, self._tally, self._columns
        )
        self.statistics.update(scan.origin, scan.points_map)
        columns = np.zeros(self.navigation.grid.shape[:2], bool)
        i, j = self._columns.take_changed().T
        columns[i, j] = True
        nav = self.navigation
        nav.known[i, j] = self._columns.known[i, j] > 0
        nav.occupied[i, j] = self._columns.occupied[i, j] > 0
        nav.reproject((i, j))
        nav.plan(scan.origin[:2] if robot_xy is None else robot_xy)
        return replace(inserted, columns=columns)

    def update_navigation(self, robot_xy: FloatArray) -> None:
        """Re-project the whole map onto the navigation grid and re-plan from ``robot_xy`` (2,)
        metres."""
        nav = self.navigation
        nav.project(*self.occupancy.project(nav.grid, nav.known_band_m, nav.occupied_band_m))
        nav.plan(robot_xy)

    def cell_totals(self) -> tuple[np.ndarray, np.ndarray]:
        """Views of G's shape (gx, gy, gz): float64 Σ p of each cell's map voxels (unknown = 0.5)
        and int32 the number of them outside the unobserved band; NbvGymError without a band."""
        tally = self._totals()
        return tally.sums, tally.outside

    def take_crossed(self) -> np.ndarray:
        """(k,) int64 flat indices of the cells of G holding a voxel whose probability crossed a
        coverage threshold since the last call (or the last :meth:`clear`), forgetting them."""
        return self._totals().take_crossed()

    @property
    def tally(self) -> CellTally | None:
        """The per-cell totals of the map over G (None without an unobserved band)."""
        return self._tally

    def _totals(self) -> CellTally:
        if self._tally is None:
            raise NbvGymError("this state keeps no cell totals: build it with unobserved_band")
        return self._tally

    def clear(self) -> None:
        """Forget everything (an empty state, as :meth:`from_config` builds), reusing the
        arrays."""
        if self._tally is not None:
            self._tally.clear()
        self._columns.clear()
        self.occupancy.clear()
        self.statistics.clear()
        self.navigation.clear()
