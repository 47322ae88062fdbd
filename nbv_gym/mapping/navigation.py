"""The navigation layer (docs/protocol.md#navigation): a 2D projection of the map, reachability and the goal grid.

- Projection at ``cell_m`` (0.5 m) over the window (G's x, y extent), computed by
  :meth:`OccupancyMap.project <nbv_gym.mapping.OccupancyMap.project>` with this layer's bands: a
  cell is *known* if any voxel of its columns whose centre lies in ``known_band_m`` is known,
  *occupied* if any voxel whose centre lies in ``occupied_band_m`` is occupied, *free* if known and
  not occupied.
- Erosion by the robot radius: a cell stays free iff every cell that a disc of ``robot_radius_m``
  around its centre overlaps is free (0.5 m at 0.5 m cells: the 3 × 3 block). Cells outside the
  window count as not free.
- Frontier cells: dilated unknown ∧ eroded free ∧ ¬ dilated occupied, centres at least
  ``border_margin_m`` inside the window (dilations with the same disc rule, by
  ``frontier_unknown_dilation_m`` and ``frontier_occupied_margin_m``).
- Path lengths: 8-connected Dijkstra over eroded free cells (steps ``cell_m`` and ``√2·cell_m``
  between cell centres) from the robot's cell (always a source). Near the robot the search may
  also cross free cells that erosion removed, within ``escape_radius_m``: a scan that reveals an
  obstacle next to the goal the robot just reached, or a lidar outlier beside it, cannot trap it
  where it stands (*ours*; goals still need eroded free space, and occupied cells stay walls).
- Goals: the x, y cells of G (row-major: index = i·ny + j, i along x). A point belongs to the nav
  cell that holds it under the half-open grid convention, so a goal's centre (a corner of four nav
  cells) belongs to the cell up and right of it; path lengths between goal centres are then exact
  8-connected distances. A goal is valid iff its nav cell is eroded free and reachable, its centre is
  at least ``border_margin_m`` from the window border, and it is not the robot's own G cell (nor
  an excluded goal: :meth:`NavigationLayer.exclude_goals`, a team's teammates' cells);
  cost = min(path length / ``cost_range_m``, 1) (1 for invalid goals). A reach limit
  (:meth:`NavigationLayer.limit_reach`, the time task's remaining time) makes goals farther
  along the path invalid too. A *frontier goal* is a valid
  goal whose nav cell is a frontier cell or touches one (8-neighbourhood): every frontier cell
  touches the nav cell of some goal, so frontiers and frontier goals vanish together unless the
  goals next to a frontier are invalid.
- The unknown space must be dilated by more than the robot radius, otherwise no eroded free cell
  can lie in it; the default (1 m = robot radius + 0.5 m) gives a one-cell frontier band.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from nbv_gym.core.arrays import BoolArray, FloatArray
from nbv_gym.core.config import check
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.morphology import dilate, erode, half_widths
from nbv_gym.sensor.lidar import SENSOR_RANGE_M


@dataclass(frozen=True)
class NavigationConfig:
    """The 2D navigation grid and the robot's clearance, metres."""

    cell_m: float = 0.5
    robot_radius_m: float = 0.5
    escape_radius_m: float = 2.0
    known_band_m: tuple[float, float] = (-0.3, 1.0)
    occupied_band_m: tuple[float, float] = (0.2, 1.0)
    cost_range_m: float = SENSOR_RANGE_M
    border_margin_m: float = 1.0
    frontier_unknown_dilation_m: float = 1.0
    frontier_occupied_margin_m: float = 1.0

    def __post_init__(self) -> None:
        check(self.cell_m > 0, "cell_m", f"must be > 0, got {self.cell_m}")
        for name in (
            "robot_radius_m",
            "escape_radius_m",
            "border_margin_m",
            "frontier_unknown_dilation_m",
        ):
            check(getattr(self, name) >= 0, name, f"must be ≥ 0, got {getattr(self, name)}")
        check(self.frontier_occupied_margin_m >= 0, "frontier_occupied_margin_m", "must be ≥ 0")
        check(
            self.frontier_unknown_dilation_m > self.robot_radius_m,
            "frontier_unknown_dilation_m",
            f"must exceed robot_radius_m ({self.robot_radius_m}) or no frontier can exist, "
            f"got {self.frontier_unknown_dilation_m}",
        )
        check(self.cost_range_m > 0, "cost_range_m", f"must be > 0, got {self.cost_range_m}")
        for name in ("known_band_m", "occupied_band_m"):
            low, high = getattr(self, name)
            check(low < high, name, f"need low < high, got {(low, high)}")


class NavigationLayer:
    """Known / free / occupied projection, frontiers, reachability and goal validity and cost.

    Args:
        goal_grid: the grid G; its x, y cells are the goals and its x, y extent is the window.
        The keyword arguments are :class:`NavigationConfig`'s fields.
    """

    def __init__(
        self,
        goal_grid: GridSpec,
        *,
        cell_m: float,
        robot_radius_m: float,
        escape_radius_m: float,
        known_band_m: tuple[float, float],
        occupied_band_m: tuple[float, float],
        cost_range_m: float,
        border_margin_m: float,
        frontier_unknown_dilation_m: float,
        frontier_occupied_margin_m: float,
    ):
        self.goal_grid = goal_grid
        self.grid = _nav_grid(goal_grid, cell_m, known_band_m[0])
        self.known_band_m: tuple[float, float] = (known_band_m[0], known_band_m[1])
        self.occupied_band_m: tuple[float, float] = (occupied_band_m[0], occupied_band_m[1])
        self.cost_range_m = float(cost_range_m)
        self._robot_widths = half_widths(disc(robot_radius_m, cell_m))
        self._escape_disc = disc(escape_radius_m, cell_m)
        self._unknown_widths = half_widths(disc(frontier_unknown_dilation_m, cell_m))
        self._occupied_widths = half_widths(disc(frontier_occupied_margin_m, cell_m))
        self._inner = _inner_cells(self.grid, border_margin_m)
        centres = goal_grid.xy_centres()
        cells = self.grid.index(np.column_stack([centres, np.zeros(len(centres))]))[:, :2]
        #: (n_goals,) flat index of each goal's nav cell in the (nx, ny) layers
        self._goal_cells = np.ravel_multi_index(tuple(cells.T), self.grid.shape[:2])
        self._goal_inner = _inner_cells(_flat(goal_grid), border_margin_m).ravel()
        shape = self.grid.shape[:2]
        self.known = np.zeros(shape, bool)
        self.occupied = np.zeros(shape, bool)
        self.eroded_free = np.zeros(shape, bool)
        self.frontier_mask = np.zeros(shape, bool)
        self._frontier_near = np.zeros(shape, bool)  # frontier_mask dilated by one cell
        #: (3, gx, gy) float64: the fraction of each goal cell's nav cells that are known, free
        #: and occupied
        self.goal_fractions = np.zeros((3, *goal_grid.shape[:2]))
        self._cells_per_goal = round(goal_grid.res / cell_m)
        #: the farthest (nav cells) an erosion or dilation of a layer reaches from a cell
        self._stencil_cells = max(max(len(w) // 2, int(w.max())) for w in (
            self._robot_widths, self._unknown_widths, self._occupied_widths))  # fmt: skip
        self.distance = np.full(shape, np.inf)
        self.robot_xy = np.zeros(2)
        #: the longest path (metres) a valid goal may take (:meth:`limit_reach`; inf: no limit)
        self.reach_m = math.inf
        #: (k,) int64 goals made invalid besides the rules above (a team's: where teammates
        #: stand or drive to; :meth:`exclude_goals`)
        self.excluded_goals = np.zeros(0, np.int64)
        self._goals: _Goals | None = None

    @classmethod
    def from_config(cls, config: NavigationConfig, goal_grid: GridSpec) -> NavigationLayer:
        """The layer ``config`` describes over ``goal_grid``'s goals."""
        return cls(goal_grid, **vars(config))

    # ------------------------------------------------------------------ update

    def update(self, known: BoolArray, occupied: BoolArray, robot_xy: FloatArray) -> None:
        """Recompute every layer from the (nx, ny) bool ``known`` and ``occupied`` projections over
        :attr:`grid` (see :meth:`OccupancyMap.project`) and the robot's (2,) position in metres."""
        self.project(known, occupied)
        self.plan(robot_xy)

    def project(self, known: BoolArray, occupied: BoolArray) -> None:
        """Set the known and occupied cells and recompute eroded free space and frontiers."""
        shape = self.grid.shape[:2]
        if np.shape(known) != shape or np.shape(occupied) != shape:
            raise NbvGymError(
                f"known and occupied must have the nav grid's shape {shape}, "
                f"got {np.shape(known)} and {np.shape(occupied)}"
            )
        self.known[...] = known
        self.occupied[...] = occupied
        self.reproject()

    def reproject(self, changed: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Recompute eroded free space, frontiers and :attr:`goal_fractions` from :attr:`known`
        and :attr:`occupied` (after they were changed in place, e.g. from the map's column
        counts): everywhere, or around the nav cells ``changed`` ((m,) x and (m,) y indices, the
        only cells whose known or occupied flags changed) — the same result, with work
        proportional to the changed area."""
        nx, ny = self.grid.shape[:2]
        if changed is None:
            box = (0, nx, 0, ny)
        elif len(changed[0]):
            box = (changed[0].min(), changed[0].max() + 1, changed[1].min(), changed[1].max() + 1)
        else:
            return
        written = _grown(box, self._stencil_cells + 1, (nx, ny))  # every output that can change
        window = _grown(written, self._stencil_cells + 1, (nx, ny))  # every input those depend on
        part = (slice(window[0], window[1]), slice(window[2], window[3]))
        inner = (slice(written[0] - window[0], written[1] - window[0]),
                 slice(written[2] - window[2], written[3] - window[2]))  # fmt: skip
        known, occupied = self.known[part], self.occupied[part]
        eroded = erode(known & ~occupied, self._robot_widths)
        unknown_near = dilate(~known, self._unknown_widths)
        occupied_near = dilate(occupied, self._occupied_widths)
        frontier = unknown_near & eroded & ~occupied_near & self._inner[part]
        out = (slice(written[0], written[1]), slice(written[2], written[3]))
        self.eroded_free[out] = eroded[inner]
        self.frontier_mask[out] = frontier[inner]
        self._frontier_near[out] = dilate(frontier, _NEIGHBOURS)[inner]
        self._update_fractions(box)
        self._goals = None

    def _update_fractions(self, box: tuple[int, int, int, int]) -> None:
        """:attr:`goal_fractions` of the goal cells holding the nav cells ``box`` (i0, i1, j0,
        j1)."""
        f = self._cells_per_goal
        goals = (box[0] // f, -(-box[1] // f), box[2] // f, -(-box[3] // f))
        _goal_fractions(self.known, self.occupied, f, *goals, self.goal_fractions)

    def plan(self, robot_xy: FloatArray) -> None:
        """Recompute path lengths from the robot at ``robot_xy`` (2,) metres over eroded free
        cells and the robot's escape zone."""
        self.robot_xy = np.asarray(robot_xy, dtype=float).reshape(2)
        cell = self.grid.index(np.array([[*self.robot_xy, self.grid.origin[2]]]))[0, :2]
        start = (int(cell[0]), int(cell[1]))
        self.distance = path_lengths(self._passable(start), start, self.grid.res)
        self._goals = None

    def limit_reach(self, reach_m: float) -> None:
        """Make goals whose path is longer than ``reach_m`` metres invalid (inf: no limit)."""
        if reach_m != self.reach_m:
            self.reach_m = float(reach_m)
            self._goals = None

    def exclude_goals(self, goals: np.ndarray) -> None:
        """Make the (k,) goal indices ``goals`` invalid (none: an empty array) until the next
        call or :meth:`clear`."""
        goals = np.asarray(goals, np.int64).reshape(-1)
        if not np.array_equal(goals, self.excluded_goals):
            self.excluded_goals = goals
            self._goals = None

    def clear(self) -> None:
        """Forget the map: nothing known, the robot at the origin, path lengths from there.
        (With nothing known, nothing is free, eroded free or a frontier: :meth:`reproject`'s
        result, without the passes over the grid)."""
        for array in (self.known, self.occupied, self.eroded_free, self.frontier_mask,
                      self._frontier_near, self.goal_fractions):  # fmt: skip
            array[...] = 0
        self.excluded_goals = np.zeros(0, np.int64)
        self._goals = None
        self.plan(np.zeros(2))

    def _passable(self, cell: tuple[int, int]) -> BoolArray:
        """(nx, ny) bool: eroded free cells, and the free cells within the escape radius of
        ``cell`` (written in the disc's box only)."""
        passable = self.eroded_free.copy()
        k = self._escape_disc.shape[0] // 2
        nx, ny = passable.shape
        i0, j0 = max(cell[0] - k, 0), max(cell[1] - k, 0)
        i1, j1 = min(cell[0] + k + 1, nx), min(cell[1] + k + 1, ny)
        if i0 < i1 and j0 < j1:
            box = (slice(i0, i1), slice(j0, j1))
            zone = self._escape_disc[i0 - cell[0] + k : i1 - cell[0] + k,
                                     j0 - cell[1] + k : j1 - cell[1] + k]  # fmt: skip
            passable[box] |= zone & self.known[box] & ~self.occupied[box]
        return passable

    # ------------------------------------------------------------------ read-out

    @property
    def free(self) -> BoolArray:
        """(nx, ny) bool known and not occupied (before erosion)."""
        return self.known & ~self.occupied

    @property
    def discovered_fraction(self) -> float:
        """Known nav cells / all nav cells of the window."""
        return float(np.count_nonzero(self.known) / self.known.size)  # = known.mean(), bit for bit

    @property
    def robot_goal(self) -> int:
        """Index of the goal cell holding the robot (−1 if outside the window)."""
        i, j = np.floor((self.robot_xy - self.goal_grid.low[:2]) / self.goal_grid.res).astype(int)
        nx, ny = self.goal_grid.shape[:2]
        return int(i * ny + j) if 0 <= i < nx and 0 <= j < ny else -1

    def goal_path_length(self) -> np.ndarray:
        """(n_goals,) float64 path length (metres) from the robot to each goal, inf if unreachable
        (read-only; computed once per plan, like the other goal read-outs)."""
        return self._goal_arrays().path_length

    def goal_mask(self, limited: bool = True) -> np.ndarray:
        """(n_goals,) bool: valid goals (read-only); ``limited=False``: those that would be
        valid without the reach limit."""
        goals = self._goal_arrays()
        return goals.mask if limited else goals.reachable

    def goal_cost(self, clipped: bool = True) -> np.ndarray:
        """(n_goals,) float64 min(path length / ``cost_range_m``, 1); 1 for invalid goals
        (read-only). ``clipped=False``: path length / ``cost_range_m`` however far (the time
        task's, whose reach limit bounds it)."""
        goals = self._goal_arrays()
        return goals.cost if clipped else goals.unclipped_cost

    def frontier_goal_mask(self) -> np.ndarray:
        """(n_goals,) bool: valid goals whose nav cell is or touches (8-neighbourhood) a frontier
        cell (read-only)."""
        return self._goal_arrays().frontier

    def _goal_arrays(self) -> _Goals:
        """The goal read-outs of the current projection and plan, computed on first use."""
        if self._goals is None:
            self._goals = self._compute_goals()
        return self._goals

    def _compute_goals(self) -> _Goals:
        cells = self._goal_cells
        path_length = self.distance.reshape(-1).take(cells)
        path_length[~self.eroded_free.reshape(-1).take(cells)] = np.inf
        reachable = np.isfinite(path_length) & self._goal_inner
        if self.robot_goal >= 0:
            reachable[self.robot_goal] = False
        reachable[self.excluded_goals] = False
        mask = reachable & (path_length <= self.reach_m) if self.reach_m < math.inf else reachable
        unclipped = np.where(mask, path_length / self.cost_range_m, 1.0)
        cost = np.minimum(unclipped, 1.0)
        frontier = self._frontier_near.reshape(-1).take(cells) & mask
        for array in (path_length, reachable, mask, cost, unclipped, frontier):
            array.flags.writeable = False
        return _Goals(path_length, reachable, mask, cost, unclipped, frontier)


@dataclass(frozen=True)
class _Goals:
    """The (n_goals,) read-outs of one projection and plan (see the NavigationLayer methods)."""

    path_length: np.ndarray
    reachable: np.ndarray
    mask: np.ndarray
    cost: np.ndarray
    unclipped_cost: np.ndarray
    frontier: np.ndarray


#: Row half widths of the 3 × 3 block: a cell and its 8 neighbours.
_NEIGHBOURS = half_widths(np.ones((3, 3), bool))


def disc(radius_m: float, cell_m: float) -> np.ndarray:
    """(2k+1, 2k+1) bool: the cells a disc of ``radius_m`` around a cell's centre overlaps."""
    k = math.ceil(radius_m / cell_m + 0.5)
    d = np.abs(np.arange(-k, k + 1))
    gap = np.maximum(d - 0.5, 0.0) * cell_m
    element = gap[:, None] ** 2 + gap[None, :] ** 2 < radius_m**2
    element[k, k] = True
    return element


def path_lengths(passable: np.ndarray, start: tuple[int, int], step_m: float) -> np.ndarray:
    """(nx, ny) float64 8-connected shortest path lengths (metres) from cell ``start`` through the
    ``passable`` (nx, ny) bool cells; inf where unreachable. ``start`` is a source even if not
    passable; outside the grid, everything is inf."""
    nx, ny = passable.shape
    if not (0 <= start[0] < nx and 0 <= start[1] < ny):
        return np.full(passable.shape, np.inf)
    if not passable.any():  # the start alone (a cleared map's plan), without the search's heap
        distance = np.full(passable.shape, np.inf)
        distance[start] = 0.0
        return distance
    return _dijkstra(passable, start[0], start[1], float(step_m))


#: The bucket width of :func:`_dijkstra` in steps: under one, so that a cell's bucket is always
#: after that of the cell it is reached from, whatever the rounding.
_BUCKET_STEPS = 0.999


@njit(cache=True)
def _dijkstra(passable, si, sj, step):
    """Dijkstra's algorithm on the 8-connected grid with a bucket queue: distances fall into
    buckets ``_BUCKET_STEPS · step`` wide, narrower than the shortest edge, so every cell of the
    lowest open bucket is already final (its best neighbour lies in an earlier bucket) and is
    settled in any order, with no heap. An edge leads at most 2 buckets on (√2 / 0.999 < 2), so 4
    buckets in a ring suffice; a cell is put in a bucket when its distance first falls into it,
    and entries whose cell has moved to an earlier bucket are skipped. Any correct order of
    settling gives the same distances, bit for bit: each is the least ``dist[u] + w`` over the
    neighbours settled before it. The grid is padded by one impassable cell on each side, so
    that the neighbours need no bounds checks."""
    nx, ny = passable.shape
    py = ny + 2
    n = (nx + 2) * py
    open_ = np.zeros(n, np.bool_)
    for i in range(nx):
        for j in range(ny):
            open_[(i + 1) * py + j + 1] = passable[i, j]
    dist = np.full(n, np.inf)
    diagonal = step * math.sqrt(2.0)
    offsets = np.array([-py - 1, -py, -py + 1, -1, 1, py - 1, py, py + 1])
    weights = np.array([diagonal, step, diagonal, step, step, diagonal, step, diagonal])
    per_bucket = 1.0 / (step * _BUCKET_STEPS)
    ring = np.empty((4, n), np.int32)  # a cell is at most once in each bucket
    sizes = np.zeros(4, np.int64)
    start = (si + 1) * py + sj + 1
    dist[start], ring[0, 0], sizes[0] = 0.0, start, 1
    pending, bucket = 1, 0
    while pending:
        slot = bucket & 3
        for entry in range(sizes[slot]):
            u = ring[slot, entry]
            d = dist[u]
            if int(d * per_bucket) != bucket:  # settled already, from an earlier bucket
                continue
            for t in range(8):
                v = u + offsets[t]
                nd = d + weights[t]
                if open_[v] and nd < dist[v]:
                    old, dist[v] = dist[v], nd
                    later = int(nd * per_bucket)
                    if old == np.inf or int(old * per_bucket) != later:
                        ring[later & 3, sizes[later & 3]] = v
                        sizes[later & 3] += 1
                        pending += 1
        pending -= sizes[slot]
        sizes[slot] = 0
        bucket += 1
    return dist.reshape(nx + 2, py)[1:-1, 1:-1].copy()


@njit(cache=True)
def _goal_fractions(known, occupied, f, gi0, gi1, gj0, gj1, out):
    """``out[:, gi, gj]`` for the goal cells ``gi0 <= gi < gi1``, ``gj0 <= gj < gj1``: the
    fractions of their ``f`` × ``f`` nav cells that are known, free and occupied (counts over
    f², as the mean of a bool block: the same bits)."""
    for gi in range(gi0, gi1):
        for gj in range(gj0, gj1):
            n_known = n_free = n_occupied = 0
            for a in range(gi * f, gi * f + f):
                for b in range(gj * f, gj * f + f):
                    n_known += known[a, b]
                    n_occupied += occupied[a, b]
                    n_free += known[a, b] and not occupied[a, b]
            out[0, gi, gj] = n_known / (f * f)
            out[1, gi, gj] = n_free / (f * f)
            out[2, gi, gj] = n_occupied / (f * f)


def _nav_grid(goal_grid: GridSpec, cell_m: float, z_m: float) -> GridSpec:
    """The nav grid over goal_grid's x, y extent (one z layer at ``z_m``; only x, y matter)."""
    ratio = goal_grid.res / cell_m
    if abs(ratio - round(ratio)) > 1e-6 or ratio < 1:
        raise ConfigError(
            f"navigation cell_m {cell_m} must divide the goal grid's {goal_grid.res} m cells"
        )
    nx, ny = (round(s * ratio) for s in goal_grid.shape[:2])
    return GridSpec((goal_grid.origin[0], goal_grid.origin[1], z_m), cell_m, (nx, ny, 1))


def _grown(box, by: int, shape) -> tuple[int, int, int, int]:
    """The cell ranges ``box`` (i0, i1, j0, j1) grown by ``by`` cells, clipped to ``shape``."""
    return (max(box[0] - by, 0), min(box[1] + by, shape[0]),
            max(box[2] - by, 0), min(box[3] + by, shape[1]))  # fmt: skip


def _flat(grid: GridSpec) -> GridSpec:
    """``grid`` with one z layer."""
    return GridSpec(grid.origin, grid.res, (grid.shape[0], grid.shape[1], 1))


def _inner_cells(grid: GridSpec, margin_m: float) -> np.ndarray:
    """(nx, ny) bool: cells whose centre is at least ``margin_m`` inside the x, y extent."""
    axes = [grid.low[a] + (np.arange(grid.shape[a]) + 0.5) * grid.res for a in range(2)]
    ok = [(c - grid.low[a] >= margin_m - 1e-9) & (grid.high[a] - c >= margin_m - 1e-9)
          for a, c in enumerate(axes)]  # fmt: skip
    return ok[0][:, None] & ok[1][None, :]
