"""Which cells of G a scan from a candidate is predicted to observe: the four visibility models.

A sight line runs from a candidate T's sensor to the centre of a cell C of G. It is *clear* iff it
passes through the interior of no occluding cell other than C itself and the sensor's own cell
(docs/protocol.md#visibility: unknown space does not occlude; an occupied cell is seen — it is the surface we want to
see — but hides what is behind it). A segment that only touches a cell's edge or corner does not
pass through it. The models (:data:`VISIBILITY_MODELS`, docs/protocol.md#visibility) credit:

- ``authors`` (their code): every cell of the cube of ± sensor range around T (clipped to G) with a
  clear sight line, the sensor at the centre height of T's cell in G's lowest layer, no field of
  view, no range limit inside the cube;
- ``sphere``: every cell whose centre's range from a sensor at the lidar's height is in
  ``[min_range_m, sensor_range_m)`` with a clear sight line;
- ``fov``: as ``sphere``, restricted to sight lines whose elevation lies in the lidar's vertical
  field of view;
- ``physical``: what the statistics update (docs/protocol.md#viewpoint-statistics) would really touch: a clear sight line inside
  the field of view and the range window that *ends on a surface the map already knows* (a cell
  holding an occupied voxel, p ≥ ``NbvConfig.surface_probability`` = 0.5; such cells are also what
  blocks the lines, as a real ray stops at the first surface) credits that cell and every cell
  whose own range is in the window and that a ray to the cell crosses — the rays of a bundle
  (:data:`FAN`) to its centre and to eight points a quarter cell from it, since a real scan hits
  the surface all over its face (measured: with the centre line alone the realised gain was ≈ 2×
  the predicted one on pp1-cuboids, with the bundle ≈ 1×). A
  line ending in free or unknown space credits nothing: the lidar's ray would either return from
  the ground (below 0.2 m, ignored by the statistics) or from nowhere.

Every candidate's sensor stands at the centre (x, y) of a G column at the same height, so the cells a
sight line crosses depend only on the offset (dx, dy) of the target column and the target layer k:
the crossings are computed once per grid geometry (:func:`sight_lines`, cached) with an exact 3D
DDA, and stored inverted — for each relative cell, the sight lines that cross it. A candidate's
occluded sight lines are then the union of those of the occluding cells near it, which costs a few
operations per occluding cell instead of a ray walk per target cell. Under ``physical`` only the
lines that end on an occluding cell can credit anything, so that kernel
(:func:`credited_surface_rays`) visits just the occluding cells within reach, in sight-line
order, tests each one's line against the occluding cells it crosses, and reads the cells of G
padded by the reach (:class:`SurfaceTables`), so that no crossed cell needs a bounds check.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
from numba import njit

from nbv_gym.core import libm
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.statistics import StatisticsConfig
from nbv_gym.sensor.lidar import SENSOR_RANGE_M, LidarConfig

#: Crossings closer than this (in units of the segment's parameter t ∈ [0, 1]) are simultaneous.
_TIE = 1e-12

#: The end point of a sight line: its target cell's centre (cell units).
CENTRE = np.array([[0.5, 0.5, 0.5]])
#: The end points of a physical ray bundle: the centre and the eight points a quarter cell from
#: it along each diagonal — a real scan hits a surface cell all over its face, and the segments
#: from those hits to the sensor cross a thicker set of cells than one centre line.
FAN = np.vstack(
    [CENTRE, 0.5 + 0.25 * np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T]
)

#: The visibility models of gain prediction (module docstring), in the kernel's numbering.
VISIBILITY_MODELS: tuple[str, ...] = ("authors", "sphere", "fov", "physical")
_PHYSICAL = 3


@dataclass(frozen=True)
class SightModel:
    """The geometry of one visibility model: which sight lines a candidate has.

    Attributes:
        model: one of :data:`VISIBILITY_MODELS`.
        sensor_height_m: the sensor's height (map frame), metres (``authors``: G's lowest cell
            centre, set by :meth:`for_grid`).
        min_range_m, max_range_m: the range window ``[min, max)`` of a sight line, metres
            (``authors``: the cube's half-width is ``max_range_m`` and only the sensor's own
            cell is left out).
        elevation_min_rad, elevation_max_rad: the field of view (``fov`` and ``physical``);
            a sight line aims at its target iff its elevation lies in ``[min, max]``.

    The defaults are the benchmark's sensor (:class:`~nbv_gym.sensor.lidar.LidarConfig`, the
    statistics' range window); the simulator builds its model from its own configs
    (:meth:`nbv_gym.nbv.config.NbvConfig.sight_model`).
    """

    model: str = "physical"
    sensor_height_m: float = LidarConfig.mount_height_m
    min_range_m: float = StatisticsConfig.min_range_cells * StatisticsConfig.cell_m
    max_range_m: float = SENSOR_RANGE_M
    elevation_min_rad: float = LidarConfig.elevation_min_rad
    elevation_max_rad: float = LidarConfig.elevation_max_rad

    def __post_init__(self) -> None:
        if self.model not in VISIBILITY_MODELS:
            raise NbvGymError(
                f"visibility: expected one of {', '.join(VISIBILITY_MODELS)}, got {self.model!r}"
            )

    def for_grid(self, grid: GridSpec) -> SightModel:
        """This model on ``grid``: the ``authors`` sensor stands at G's lowest cell centre."""
        if self.model != "authors":
            return self
        return replace(self, sensor_height_m=float(grid.origin[2] + 0.5 * grid.res))

    @property
    def code(self) -> int:
        """The model's index in :data:`VISIBILITY_MODELS` (what the kernels read)."""
        return VISIBILITY_MODELS.index(self.model)


@dataclass(frozen=True)
class SightLines:
    """All sight lines from a sensor at a column centre to the cells within range.

    Ray ``r`` goes from the sensor (column offset (0, 0)) to the centre of the cell at column offset
    ``(dx[r], dy[r])`` and absolute layer ``k[r]``. Rays are sorted by ``dx``; those with offset
    ``dx`` are ``dx_start[dx + reach] : dx_start[dx + reach + 1]``.

    Attributes:
        reach: largest |dx|, |dy| of a ray, cells.
        dx, dy, k: (n,) int64 target cell offsets and layer.
        range_m: (n,) float64 distance sensor – target centre, metres.
        unit: (n, 3) float64 unit vector target centre → sensor, ``(T − C) / |T − C|``.
        azimuth: (n,) float64 ``atan2(T_y − C_y, T_x − C_x)`` in [0, 2π).
        aimed: (n,) bool the sight lines the lidar aims along (inside the model's field of view);
            the others are kept as cells a physical ray may cross.
        through_start, through_rays: CSR lists, per sight line, of the sight lines of the cells it
            crosses that lie in the range window (a physical ray credits them too).
        dx_start: (2 · reach + 2,) int64 first ray of each dx.
        crossing_start: (n_offsets + 1,) int64 CSR row starts over the relative cells
            ``((cdx + reach) · (2 · reach + 1) + cdy + reach) · nz + ck``.
        crossing_rays: int64 ids of the rays crossing each relative cell (strictly between the
            sensor's cell and the target cell).
        forward_start, forward_cells: CSR lists, per sight line, of the (dx, dy, k) relative
            cells it crosses (the same crossings, per line: (n_crossings, 3) int64).
        ray_of: (width · width · nz,) int64 the sight line of each relative cell, −1 where none
            (outside the range window).
    """

    reach: int
    nz: int
    dx: np.ndarray
    dy: np.ndarray
    k: np.ndarray
    range_m: np.ndarray
    unit: np.ndarray
    azimuth: np.ndarray
    aimed: np.ndarray
    through_start: np.ndarray
    through_rays: np.ndarray
    dx_start: np.ndarray
    crossing_start: np.ndarray
    crossing_rays: np.ndarray
    forward_start: np.ndarray
    forward_cells: np.ndarray
    ray_of: np.ndarray

    @property
    def n_rays(self) -> int:
        """Number of sight lines."""
        return len(self.dx)


def sight_lines(grid: GridSpec, model: SightModel) -> SightLines:
    """The sight lines of ``model`` (see :class:`SightModel`) from a sensor above a column centre
    of ``grid``. Cached per geometry."""
    model = model.for_grid(grid)
    return _sight_lines(
        float(grid.res), float(grid.origin[2]), int(grid.shape[2]), model.model == "authors",
        float(model.sensor_height_m), float(model.min_range_m), float(model.max_range_m),
        *((model.elevation_min_rad, model.elevation_max_rad) if model.code >= 2 else (-9.0, 9.0)),
        model.code == _PHYSICAL,
    )  # fmt: skip


@functools.lru_cache(maxsize=8)
def _sight_lines(
    res: float, z0: float, nz: int, cube: bool, sensor_height_m: float, min_range_m: float,
    max_range_m: float, elevation_min: float, elevation_max: float, fan: bool,
) -> SightLines:  # fmt: skip
    reach = max(
        int(math.floor(max_range_m / res + 1e-9) if cube else math.ceil(max_range_m / res)), 0
    )
    zs = (sensor_height_m - z0) / res
    dx, dy, k = (a.ravel() for a in np.meshgrid(
        np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), np.arange(nz), indexing="ij"
    ))  # fmt: skip
    to_sensor = np.column_stack([-dx, -dy, zs - (k + 0.5)]).astype(np.float64) * res
    range_m = np.linalg.norm(to_sensor, axis=1)
    if cube:
        keep = range_m > 1e-9
    else:
        keep = (range_m >= min_range_m) & (range_m < max_range_m)
    dx, dy, k, range_m, to_sensor = dx[keep], dy[keep], k[keep], range_m[keep], to_sensor[keep]
    if len(dx) == 0:
        raise NbvGymError(
            f"no cell of G lies within [{min_range_m}, {max_range_m}) m of a sensor at "
            f"{sensor_height_m} m; check NbvConfig.min_range_m and sensor_range_m"
        )
    unit = to_sensor / range_m[:, None]
    azimuth = np.mod(libm.arctan2(to_sensor[:, 1], to_sensor[:, 0]), 2.0 * np.pi)
    azimuth[azimuth >= 2.0 * np.pi] = 0.0
    elevation = libm.arcsin(np.clip(-unit[:, 2], -1.0, 1.0))  # of the line sensor → target
    aimed = (elevation >= elevation_min - 1e-12) & (elevation <= elevation_max + 1e-12)
    width = 2 * reach + 1
    offsets, rays = _all_crossings(dx, dy, k, zs, nz, reach, CENTRE)
    order = np.argsort(offsets, kind="stable")
    counts = np.bincount(offsets, minlength=width * width * nz)
    crossing_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    crossing_rays = rays[order].astype(np.int64)
    forward_start = np.concatenate([[0], np.cumsum(np.bincount(rays, minlength=len(dx)))])
    cell, ck = np.divmod(offsets, nz)  # rays ascend: the pairs are already per sight line
    cdx, cdy = np.divmod(cell, width)
    forward_cells = np.column_stack([cdx - reach, cdy - reach, ck]).astype(np.int64)
    dx_start = np.searchsorted(dx, np.arange(-reach, reach + 2)).astype(np.int64)
    ray_of = np.full(width * width * nz, -1, np.int64)
    ray_of[((dx + reach) * width + dy + reach) * nz + k] = np.arange(len(dx))
    if fan:
        offsets, rays = _all_crossings(dx, dy, k, zs, nz, reach, FAN)
    through_start, through_rays = _through_lists(offsets, rays, ray_of, len(dx))
    return SightLines(
        reach, nz, dx.astype(np.int64), dy.astype(np.int64), k.astype(np.int64), range_m, unit,
        azimuth, aimed, through_start, through_rays, dx_start, crossing_start, crossing_rays,
        forward_start.astype(np.int64), forward_cells, ray_of,
    )  # fmt: skip


def _through_lists(offsets, rays, ray_of, n_rays) -> tuple[np.ndarray, np.ndarray]:
    """CSR (start (n + 1,), rays) of the in-window sight lines of the cells each sight line
    crosses: a crossed relative cell is looked up among the sight lines' targets (``ray_of``)."""
    crossed = ray_of[offsets]
    keep = crossed >= 0
    pairs = np.unique(np.column_stack([rays[keep], crossed[keep]]), axis=0)  # sorted by ray
    counts = np.bincount(pairs[:, 0], minlength=n_rays)
    return np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), pairs[:, 1].copy()


def crossed_cells(dx: int, dy: int, k: int, zs: float) -> np.ndarray:
    """(m, 3) int64 cells (column offset dx, dy and absolute layer) whose interior the segment from
    the sensor at ``(0.5, 0.5, zs)`` (grid units, column (0, 0)) to the centre of cell
    ``(dx, dy, k)`` crosses, in order, the sensor's and the target's cells excluded."""
    out = np.empty((abs(dx) + abs(dy) + abs(k - int(math.floor(zs))) + 3, 3), np.int64)
    n = _crossings(dx, dy, k, zs, out)
    return out[:n].copy()


@njit(cache=True)
def _crossings(dx, dy, k, zs, out, ex=0.5, ey=0.5, ez=0.5) -> int:
    """Write the crossed cells of one sight line to ``out`` (see :func:`crossed_cells`); return how
    many. The line ends at ``(dx + ex, dy + ey, k + ez)``, a point of the target cell (its centre
    by default). Crossing parameters are computed from the boundary, not accumulated, so that
    exact ties (a segment through an edge or corner) are found exactly in x, y (both ends of a
    centre line are column centres)."""
    p0 = np.array([0.5, 0.5, zs])
    d = np.array([dx + ex, dy + ey, k + ez]) - p0
    cell = np.array([0, 0, int(math.floor(zs))])
    end = np.array([dx, dy, k])
    step = np.zeros(3, np.int64)
    boundary = np.zeros(3)
    t = np.full(3, np.inf)
    for a in range(3):
        if d[a] > 0.0:
            step[a] = 1
            boundary[a] = cell[a] + 1.0
        elif d[a] < 0.0:
            step[a] = -1
            boundary[a] = cell[a]
        if step[a] != 0:
            t[a] = (boundary[a] - p0[a]) / d[a]
    n = 0
    while True:
        t_min = min(t[0], min(t[1], t[2]))
        if t_min >= 1.0:
            return n
        for a in range(3):
            if t[a] <= t_min + _TIE:
                cell[a] += step[a]
                boundary[a] += step[a]
                t[a] = (boundary[a] - p0[a]) / d[a]
        at_end = cell[0] == end[0] and cell[1] == end[1] and cell[2] == end[2]
        if t_min > _TIE and not at_end:
            out[n, 0], out[n, 1], out[n, 2] = cell[0], cell[1], cell[2]
            n += 1


@njit(cache=True)
def _all_crossings(dx, dy, k, zs, nz, reach, ends):
    """(offset, ray) pairs of every in-grid (0 ≤ layer < nz) cell crossed by every sight line;
    a line is the union of the segments to its target cell's (e, 3) ``ends`` (points in cell
    units inside the cell, :data:`CENTRE` or :data:`FAN`)."""
    width = 2 * reach + 1
    longest = 2 * (2 * reach + 1) + nz + int(abs(zs)) + 4
    buffer = np.empty((longest, 3), np.int64)
    total = 0
    for r in range(len(dx)):
        for e in range(ends.shape[0]):
            total += _crossings(dx[r], dy[r], k[r], zs, buffer, ends[e, 0], ends[e, 1], ends[e, 2])
    offsets = np.empty(total, np.int64)
    rays = np.empty(total, np.int64)
    n = 0
    for r in range(len(dx)):
        for e in range(ends.shape[0]):
            m = _crossings(dx[r], dy[r], k[r], zs, buffer, ends[e, 0], ends[e, 1], ends[e, 2])
            for c in range(m):
                ck = buffer[c, 2]
                if 0 <= ck < nz:
                    offsets[n] = ((buffer[c, 0] + reach) * width + buffer[c, 1] + reach) * nz + ck
                    rays[n] = r
                    n += 1
    return offsets[:n], rays[:n]


@njit(cache=True)
def mark_occluded(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, stamps, stamp):
    """Set ``stamps[r] = stamp`` for every sight line ``r`` of the candidate column ``(ci, cj)``
    that crosses one of the (q, 3) int64 ``occluders`` cells."""
    width = 2 * reach + 1
    for q in range(occluders.shape[0]):
        a = occluders[q, 0] - ci
        b = occluders[q, 1] - cj
        if a < -reach or a > reach or b < -reach or b > reach:
            continue
        o = ((a + reach) * width + b + reach) * nz + occluders[q, 2]
        for p in range(crossing_start[o], crossing_start[o + 1]):
            stamps[crossing_rays[p]] = stamp


@njit(cache=True)
def credited_rays(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, dx_start, dy,
                  aimed, nx, ny, stamps, stamp, out):  # fmt: skip
    """Write to ``out`` the clear, aimed sight lines of the candidate column ``(ci, cj)`` — the
    cells it is credited with under ``authors``, ``sphere`` and ``fov`` (module docstring); return
    how many. ``stamps`` (n_rays,) int64 scratch holding no ``stamp`` yet (a new stamp per
    candidate)."""
    mark_occluded(ci, cj, occluders, reach, nz, crossing_start, crossing_rays, stamps, stamp)
    n = 0
    for a in range(max(-reach, -ci), min(reach, nx - 1 - ci) + 1):
        for r in range(dx_start[a + reach], dx_start[a + reach + 1]):
            j = cj + dy[r]
            if 0 <= j < ny and stamps[r] != stamp and aimed[r]:
                out[n] = r
                n += 1
    return n


class SurfaceTables(NamedTuple):
    """The ``physical`` kernel's view of one occlusion mask (:func:`surface_tables`), over G
    padded by the sight lines' reach R on each side in x and y, cells flat in C order.

    Attributes:
        reach: R, cells.
        stride: ny + 2R, the padded grid's y size.
        occluding: ((nx + 2R) · (ny + 2R) · nz,) bool, False in the padding.
        visits: same size, int64: −1 in G, the largest int64 in the padding (a crossed cell
            outside G counts as visited: never credited); read-only, kernels work on a copy.
        column_start: (nx · ny + 1,) int64 CSR of the occluding cells by column (i · ny + j).
        occluder_j, occluder_k: (q,) int64 the occluding cells' j and k, sorted by (i, j, k).
        forward_offsets: per crossing of :attr:`SightLines.forward_cells`, its padded offset.
        through_offsets: per entry of :attr:`SightLines.through_rays`, its target's padded offset.
        ray_of, aimed, forward_start, through_start, through_rays: the :class:`SightLines`'.
    """

    reach: int
    stride: int
    occluding: np.ndarray
    visits: np.ndarray
    column_start: np.ndarray
    occluder_j: np.ndarray
    occluder_k: np.ndarray
    forward_offsets: np.ndarray
    through_offsets: np.ndarray
    ray_of: np.ndarray
    aimed: np.ndarray
    forward_start: np.ndarray
    through_start: np.ndarray
    through_rays: np.ndarray


def surface_tables(grid: GridSpec, model: SightModel, occluding: np.ndarray) -> SurfaceTables:
    """The :class:`SurfaceTables` of the (nx, ny, nz) bool ``occluding`` cells of ``grid`` for
    ``model``'s sight lines (their padded offsets computed once per geometry)."""
    occluding = np.asarray(occluding, bool)
    nx, ny, nz = grid.shape
    lines = sight_lines(grid, model)
    reach = lines.reach
    stride, visits, forward_offsets, through_offsets = _padded_lines(grid, model)
    padded = np.zeros((nx + 2 * reach, stride, nz), bool)
    padded[reach : reach + nx, reach : reach + ny] = occluding
    cells = occluder_cells(occluding)
    columns = np.bincount(cells[:, 0] * ny + cells[:, 1], minlength=nx * ny)
    return SurfaceTables(
        reach, stride, padded.ravel(), visits,
        np.concatenate([[0], np.cumsum(columns)]).astype(np.int64),
        cells[:, 1].copy(), cells[:, 2].copy(), forward_offsets, through_offsets,
        lines.ray_of, lines.aimed, lines.forward_start, lines.through_start, lines.through_rays,
    )  # fmt: skip


@functools.lru_cache(maxsize=8)
def _padded_lines(
    grid: GridSpec, model: SightModel
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """The padded geometry of :class:`SurfaceTables` (read-only): stride, visits, forward and
    through offsets."""
    lines = sight_lines(grid, model)
    nx, ny, nz = grid.shape
    reach, stride = lines.reach, ny + 2 * lines.reach
    visits = np.full((nx + 2 * reach, stride, nz), np.iinfo(np.int64).max, np.int64)
    visits[reach : reach + nx, reach : reach + ny] = -1

    def offsets(dx: np.ndarray, dy: np.ndarray, k: np.ndarray) -> np.ndarray:
        return ((dx * stride + dy) * nz + k).astype(np.int64)

    forward, through = lines.forward_cells, lines.through_rays
    arrays = (
        visits.ravel(),
        offsets(forward[:, 0], forward[:, 1], forward[:, 2]),
        offsets(lines.dx[through], lines.dy[through], lines.k[through]),
    )
    for array in arrays:
        array.flags.writeable = False
    return (stride, *arrays)


@njit(cache=True)
def credited_surface_rays(ci, cj, tables, nx, ny, nz, visits, stamp, out):
    """Write to ``out`` the sight lines (one per cell, its first) of the cells the candidate
    column ``(ci, cj)`` is credited with under ``physical`` (module docstring); return how many.

    Visits the occluding cells within reach in sight-line order (by dx, dy, k), so the lines and
    their order are those of a pass over every sight line. ``tables`` is a
    :class:`SurfaceTables`; ``visits`` a copy of its :attr:`~SurfaceTables.visits`, holding no
    stamp ≥ ``stamp`` in G yet (stamps grow from candidate to candidate).
    """
    reach, stride, ray_of = tables.reach, tables.stride, tables.ray_of
    forward_start, through_start = tables.forward_start, tables.through_start
    width = 2 * reach + 1
    base = ((ci + reach) * stride + cj + reach) * nz  # the candidate's column in the padding
    j_lo, j_hi = max(cj - reach, 0), min(cj + reach, ny - 1)
    n = 0
    for i in range(max(ci - reach, 0), min(ci + reach, nx - 1) + 1):
        a = i - ci
        for o in range(tables.column_start[i * ny + j_lo], tables.column_start[i * ny + j_hi + 1]):
            b, ck = tables.occluder_j[o] - cj, tables.occluder_k[o]
            r = ray_of[((a + reach) * width + b + reach) * nz + ck]
            if r < 0 or not tables.aimed[r]:
                continue
            hidden = False
            for p in range(forward_start[r], forward_start[r + 1]):
                if tables.occluding[base + tables.forward_offsets[p]]:
                    hidden = True
                    break
            if hidden:
                continue
            cell = base + (a * stride + b) * nz + ck
            if visits[cell] < stamp:
                visits[cell] = stamp
                out[n] = r
                n += 1
            for p in range(through_start[r], through_start[r + 1]):
                crossed = base + tables.through_offsets[p]
                if visits[crossed] < stamp:
                    visits[crossed] = stamp
                    out[n] = tables.through_rays[p]
                    n += 1
    return n


def credited_cells(
    occluding: np.ndarray, column: tuple[int, int], grid: GridSpec, model: SightModel
) -> np.ndarray:
    """(nx, ny, nz) bool: the cells of ``grid`` a candidate at column ``(i, j)`` is credited
    with under ``model``, given the (nx, ny, nz) bool ``occluding`` cells."""
    lines = sight_lines(grid, model)
    occluding = np.asarray(occluding, bool)
    nx, ny, nz = grid.shape
    rays = np.empty(lines.n_rays, np.int64)
    ci, cj = int(column[0]), int(column[1])
    if model.code == _PHYSICAL:
        tables = surface_tables(grid, model, occluding)
        n = credited_surface_rays(ci, cj, tables, nx, ny, nz, tables.visits.copy(), 0, rays)
    else:
        n = credited_rays(
            ci, cj, occluder_cells(occluding), lines.reach, nz, lines.crossing_start,
            lines.crossing_rays, lines.dx_start, lines.dy, lines.aimed, nx, ny,
            np.full(lines.n_rays, -1, np.int64), 0, rays,
        )  # fmt: skip
    out = np.zeros(grid.shape, bool)
    rays = rays[:n]
    out[ci + lines.dx[rays], cj + lines.dy[rays], lines.k[rays]] = True
    return out


def occluder_cells(occluding: np.ndarray) -> np.ndarray:
    """(q, 3) int64 indices of the True cells of the (nx, ny, nz) bool ``occluding``."""
    return np.argwhere(np.asarray(occluding, bool)).astype(np.int64)
