"""The occupancy map: a dense grid of log-odds voxels with OctoMap's update semantics (docs/protocol.md#map).

Per scan, every voxel is updated at most once: the voxels holding a return within the sensor range
get a hit, then every other voxel crossed by a ray (OctoMap's ``computeRayKeys``: the sensor's voxel
included, the return's voxel excluded) gets a miss. A return beyond the range carves free space up to
the range along its ray and marks nothing occupied. Log-odds are clamped to the clamping bounds, as
in OctoMap with ``insertPointCloud(cloud, origin, max_range)``.

Storage is one float32 per voxel (640 × 640 × 90 voxels: 147.5 MB), zero bits for unknown so that
only pages some scan wrote are resident (:mod:`nbv_gym.mapping.store`), in bricks of 16 × 16 × 4
voxels, one page each (:mod:`nbv_gym.mapping.traversal`), plus a per-scan marking bitset over the
bricks of the sensor's reach (2.1 MB for 20 m at 0.1 m), through which a scan's updates are
applied in store order (:mod:`nbv_gym.mapping.insertion`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import cast

import numpy as np

from nbv_gym.core.arrays import BoolArray, FloatArray
from nbv_gym.core.config import check
from nbv_gym.core.errors import ConfigError, NbvGymError, PoseError
from nbv_gym.core.grid import GridSpec
from nbv_gym.core.protocol import RESOLUTION_M
from nbv_gym.mapping.blocks import CellReaders, is_whole
from nbv_gym.mapping.columns import NO_COLUMNS, ColumnCounts
from nbv_gym.mapping.insertion import MarkingWindow, grid_points, insert_scan
from nbv_gym.mapping.probability import new_cache, probabilities
from nbv_gym.mapping.store import ZeroPages, decoded, encoded
from nbv_gym.mapping.tally import NO_LOG, CellTally
from nbv_gym.mapping.traversal import BRICK, OUTSIDE, TILE, axis_offsets


def logit(p: float) -> float:
    """Log-odds ``ln(p / (1 − p))`` of a probability in (0, 1)."""
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class MapConfig:
    """The occupancy map's box, resolution and OctoMap sensor model (octomap_server defaults).

    A voxel is occupied iff its probability is ≥ ``p_occupied``; unknown voxels have probability 0.5.
    """

    resolution_m: float = RESOLUTION_M
    low_m: tuple[float, float, float] = (-32.0, -32.0, -1.0)
    high_m: tuple[float, float, float] = (32.0, 32.0, 8.0)
    p_hit: float = 0.7
    p_miss: float = 0.4
    p_clamp_min: float = 0.12
    p_clamp_max: float = 0.97
    p_occupied: float = 0.5

    def __post_init__(self) -> None:
        check(self.resolution_m > 0, "resolution_m", f"must be > 0, got {self.resolution_m}")
        check(0.5 < self.p_hit < 1, "p_hit", f"must be in (0.5, 1), got {self.p_hit}")
        check(0 < self.p_miss < 0.5, "p_miss", f"must be in (0, 0.5), got {self.p_miss}")
        check(
            0 < self.p_clamp_min < self.p_clamp_max < 1,
            "p_clamp_min",
            f"need 0 < p_clamp_min < p_clamp_max < 1, got {self.p_clamp_min}, {self.p_clamp_max}",
        )
        check(0 < self.p_occupied < 1, "p_occupied", f"must be in (0, 1), got {self.p_occupied}")
        self.grid()  # raises ConfigError unless the box is a whole number of voxels

    def grid(self) -> GridSpec:
        """The voxel grid of the map box."""
        return GridSpec.from_bounds(self.low_m, self.high_m, self.resolution_m)


@dataclass(frozen=True)
class ScanUpdate:
    """What one scan did to the map (:meth:`OccupancyMap.insert`,
    :meth:`ExplorationState.apply <nbv_gym.mapping.ExplorationState.apply>`).

    Attributes:
        n_points: returns given.
        n_dropped: returns dropped for a NaN or infinite coordinate.
        n_occupied: voxels that received a hit.
        n_updated: voxels updated, a hit or a miss each (those whose value stayed at a clamp
            included): the insertion's work.
        touched: bool mask over the ``region`` grid passed to ``insert`` (G in the exploration
            state): cells holding a voxel whose value changed (empty (0, 0, 0) without a region).
        touched_cells: (k,) int64 flat (C-order) indices of those cells.
        columns: (nx, ny) bool over the navigation grid (set by the exploration state): cells
            whose counts of known or occupied voxels in the navigation bands changed, hence
            re-projected (empty (0, 0) from a bare map insert).
    """

    n_points: int
    n_dropped: int
    n_occupied: int
    n_updated: int
    touched: BoolArray
    touched_cells: np.ndarray
    columns: BoolArray = field(default_factory=lambda: np.zeros((0, 0), bool))

    @property
    def changed_columns(self) -> np.ndarray:
        """(m, 2) int64 x, y indices of the changed columns."""
        return np.argwhere(self.columns)


class OccupancyMap(CellReaders):
    """Log-odds occupancy voxels over a box, updated scan by scan like OctoMap.

    Args:
        grid: the voxel grid (cell size = map resolution, metres).
        p_hit, p_miss: probabilities of the hit and miss updates.
        p_clamp_min, p_clamp_max: clamping bounds of a voxel's probability.
        p_occupied: a voxel is occupied iff its probability is ≥ this.
        max_range_m: sensor range; farther returns carve free space up to it and mark nothing.
    """

    def __init__(
        self,
        grid: GridSpec,
        *,
        p_hit: float,
        p_miss: float,
        p_clamp_min: float,
        p_clamp_max: float,
        p_occupied: float,
        max_range_m: float,
    ):
        check(max_range_m > 0, "max_range_m", f"must be > 0, got {max_range_m}")
        self.grid = grid
        self.params = {
            "p_hit": float(p_hit),
            "p_miss": float(p_miss),
            "p_clamp_min": float(p_clamp_min),
            "p_clamp_max": float(p_clamp_max),
            "p_occupied": float(p_occupied),
            "max_range_m": float(max_range_m),
        }
        self._deltas = np.array([logit(p_hit), logit(p_miss)], np.float32)
        self._bounds = np.array([logit(p_clamp_min), logit(p_clamp_max)], np.float32)
        self._lo_occupied = np.float32(logit(p_occupied))
        #: the log-odds of an unknown voxel after its first miss
        self._first_miss = min(max(self._deltas[1], self._bounds[0]), self._bounds[1])
        nx, ny, nz = grid.shape
        bx, by, bz = (-(-n // b) for n, b in zip(grid.shape, BRICK, strict=True))
        self._bricks = (bx, by, bz)
        self._dims = np.array([*self._bricks[:2], nx, ny, nz], np.int64)
        self._offsets = axis_offsets(self._bricks)
        self._pages = ZeroPages(math.prod(self._bricks) * math.prod(BRICK))
        self._store = self._pages.array
        self._window = MarkingWindow(grid.shape, max_range_m / grid.res)
        self._region_cells: dict[tuple, np.ndarray] = {}  # _touch_grid's tables per region
        self._dirty = np.zeros(self._pages.n_blocks, bool)  # store blocks written since clear()
        self._mapped = np.zeros(self._pages.n_blocks, bool)  # blocks written before clear()
        self._journal = np.zeros(self._pages.n_blocks, bool)  # blocks inserts wrote since taken
        self._sigmoid_cache = new_cache()

    @classmethod
    def from_config(cls, config: MapConfig, max_range_m: float) -> OccupancyMap:
        """An empty map as ``config`` describes, for a sensor of range ``max_range_m`` metres."""
        return cls(
            config.grid(),
            p_hit=config.p_hit,
            p_miss=config.p_miss,
            p_clamp_min=config.p_clamp_min,
            p_clamp_max=config.p_clamp_max,
            p_occupied=config.p_occupied,
            max_range_m=max_range_m,
        )

    @staticmethod
    def brick_counts(grid: GridSpec, max_range_m: float) -> tuple[tuple[int, ...], ...]:
        """The bricks (pages) of a map over ``grid`` along x, y, z, and the most bricks along
        each axis that the marking window of a sensor of range ``max_range_m`` (the voxels one
        scan can write) overlaps: one more than it spans, as it need not start on a brick."""
        box = tuple(-(-n // b) for n, b in zip(grid.shape, BRICK, strict=True))
        return box, MarkingWindow.brick_shape(grid.shape, max_range_m / grid.res)

    # ------------------------------------------------------------------ update

    def insert(
        self,
        origin: FloatArray,
        points: FloatArray,
        region: GridSpec | None = None,
        tally: CellTally | None = None,
        columns: ColumnCounts | None = None,
    ) -> ScanUpdate:
        """Insert one scan.

        Args:
            origin: (3,) float sensor position in the map frame, metres; must lie inside the map box.
            points: (n, 3) float returns in the map frame, metres. Rows with a NaN or infinite
                coordinate are dropped and counted.
            region: an optional coarse grid aligned to the map whose cells are whole numbers of
                voxels (e.g. the statistics grid G); the result's ``touched`` mask is over it.
            tally: per-cell totals over ``region`` to keep up to date (built for this map when it
                was empty, cleared with it).
            columns: per-column counts to keep up to date (:meth:`column_counts`, built when the
                map was empty, cleared with it).

        Raises:
            PoseError: the sensor lies outside the map box or is not finite.
        """
        origin_grid = self._origin_in_grid(origin)
        points = _as_points(points)
        points_grid = grid_points(points, self.grid.low, self.grid.res)
        touched, cells = self._touch_grid(region)
        if tally is not None and tally.sums.shape != touched.shape:
            raise NbvGymError(f"a tally of {tally.sums.shape} cells needs a region of that shape")
        log = NO_LOG if tally is None else tally.log
        n_occupied, n_changes, n_updated = self._update(
            origin_grid, points_grid, touched, cells, log, columns or NO_COLUMNS
        )
        changed = np.flatnonzero(touched)
        if tally is not None and not tally.apply(
            n_changes, self._sigmoid_cache, self._first_miss, changed
        ):
            cells = np.argwhere(touched)
            # a tally has the shape of the touched mask (checked above), so it comes with a region
            tally.recount(cells, self.probability_blocks(cast(GridSpec, region), cells))
        n_dropped = len(points) - len(points_grid)
        return ScanUpdate(len(points), n_dropped, int(n_occupied), int(n_updated), touched, changed)

    def clear(self) -> None:
        """Forget every voxel (all unknown again), reusing the storage: only the blocks written
        since the last clear are reset, in place, so that their memory pages stay mapped for the
        next episode (which, from the same start pose, writes most of them again, and need not
        fault them in). Pages that the episode before the last wrote but the last did not are
        handed back to the system: the map holds at most two episodes' pages."""
        self._pages.zero_blocks(self._dirty | self._mapped, self._dirty)
        np.copyto(self._mapped, self._dirty)
        self._dirty[:] = False

    def written_blocks(self) -> np.ndarray:
        """(n_blocks,) bool: the store's blocks written since the last :meth:`clear` (a copy)."""
        return self._dirty.copy()

    def take_journal(self) -> np.ndarray:
        """(n_blocks,) bool: the store's blocks that :meth:`insert` wrote since the last call
        (or since the map was made); the journal starts empty again."""
        blocks = self._journal.copy()
        self._journal[:] = False
        return blocks

    def copy_blocks(self, source: OccupancyMap, blocks: np.ndarray) -> None:
        """Make the store blocks flagged in the (n_blocks,) bool ``blocks`` equal to those of
        ``source`` (a map over the same grid); they count as written."""
        if source.grid != self.grid:
            raise NbvGymError(f"cannot copy blocks of a map over {source.grid} into {self.grid}")
        index = np.flatnonzero(blocks)
        self._pages.blocks[index] = source._pages.blocks[index]
        self._dirty[index] = True

    def _origin_in_grid(self, origin: FloatArray) -> np.ndarray:
        """(3,) float64 sensor position in grid units; PoseError outside the box."""
        origin = np.asarray(origin, dtype=np.float64).reshape(3)
        inside = np.all(origin >= self.grid.low) and np.all(origin < self.grid.high)
        if not (np.isfinite(origin).all() and inside):
            raise PoseError(
                f"sensor position {origin.tolist()} is outside the map box "
                f"{self.grid.low.tolist()}–{self.grid.high.tolist()} m; keep the robot inside the "
                "map or enlarge MapConfig.low_m/high_m"
            )
        return (origin - self.grid.low) / self.grid.res

    def _update(
        self,
        origin_grid: np.ndarray,
        points_grid: np.ndarray,
        touched: np.ndarray,
        cells: np.ndarray,
        log: tuple,
        columns: ColumnCounts,
    ) -> tuple[int, int, int]:
        """Apply a scan (sensor and finite returns in grid units) to the store and the
        bookkeeping (:func:`~nbv_gym.mapping.insertion.insert_scan`); returns the number of
        voxels hit, of changes logged and of voxels updated."""
        layout = self._window.place(origin_grid)
        return self._window.run(
            insert_scan, self._store, self._offsets, origin_grid, points_grid,
            self.params["max_range_m"] / self.grid.res, self._deltas, self._bounds,
            self._window.words, self._window.tables, layout, touched.reshape(-1), cells, log,
            self._dirty, self._journal, columns.kernel_args(),
        )  # fmt: skip

    def _touch_grid(self, region: GridSpec | None) -> tuple[np.ndarray, np.ndarray]:
        """The empty touched mask over ``region`` and the (3, n) part of the flat region cell
        index (cell index × stride) of each voxel index along each axis (``OUTSIDE`` outside the
        region: a sum with one is negative), computed once per region."""
        if region is None:
            return np.zeros((0, 0, 0), bool), np.full((3, max(self.grid.shape)), OUTSIDE)
        key = (tuple(region.origin), region.res, tuple(region.shape))
        if key not in self._region_cells:
            self._region_cells[key] = self._region_index(region)
        return np.zeros(region.shape, bool), self._region_cells[key]

    def _region_index(self, region: GridSpec) -> np.ndarray:
        """:meth:`_touch_grid`'s (3, n) table of ``region``; ConfigError unless it is aligned."""
        factor = region.res / self.grid.res
        offset = (region.low - self.grid.low) / self.grid.res
        if not (is_whole(factor) and factor >= 1 and np.all(is_whole(offset))):
            raise ConfigError(
                f"region grid (origin {region.origin}, {region.res} m cells) must be aligned to the "
                f"map's {self.grid.res} m voxels and use a whole multiple of that cell size"
            )
        cells = (np.arange(max(self.grid.shape)) - np.rint(offset)[:, None]) // round(factor)
        outside = (cells < 0) | (cells >= np.asarray(region.shape)[:, None])
        strides = np.array([region.shape[1] * region.shape[2], region.shape[2], 1])
        return np.where(outside, OUTSIDE, cells * strides[:, None]).astype(np.int64)

    # ------------------------------------------------------------------ queries

    @property
    def logodds(self) -> np.ndarray:
        """(nx, ny, nz) float32 log-odds over :attr:`grid`, NaN = unknown: a copy of the whole map
        (0.15 GB by default; :meth:`logodds_in` copies a part)."""
        return self._dense((0, 0, 0), self.grid.shape)

    @property
    def occupied_logodds(self) -> float:
        """The log-odds at and above which a voxel is occupied."""
        return float(self._lo_occupied)

    @property
    def n_known(self) -> int:
        """Number of known voxels."""
        blocks = self._store.reshape(-1, math.prod(BRICK))[np.flatnonzero(self._dirty)]
        return int(np.count_nonzero(blocks.view(np.uint32)))

    def memory_bytes(self) -> int:
        """Bytes the map's arrays span (only the store's written pages are resident)."""
        return self._store.nbytes + self._window.words.nbytes

    def logodds_in(self, grid: GridSpec) -> np.ndarray:
        """float32 log-odds of ``grid.shape`` (NaN = unknown, also outside the map box).

        ``grid`` must have the map's resolution and be aligned to its voxels.
        """
        offset = self._voxel_offset(grid)
        out = np.full(grid.shape, np.nan, dtype=np.float32)
        lo = np.maximum(offset, 0)
        hi = np.minimum(offset + grid.shape, self.grid.shape)
        if np.all(hi > lo):
            out[tuple(slice(a, b) for a, b in zip(lo - offset, hi - offset, strict=True))] = (
                self._dense(lo, hi)
            )
        return out

    def probability(self, grid: GridSpec) -> np.ndarray:
        """float32 occupancy probability of ``grid.shape``; 0.5 where unknown or outside the map.

        ``grid`` must have the map's resolution and be aligned to its voxels (``ConfigError``
        otherwise).
        """
        return probabilities(self.logodds_in(grid))

    def known_mask(self, grid: GridSpec) -> np.ndarray:
        """bool of ``grid.shape``: voxels observed at least once."""
        return ~np.isnan(self.logodds_in(grid))

    def occupied_mask(self, grid: GridSpec) -> np.ndarray:
        """bool of ``grid.shape``: voxels whose probability is ≥ ``p_occupied``."""
        return _at_least(self.logodds_in(grid), self._lo_occupied)

    def occupied_points(self, threshold: float = 0.5) -> np.ndarray:
        """(n, 3) float64 centres (metres) of the voxels with probability ≥ ``threshold``."""
        index, _ = self.voxels_at_least(threshold)
        return self.grid.centres(index)

    def _brick_view(self) -> np.ndarray:
        """(BZ, BX, BY, z, X, Y, x, y) view of the bricked storage: brick, tile in the brick
        (4 z layers × 4 × 4 tiles) and voxel in the tile (4 × 4); voxel (i, j, k) is at
        i = (BX·4 + X)·4 + x, j = (BY·4 + Y)·4 + y, k = BZ·4 + z."""
        bx, by, bz = self._bricks
        return self._store.reshape(bz, bx, by, BRICK[2], TILE, TILE, TILE, TILE)

    def _dense(self, lo, hi) -> np.ndarray:
        """float32 log-odds (NaN = unknown) of the voxels ``lo ≤ (i, j, k) < hi`` in (x, y, z)
        order."""
        first = [a // b for a, b in zip(lo, BRICK, strict=True)]
        end = [-(-a // b) for a, b in zip(hi, BRICK, strict=True)]
        bricks = self._brick_view()[first[2] : end[2], first[0] : end[0], first[1] : end[1]]
        shape = [(e - f) * b for f, e, b in zip(first, end, BRICK, strict=True)]
        dense = bricks.transpose(1, 4, 6, 2, 5, 7, 0, 3).reshape(shape)
        start = [a - f * b for a, f, b in zip(lo, first, BRICK, strict=True)]
        return decoded(
            dense[tuple(slice(s, s + h - a) for s, a, h in zip(start, lo, hi, strict=True))]
        )

    def _set_dense(self, logodds: np.ndarray) -> None:
        """Replace the whole map by (nx, ny, nz) float32 log-odds (NaN = unknown)."""
        nx, ny, nz = self.grid.shape
        bx, by, bz = self._bricks
        padded = np.full((bx * BRICK[0], by * BRICK[1], bz * BRICK[2]), np.nan, np.float32)
        padded[:nx, :ny, :nz] = logodds
        bricked = padded.reshape(bx, TILE, TILE, by, TILE, TILE, bz, BRICK[2])
        bricked = bricked.transpose(6, 0, 3, 7, 1, 4, 2, 5)
        bricked = encoded(bricked.ravel())
        known = np.flatnonzero(bricked.view(np.uint32))  # write only the pages that hold voxels
        self._pages.zero(0, self._store.size)
        self._store[known] = bricked[known]

    def voxels_at_least(self, threshold: float) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) int64 indices and (n,) float32 log-odds of the known voxels with probability ≥
        ``threshold`` (≤ 0: all known voxels), in (x, y, z) C order. Reads only the store's
        blocks written since the last :meth:`clear` (memory and time follow the observed
        volume, not the map box)."""
        blocks = np.flatnonzero(self._dirty)
        values = self._store.reshape(-1, math.prod(BRICK))[blocks]
        values = values.reshape(-1, BRICK[2], TILE, TILE, TILE, TILE)
        keep = values != 0
        if threshold >= 1:
            keep[:] = False
        elif threshold > 0:
            keep &= values >= np.float32(logit(threshold))
        block, z, tx, ty, x, y = np.nonzero(keep)
        bx, by, bz = self._bricks
        brick_z, brick_x, brick_y = np.unravel_index(blocks[block], (bz, bx, by))
        index = np.column_stack(
            [
                (brick_x * TILE + tx) * TILE + x,
                (brick_y * TILE + ty) * TILE + y,
                brick_z * BRICK[2] + z,
            ]
        ).astype(np.int64)
        order = np.lexsort(index.T[::-1])
        return index[order], decoded(values[keep][order])

    def _voxel_offset(self, grid: GridSpec) -> np.ndarray:
        """(3,) int64 index in the map of ``grid``'s first voxel; ConfigError if not aligned."""
        offset = (grid.low - self.grid.low) / self.grid.res
        if not (math.isclose(grid.res, self.grid.res) and np.all(is_whole(offset))):
            raise ConfigError(
                f"query grid (origin {grid.origin}, res {grid.res} m) must have the map's "
                f"resolution {self.grid.res} m and be aligned to its voxels (map origin "
                f"{self.grid.origin}); build it with GridSpec.from_bounds on multiples of "
                f"{self.grid.res} m"
            )
        return np.rint(offset).astype(np.int64)

    @classmethod
    def from_logodds(cls, grid: GridSpec, logodds: np.ndarray, **params: float) -> OccupancyMap:
        """A map over ``grid`` holding the (nx, ny, nz) float ``logodds`` (NaN = unknown);
        ``params`` are the constructor's keyword arguments."""
        logodds = np.asarray(logodds, dtype=np.float32)
        if logodds.shape != grid.shape:
            raise NbvGymError(
                f"logodds must have the grid's shape {grid.shape}, got {logodds.shape}"
            )
        occupancy = cls(grid, **params)
        occupancy._set_dense(logodds)
        occupancy._dirty[:] = True
        return occupancy


def _at_least(logodds: np.ndarray, threshold: np.float32) -> np.ndarray:
    """bool: known (not NaN) and ≥ ``threshold``."""
    return np.greater_equal(
        logodds, threshold, where=~np.isnan(logodds), out=np.zeros(logodds.shape, bool)
    )


def _as_points(points: FloatArray) -> np.ndarray:
    """(n, 3) float64 points; NbvGymError for any other shape."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise NbvGymError(f"points must be an (n, 3) array of metres, got shape {points.shape}")
    return points
