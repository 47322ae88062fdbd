"""Predicted viewpoint gains of candidate goals (docs/protocol.md#visibility, paper §III-C, the authors' code).

For a candidate goal T, every cell C of G that T is credited with under the config's visibility
model (:mod:`nbv_gym.nbv.visibility`) is predicted to receive one more observation from T; the
gain of a cell compares its statistic now (b) with the predicted one (â), with the floor f (1e-3):

- n_obs: ``ln(â / max(b, f))`` with ``â = b + 1`` — a first observation gains ``ln(1 / f)``.
- r_min: ``b − â`` if ``â < b`` else 0, with ``b`` = ``unobserved_r_min_m`` (100 m) for a
  never-observed cell and ``â = min(b, |T − C|)``.
- n_Ω: ``ln(â / max(b, f))`` if ``â > b`` else 0, where ``â`` counts the sectors after adding the
  sector of T and every sector swept between the robot's position R and T, seen from C: the
  azimuths ``atan2(R_y − C_y, R_x − C_x)`` and ``atan2(T_y − C_y, T_x − C_x)`` are joined along the
  shorter arc and every sector that arc passes through is set, both ends included (the authors'
  ``getAngularSectorsForVoxFromCandidate``). When the two azimuths are exactly π apart the arc runs
  counter-clockwise from R to T (the authors' code picks a side at random). When R lies on C's
  vertical axis (its azimuth is undefined) only T's sector is set.
- σ_θ: ``ln(max(â, f) / max(b, f))`` if ``â > b`` else 0, where ``â`` is the spherical variance
  after adding ``u = (T − C) / |T − C|`` to Σu and 1 to n_obs (so a first observation gains 0;
  under the ``authors`` model, as in their code, a first observation's â is shifted to 0.5 and
  gains ``ln(0.5 / f)``).

:func:`realised_gains` evaluates the same per-cell formulas on the statistics before and after a
real scan, so a prediction can be checked against what the scan achieved.

E[I(a_T)] of a statistic is the sum of its cell gains over the visible cells (``aggregate="sum"``,
authors' code) or their mean (``"mean"``, the paper; 0 when nothing is visible).

All four layers come from one pass over the sight lines of each candidate, so asking for all four
costs little more than asking for one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from nbv_gym.core import libm
from nbv_gym.core.arrays import BoolArray, FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.grid import GridSpec
from nbv_gym.mapping.statistics import ViewpointStatistics, spherical_variance
from nbv_gym.nbv.config import NbvConfig, NbvSensor
from nbv_gym.nbv.visibility import (
    credited_rays,
    credited_surface_rays,
    occluder_cells,
    sight_lines,
    surface_tables,
)

#: The gain layers, in the order of the kernel's output columns.
GAIN_LAYERS: tuple[str, ...] = ("gain_nobs", "gain_rmin", "gain_nomega", "gain_sigma")

# Columns of the per-cell table (:func:`cell_table`) the kernel reads.
_NOBS_GAIN, _RMIN, _SUM_U, _N_NEXT, _SIGMA, _LN_SIGMA, _NOMEGA, _LN_NOMEGA, _SECTORS = (
    0, 1, 2, 5, 6, 7, 8, 9, 10,
)  # fmt: skip
_N_COLUMNS = 11


def candidate_mask(
    goal_mask: BoolArray, robot_xy: FloatArray, goal_centres_xy: FloatArray, search_range_m: float
) -> np.ndarray:
    """(n_goals,) bool: the valid goals (``goal_mask``, (n_goals,) bool) whose centre
    (``goal_centres_xy``, (n_goals, 2) float metres) lies within ``search_range_m`` (≤) of
    ``robot_xy`` (2,) metres."""
    goal_mask = np.asarray(goal_mask, bool).ravel()
    centres = np.asarray(goal_centres_xy, float).reshape(-1, 2)
    if len(centres) != len(goal_mask):
        raise NbvGymError(
            f"goal_mask has {len(goal_mask)} goals but goal_centres_xy has {len(centres)} rows"
        )
    offset = centres - np.asarray(robot_xy, float).reshape(1, 2)
    return goal_mask & (np.hypot(offset[:, 0], offset[:, 1]) <= search_range_m)


def goal_centres_xy(grid: GridSpec) -> np.ndarray:
    """(nx · ny, 2) float64 centres of ``grid``'s x, y cells (goal order)."""
    return grid.xy_centres()


def predict_gains(
    statistics: ViewpointStatistics,
    occluding: BoolArray,
    robot_xy: FloatArray,
    candidates: BoolArray,
    config: NbvConfig,
    layers: Sequence[str] = GAIN_LAYERS,
    sensor: NbvSensor | None = None,
) -> dict[str, np.ndarray]:
    """The gain layers of the candidates, read from ``statistics`` (see :func:`predict_gains_arrays`
    for the arguments)."""
    return predict_gains_arrays(
        statistics.grid,
        statistics.n_obs,
        statistics.r_min,
        statistics.sector_mask,
        statistics.sum_u,
        occluding,
        robot_xy,
        candidates,
        config,
        layers,
        sensor,
    )


def predict_gains_arrays(
    grid: GridSpec,
    n_obs: np.ndarray,
    r_min: np.ndarray,
    sector_mask: np.ndarray,
    sum_u: np.ndarray,
    occluding: BoolArray,
    robot_xy: FloatArray,
    candidates: BoolArray,
    config: NbvConfig,
    layers: Sequence[str] = GAIN_LAYERS,
    sensor: NbvSensor | None = None,
) -> dict[str, np.ndarray]:
    """Predicted gain E[I(a_T)] of every candidate goal, one (nx, ny) layer per statistic.

    Args:
        grid: the statistics grid G (its x, y cells are the goals).
        n_obs: (nx, ny, nz) int observations per cell.
        r_min: (nx, ny, nz) float smallest observation range, metres; NaN (or +inf) where never
            observed.
        sector_mask: (nx, ny, nz) uint32 azimuth sectors observed from (bit s = sector s).
        sum_u: (nx, ny, nz, 3) float sum of the unit vectors cell centre → sensor.
        occluding: (nx, ny, nz) bool cells that occlude (hold a voxel with p ≥ 0.8).
        robot_xy: (2,) float the robot's position R, metres.
        candidates: (nx · ny,) or (nx, ny) bool candidate goals (row-major index i · ny + j).
        config: the NBV config (visibility model, floors, aggregate).
        layers: which of :data:`GAIN_LAYERS` to compute.
        sensor: the sensor predicted for (ranges, height, field of view, sectors); default
            :meth:`NbvSensor.default`.

    Returns:
        For each requested layer name, an (nx, ny) float32 array indexed ``[i, j]`` = goal
        ``i · ny + j``, zero outside the candidates.
    """
    unknown = [name for name in layers if name not in GAIN_LAYERS]
    if unknown:
        raise NbvGymError(f"unknown gain layer(s) {unknown}; valid: {', '.join(GAIN_LAYERS)}")
    nx, ny, nz = grid.shape
    _checked(n_obs, grid.shape, "n_obs")
    candidates = _candidate_cells(candidates, nx, ny)
    sensor = sensor or NbvSensor.default()
    table = cell_table(n_obs, r_min, sector_mask, sum_u, config, sensor)
    robot_azimuth, robot_on_axis = _robot_azimuths(grid, robot_xy)
    model = config.sight_model(sensor)
    lines = sight_lines(grid, model)
    occluding = np.asarray(_checked(occluding, grid.shape, "occluding"), bool)
    wanted = np.array([name in layers for name in GAIN_LAYERS])
    sums, n_visible = _gains_kernel(
        candidates, model.model == "physical", occluder_cells(occluding),
        surface_tables(grid, model, occluding), lines.reach, nz, lines.crossing_start,
        lines.crossing_rays, lines.dx_start, lines.dx, lines.dy, lines.k, lines.range_m,
        lines.unit, lines.azimuth, lines.aimed, nx, ny, table, robot_azimuth, robot_on_axis,
        sensor.n_sectors, _log_floor_table(config.gain_floor), config.gain_floor,
        _first_sigma(config), wanted,
    )  # fmt: skip
    if config.aggregate == "mean":
        sums = sums / np.maximum(n_visible, 1)[:, None]
    out = {}
    for column, name in enumerate(GAIN_LAYERS):
        if name in layers:
            layer = np.zeros((nx, ny), np.float32)
            layer[candidates[:, 0], candidates[:, 1]] = sums[:, column]
            out[name] = layer
    return out


def realised_gains(
    before: tuple[np.ndarray, ...],
    after: tuple[np.ndarray, ...],
    config: NbvConfig,
    sensor: NbvSensor | None = None,
) -> dict[str, float]:
    """The gain a real scan achieved, per statistic: the per-cell formulas of the prediction
    applied to the statistics before and after it, aggregated like the prediction.

    ``before`` and ``after`` are ``(n_obs, r_min, sector_mask, sum_u)`` as in :func:`cell_table`.
    Keys are :data:`GAIN_LAYERS`. With ``aggregate="mean"`` the sum is divided by the number of
    cells whose n_obs grew.
    """
    sensor = sensor or NbvSensor.default()
    (n0, r0, s0, u0), (n1, r1, s1, u1) = before, after
    b, a = cell_table(n0, r0, s0, u0, config, sensor), cell_table(n1, r1, s1, u1, config, sensor)
    floor = config.gain_floor
    n_b, n_a = b[:, _N_NEXT] - 1.0, a[:, _N_NEXT] - 1.0
    grew = n_a > n_b
    gains = {
        "gain_nobs": libm.log(n_a[grew] / np.maximum(n_b[grew], floor)).sum(),
        "gain_rmin": np.maximum(b[:, _RMIN] - a[:, _RMIN], 0.0).sum(),
        "gain_nomega": _log_growth(b[:, _NOMEGA], a[:, _NOMEGA], floor),
        "gain_sigma": _log_growth(b[:, _SIGMA], a[:, _SIGMA], floor),
    }
    scale = 1.0 / max(int(grew.sum()), 1) if config.aggregate == "mean" else 1.0
    return {name: float(value * scale) for name, value in gains.items()}


def _log_growth(before: np.ndarray, after: np.ndarray, floor: float) -> float:
    """Σ ``ln(max(a, f) / max(b, f))`` over the cells where the value grew (a > b)."""
    grew = after > before
    return float(
        (libm.log(np.maximum(after[grew], floor)) - libm.log(np.maximum(before[grew], floor))).sum()
    )


def cell_table(
    n_obs: np.ndarray,
    r_min: np.ndarray,
    sector_mask: np.ndarray,
    sum_u: np.ndarray,
    config: NbvConfig,
    sensor: NbvSensor,
) -> np.ndarray:
    """(nx · ny · nz, 11) float64 per-cell values the kernel reads (candidate-independent parts of
    the gains, computed once per decision): n_obs gain, r_min (``unobserved_r_min_m`` if never
    observed), Σu, n_obs + 1, σ_θ, ln max(σ_θ, f), n_Ω, ln max(n_Ω, f), sector bitmask."""
    shape = np.shape(n_obs)
    n = np.asarray(n_obs, np.float64)
    if np.any(n < 0):
        raise NbvGymError("n_obs must be ≥ 0")
    r = np.asarray(r_min, np.float64)
    observed_r = (n > 0) & np.isfinite(r)
    mask = np.asarray(sector_mask, np.uint32)
    _checked(r, shape, "r_min")
    _checked(mask, shape, "sector_mask")
    sum_u = _checked(np.asarray(sum_u, np.float64), (*shape, 3), "sum_u")
    floor = config.gain_floor
    sigma = spherical_variance(sum_u, np.asarray(n_obs))
    mask = mask & np.uint32((1 << sensor.n_sectors) - 1)
    n_omega = _popcount(mask)
    table = np.empty((*shape, _N_COLUMNS))
    table[..., _NOBS_GAIN] = libm.log((n + 1.0) / np.maximum(n, floor))  # â = b + 1
    table[..., _RMIN] = np.where(
        observed_r, np.minimum(np.where(observed_r, r, 0.0), config.unobserved_r_min_m),
        config.unobserved_r_min_m,
    )  # fmt: skip
    table[..., _SUM_U : _SUM_U + 3] = sum_u
    table[..., _N_NEXT] = n + 1.0
    table[..., _SIGMA] = sigma
    table[..., _LN_SIGMA] = libm.log(np.maximum(sigma, floor))
    table[..., _NOMEGA] = n_omega
    table[..., _LN_NOMEGA] = libm.log(np.maximum(n_omega, floor))
    table[..., _SECTORS] = mask
    return table.reshape(-1, _N_COLUMNS)


def swept_sectors(
    robot_xy: FloatArray, target_xy: FloatArray, cell_xy: FloatArray, n_sectors: int = 32
) -> int:
    """uint32 bitmask of the sectors, seen from the cell centre ``cell_xy`` (2,) metres, swept from
    ``robot_xy`` to ``target_xy`` along the shorter arc, both ends included (module docstring)."""
    cx, cy = (float(v) for v in np.asarray(cell_xy, float).reshape(2))
    tx, ty = (float(v) for v in np.asarray(target_xy, float).reshape(2))
    rx, ry = (float(v) for v in np.asarray(robot_xy, float).reshape(2))
    target = _azimuth(ty - cy, tx - cx)
    on_axis = math.hypot(rx - cx, ry - cy) < 1e-9
    return int(_sweep(_azimuth(ry - cy, rx - cx), target, on_axis, n_sectors))


# ---------------------------------------------------------------------- helpers


def _azimuth(y: float, x: float) -> float:
    """``atan2(y, x)`` mapped to [0, 2π)."""
    theta = math.atan2(y, x)
    if theta < 0.0:
        theta += 2.0 * math.pi
    return 0.0 if theta >= 2.0 * math.pi else theta


def _candidate_cells(candidates: BoolArray, nx: int, ny: int) -> np.ndarray:
    """(m, 2) int64 column indices of the candidate goals."""
    candidates = np.asarray(candidates, bool)
    if candidates.size != nx * ny:
        raise NbvGymError(
            f"candidates must have one entry per goal ({nx} × {ny} = {nx * ny}), "
            f"got shape {candidates.shape}"
        )
    flat = np.flatnonzero(candidates.ravel())
    return np.column_stack([flat // ny, flat % ny]).astype(np.int64)


def _robot_azimuths(grid: GridSpec, robot_xy: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """(nx, ny) float64 azimuth of R seen from each column centre in [0, 2π), and (nx, ny) bool
    whether R lies on the column's axis."""
    robot = np.asarray(robot_xy, np.float64).reshape(2)
    if not np.isfinite(robot).all():
        raise NbvGymError(f"robot_xy must be finite, got {robot.tolist()}")
    centres = goal_centres_xy(grid).reshape(*grid.shape[:2], 2)
    offset = robot - centres
    azimuth = np.mod(libm.arctan2(offset[..., 1], offset[..., 0]), 2.0 * np.pi)
    azimuth[azimuth >= 2.0 * np.pi] = 0.0
    return azimuth, np.hypot(offset[..., 0], offset[..., 1]) < 1e-9


def _first_sigma(config: NbvConfig) -> float:
    """σ_θ predicted after a first observation: 0, or 0.5 under the ``authors`` model."""
    return 0.5 if config.visibility == "authors" else 0.0


def _log_floor_table(floor: float) -> np.ndarray:
    """(33,) float64 ``ln(max(a, f))`` for a = 0 … 32 sectors."""
    return libm.log(np.maximum(np.arange(33, dtype=np.float64), floor))


def _popcount(mask: np.ndarray) -> np.ndarray:
    """int64 number of set bits of each uint32."""
    bits = np.unpackbits(np.ascontiguousarray(mask, dtype="<u4").view(np.uint8))
    return bits.reshape(*mask.shape, 32).sum(axis=-1, dtype=np.int64)


def _checked(array: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    array = np.asarray(array)
    if array.shape != tuple(shape):
        raise NbvGymError(f"{name} must have shape {tuple(shape)}, got {array.shape}")
    return array


# ---------------------------------------------------------------------- compiled kernels


@njit(cache=True, inline="always")
def _sector(azimuth, n_sectors):
    """Sector index of an azimuth in [0, 2π), as the statistics update computes it."""
    return min(int(math.floor(azimuth * n_sectors / (2.0 * math.pi))), n_sectors - 1)


@njit(cache=True, inline="always")
def _run(a, b):
    """int64 bits a … b (a ≤ b)."""
    return ((np.int64(1) << (b + 1)) - 1) ^ ((np.int64(1) << a) - 1)


@njit(cache=True)
def _sweep(robot_azimuth, target_azimuth, robot_on_axis, n_sectors):
    """int64 bitmask of the sectors on the shorter arc from the robot's to the target's azimuth,
    both ends included; only the target's sector when the robot is on the cell's axis."""
    s_target = _sector(target_azimuth, n_sectors)
    if robot_on_axis:
        return np.int64(1) << s_target
    d = target_azimuth - robot_azimuth
    if d > math.pi:
        d -= 2.0 * math.pi
    elif d <= -math.pi:
        d += 2.0 * math.pi
    s_robot = _sector(robot_azimuth, n_sectors)
    a, b = (s_robot, s_target) if d >= 0.0 else (s_target, s_robot)
    if a <= b:
        return _run(a, b)
    return _run(a, n_sectors - 1) | _run(0, b)


@njit(cache=True, inline="always")
def _popcount64(v):
    v = v - ((v >> 1) & 0x5555555555555555)
    v = (v & 0x3333333333333333) + ((v >> 2) & 0x3333333333333333)
    v = (v + (v >> 4)) & 0x0F0F0F0F0F0F0F0F
    return (v * 0x0101010101010101) >> 56 & 0xFF


@njit(cache=True)
def _gains_kernel(  # noqa: C901 — a numba kernel: helpers taking arrays cost reference counting per call
    candidates, physical, occluders, surface, reach, nz, crossing_start, crossing_rays,
    dx_start, dx, dy, k, range_m, unit, azimuth, aimed, nx, ny, table, robot_azimuth,
    robot_on_axis, n_sectors, ln_count, floor, first_sigma, wanted,
):  # fmt: skip
    """(m, 4) float64 summed gains per candidate (columns as :data:`GAIN_LAYERS`) and (m,) int64
    number of credited cells."""
    m = candidates.shape[0]
    sums = np.zeros((m, 4))
    n_visible = np.zeros(m, np.int64)
    stamps = np.full(len(dx), -1, np.int64)
    visits = surface.visits.copy()
    rays = np.empty(len(dx), np.int64)
    want_nobs, want_rmin, want_nomega, want_sigma = wanted[0], wanted[1], wanted[2], wanted[3]
    # σ_θ's gain of a first observation: â = first_sigma (0, authors 0.5)
    first_gain = math.log(first_sigma / floor) if first_sigma > floor else 0.0
    for c in range(m):
        ci, cj = candidates[c, 0], candidates[c, 1]
        if physical:
            n = credited_surface_rays(ci, cj, surface, nx, ny, nz, visits, c, rays)
        else:
            n = credited_rays(ci, cj, occluders, reach, nz, crossing_start, crossing_rays,
                              dx_start, dy, aimed, nx, ny, stamps, c, rays)  # fmt: skip
        g_nobs = g_rmin = g_nomega = g_sigma = 0.0
        for q in range(n):
            r = rays[q]
            i, j = ci + dx[r], cj + dy[r]
            cell = (i * ny + j) * nz + k[r]
            if want_nobs:
                g_nobs += table[cell, _NOBS_GAIN]
            if want_rmin:
                b = table[cell, _RMIN]
                if range_m[r] < b:
                    g_rmin += b - range_m[r]
            if want_nomega:
                sweep = _sweep(robot_azimuth[i, j], azimuth[r], robot_on_axis[i, j], n_sectors)
                n_after = _popcount64(np.int64(table[cell, _SECTORS]) | sweep)
                if n_after > table[cell, _NOMEGA]:
                    g_nomega += ln_count[n_after] - table[cell, _LN_NOMEGA]
            if want_sigma and table[cell, _N_NEXT] < 1.5:
                g_sigma += first_gain  # a first observation
            elif want_sigma:  # written out: an array-taking helper costs numba refcounting
                sx = table[cell, _SUM_U] + unit[r, 0]
                sy = table[cell, _SUM_U + 1] + unit[r, 1]
                sz = table[cell, _SUM_U + 2] + unit[r, 2]
                s_after = 1.0 - math.sqrt(sx * sx + sy * sy + sz * sz) / table[cell, _N_NEXT]
                s_after = min(max(s_after, 0.0), 1.0)
                if s_after > table[cell, _SIGMA]:
                    g_sigma += math.log(max(s_after, floor)) - table[cell, _LN_SIGMA]
        sums[c, 0], sums[c, 1], sums[c, 2], sums[c, 3] = g_nobs, g_rmin, g_nomega, g_sigma
        n_visible[c] = n
    return sums, n_visible
