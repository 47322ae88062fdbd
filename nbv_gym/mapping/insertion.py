"""The occupancy map's insertion kernel: one scan's voxel updates, applied in store order.

A scan updates each voxel at most once (docs/protocol.md#map): a hit where a return within range
lies, else a miss where a ray passes. Applying the updates in ray order makes each one a random
access over the ~2,000 store pages a scan reaches, missing the caches and the TLB. So the kernel
first *marks* what the rays cross in a per-scan bitset (:class:`MarkingWindow`) laid out like the
store's bricks, applies the hits (few), then *sweeps* the bitset brick by brick in store order,
applying one miss per remaining bit and zeroing the bitset as it goes. Every output — the voxels,
the brick flags, the touched cells, the change log's totals and the column counts — is the one
the same updates give in ray order: each voxel's update depends on that voxel alone, and the
totals are integer counts or exact sums (:mod:`nbv_gym.mapping.tally`).

A ray is walked as OctoMap's ``computeRayKeys`` walks it (Amanatides–Woo, ties to the later axis,
the endpoint's voxel excluded, an early stop where the walk overshoots the ray's length). The walk
counts the Manhattan distance to the endpoint's voxel instead of testing for it at every step;
the rare ray whose float walk does not land on that voxel by then carries on step by step with
the end test, so it marks exactly the voxels it marked before.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import cast

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.cpython.unsafe.numbers import trailing_zeros as _trailing_zeros
from numba.extending import intrinsic

from nbv_gym.mapping.store import BLOCK, is_known, stored
from nbv_gym.mapping.traversal import (
    BRICK,
    OUTSIDE,
    _advance,
    _axis_setup,
    _distance,
    axis_offsets,
)

#: Bits per bitset word, and words per brick (one bit per voxel of a :data:`BLOCK`-voxel brick).
_WORD = 64
_WORDS = BLOCK // _WORD
#: Voxels per store cache line (16 float32): 16 bits of a bitset word.
_LINE = 16


def _prefetch_intrinsic(typingctx, array, index):
    """Ask the CPU to fetch ``array[index]``'s cache line for writing (LLVM's ``prefetch``):
    no effect on any value, only on when the line arrives."""
    signature = types.void(array, index)

    def codegen(context, builder, sig, args):
        view = context.make_array(sig.args[0])(context, builder, args[0])
        address = cgutils.get_item_pointer(context, builder, sig.args[0], view, [args[1]])
        byte = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        function = builder.module.declare_intrinsic(
            "llvm.prefetch", [byte], ir.FunctionType(ir.VoidType(), [byte, i32, i32, i32])
        )
        # write, high temporal locality, data cache
        builder.call(function, [builder.bitcast(address, byte), i32(1), i32(3), i32(1)])
        return context.get_dummy_value()

    return signature, codegen


#: The intrinsics as the kernels call them: ``_prefetch(array, index)``, ``trailing_zeros(word)``
#: (numba's: the index of the lowest set bit).
_prefetch = cast(Callable[[np.ndarray, int], None], intrinsic(_prefetch_intrinsic))
trailing_zeros = cast(Callable[[np.uint64], int], _trailing_zeros)


class MarkingWindow:
    """The per-scan marking bitset: one bit per voxel of a box of whole store bricks around the
    sensor, laid out like the store (bricks in (z, x, y) order, and in each brick the store's
    order of its :data:`BLOCK` voxels), so that a sweep of the bitset walks the store in order.

    Only the voxels of the *window* are marked: a box of ``shape`` voxels holding every voxel
    within range of the sensor's, moved to lie inside the map, and cut to the map; a ray stops
    where it leaves the window. Its size follows the sensor range, not the map.

    Args:
        grid_shape: (nx, ny, nz) voxels of the map.
        max_range_voxels: sensor range in voxels.

    Attributes:
        shape: (3,) int64 voxels of the window along x, y, z.
        bricks: (3,) int64 store bricks of the bitset along x, y, z: the most the window
            overlaps (one more than it spans, as it need not start on a brick; at most the
            map's).
        words: uint64 bitset, 16 words a brick, all zero between scans.
        tables: per axis, int64 over the voxel indices −1 … n (entry ``i + 1``): voxel (i, j,
            k)'s bit is ``x[i + 1] + y[j + 1] + z[k + 1]``, negative outside the window.
    """

    def __init__(self, grid_shape: tuple[int, int, int], max_range_voxels: float):
        self.grid_shape = np.asarray(grid_shape, np.int64)
        self.shape = self.window_shape(grid_shape, max_range_voxels)
        self.map_bricks = np.array([-(-n // b) for n, b in zip(grid_shape, BRICK, strict=True)])
        self.bricks = np.array(self.brick_shape(grid_shape, max_range_voxels), np.int64)
        self.words = np.zeros(int(np.prod(self.bricks)) * _WORDS, np.uint64)
        self.tables = tuple(np.empty(n + 2, np.int64) for n in grid_shape)
        bx, by, bz = (int(n) for n in self.bricks)
        self._patterns = axis_offsets((bx, by, bz))  # the store's layout over the bitset's bricks
        self._clean = True

    @staticmethod
    def window_shape(grid_shape, max_range_voxels: float) -> np.ndarray:
        """(3,) int64 voxels of the window: a cube of side 2 · (⌈range⌉ + 1) + 1 rounded up to a
        multiple of 8, at most the map."""
        half = math.ceil(max_range_voxels) + 1
        size = np.minimum([2 * half + 1, 2 * half + 1, grid_shape[2]], grid_shape)
        return (-(-size // 8) * 8).astype(np.int64)

    @staticmethod
    def brick_shape(grid_shape, max_range_voxels: float) -> tuple[int, int, int]:
        """The most store bricks along x, y, z that the window overlaps (the store pages one scan
        can write): one more than it spans, as it need not start on a brick; at most the map's."""
        shape = MarkingWindow.window_shape(grid_shape, max_range_voxels)
        bricks = [min(-(-int(w) // b) + 1, -(-n // b))
                  for w, b, n in zip(shape, BRICK, grid_shape, strict=True)]  # fmt: skip
        return bricks[0], bricks[1], bricks[2]

    def box(self, origin_grid: np.ndarray) -> np.ndarray:
        """(3, 3) int64 rows: the low voxel, the extent inside the map and the shape of the
        window centred on the sensor at ``origin_grid`` (3,) float64 grid units."""
        shape = self.grid_shape
        low = np.floor(origin_grid).astype(np.int64) - self.shape // 2
        low = np.minimum(np.maximum(low, 0), np.maximum(shape - self.shape, 0))
        return np.stack([low, np.minimum(self.shape, shape - low), self.shape])

    def place(self, origin_grid: np.ndarray) -> np.ndarray:
        """Centre the window on the sensor at ``origin_grid`` (3,) float64 grid units: fill
        :attr:`tables`; returns the (8,) int64 layout the kernel reads: the bitset's first brick
        along x, y, z, its bricks along x, y, z, and the map's bricks along x, y."""
        low, limit, _ = self.box(origin_grid)
        first = np.minimum(low // np.array(BRICK), self.map_bricks - self.bricks)
        for table, pattern, start, count, offset in zip(
            self.tables, self._patterns, low, limit, low - first * np.array(BRICK), strict=True
        ):
            table.fill(OUTSIDE)
            table[start + 1 : start + 1 + count] = pattern[offset : offset + count]
        if not self._clean:  # a kernel call did not finish: the bitset may hold marks
            self.words[:] = 0
        return np.concatenate([first, self.bricks, self.map_bricks[:2]])

    def run(self, kernel, *args):
        """Call the insertion ``kernel`` with ``args``, noting whether it left the bitset clean."""
        self._clean = False
        result = kernel(*args)
        self._clean = True
        return result


@njit(cache=True)
def grid_points(points, low, res):
    """(m, 3) float64 ``(p − low) / res``, in grid units, of the rows ``p`` of the (n, 3)
    float64 ``points`` (metres) whose three coordinates are finite, in their order; ``low``
    (3,) float64 metres, ``res`` metres (one loop: numpy's row mask and broadcast over rows of
    three cost ~0.5 ms for a scan)."""
    out = np.empty((points.shape[0], 3))
    m = 0
    for r in range(points.shape[0]):
        x, y, z = points[r, 0], points[r, 1], points[r, 2]
        if math.isfinite(x) and math.isfinite(y) and math.isfinite(z):
            out[m, 0], out[m, 1], out[m, 2] = (
                (x - low[0]) / res,
                (y - low[1]) / res,
                (z - low[2]) / res,
            )
            m += 1
    return out[:m]


@njit(cache=True)
def insert_scan(
    store,
    offsets,
    origin,
    points,
    max_range,
    deltas,
    bounds,
    words,
    tables,
    layout,
    touched,
    cells,
    log,
    dirty,
    written,
    columns,
):
    """Insert one scan into the bricked log-odds store with OctoMap's ``insertPointCloud``
    semantics: every return within ``max_range`` gets a hit (once per voxel), then every voxel
    of every ray's free pass (the sensor's voxel included, the endpoint's excluded) not hit in
    this scan gets one miss; far returns carve up to ``max_range``. A pass stops where it leaves
    the marking window.

    Args:
        store: flat float32 bricked log-odds (:func:`~nbv_gym.mapping.traversal.axis_offsets`)
            in the store's encoding (:mod:`nbv_gym.mapping.store`: zero bits = unknown);
            updated in place.
        offsets: the (x, y, z) int64 tables of ``axis_offsets``: voxel (i, j, k) is
            ``store[x[i] + y[j] + z[k]]``.
        origin: (3,) float64 sensor position in grid units, inside the map.
        points: (n, 3) float64 finite returns in grid units.
        max_range: sensor range in grid units.
        deltas: (2,) float32 log-odds of a hit and of a miss; bounds: (2,) float32 clamping bounds.
        words: uint64 marking bitset (:attr:`MarkingWindow.words`), all zero on entry and on
            return.
        tables: the window's tables (:attr:`MarkingWindow.tables`); layout: the (8,) int64 of
            :meth:`MarkingWindow.place`.
        touched: flat bool over the coarse grid's cells; a cell is set when a voxel inside it
            changes value.
        cells: (3, max(nx, ny, nz)) int64 per voxel index along x, y, z (row 0, 1, 2) the
            contribution of its coarse cell index to the flat index (index × stride),
            :data:`~nbv_gym.mapping.traversal.OUTSIDE` outside the coarse grid.
        log: (cell, old, new, first_misses): the changes of voxels inside the coarse grid, one
            entry each while the (capacity,) arrays last: int32 flat coarse ``cell``, float32
            ``old`` (NaN when unknown) and ``new`` log-odds — except a voxel's first miss
            (unknown to the miss log-odds, most changes of a scan), counted per coarse cell in
            the (cells,) int32 ``first_misses`` instead (empty: log it too). Entries come in
            store order (hits first), not ray order.
        dirty: (bricks,) bool: set for each brick (block of the store) written; the voxels of a
            brick not set are all unknown (0).
        written: (bricks,) bool: also set for each brick written (``dirty`` itself, or a journal
            of the bricks this scan and others since its reset wrote).
        columns: :meth:`ColumnCounts.kernel_args <nbv_gym.mapping.columns.ColumnCounts>`: the
            per-column counts of known and occupied voxels in the navigation bands to keep up
            to date (``NO_COLUMNS``: empty bands, nothing counted).

    Returns:
        Number of voxels that received a hit, number of logged changes inside the coarse grid
        (more than the log's capacity when they did not all fit), number of voxels updated (a
        hit or a miss each).
    """
    hits, n_hits = _mark_hits(origin, points, max_range, words, tables)
    box = _mark_passes(origin, points, max_range, words, tables)
    for h in range(n_hits):  # an endpoint beats a free pass: its voxel gets no miss
        bit = hits[h, 3]
        words[bit >> 6] &= ~(np.uint64(1) << np.uint64(bit & 63))
    bricks = _marked_bricks(words, layout, box)
    n_changes, n_misses = _apply(store, offsets, deltas, bounds, words, bricks, hits, n_hits,
                                 touched, cells, log, dirty, written, columns)  # fmt: skip
    return n_hits, n_changes, n_hits + n_misses


@njit(cache=True)
def _mark_hits(origin, points, max_range, words, tables):
    """Mark the voxel of each return within range (in the map and the window) once; returns the
    (n, 4) int64 voxel index (i, j, k) and bit of each voxel marked, and their number."""
    x_mark, y_mark, z_mark = tables
    n_x, n_y, n_z = x_mark.shape[0] - 2, y_mark.shape[0] - 2, z_mark.shape[0] - 2
    hits = np.empty((points.shape[0], 4), np.int64)
    n_hits = 0
    for r in range(points.shape[0]):
        p = points[r]
        if not _distance(p, origin) <= max_range:
            continue
        cx, cy, cz = int(math.floor(p[0])), int(math.floor(p[1])), int(math.floor(p[2]))
        if not (0 <= cx < n_x and 0 <= cy < n_y and 0 <= cz < n_z):
            continue  # outside the map (the tables cover one voxel beyond it)
        bit = x_mark[cx + 1] + y_mark[cy + 1] + z_mark[cz + 1]
        if bit < 0:
            continue
        mask = np.uint64(1) << np.uint64(bit & 63)
        if words[bit >> 6] & mask:
            continue  # a second return in the voxel
        words[bit >> 6] |= mask
        hits[n_hits, 0], hits[n_hits, 1], hits[n_hits, 2], hits[n_hits, 3] = cx, cy, cz, bit
        n_hits += 1
    return hits, n_hits


@njit(cache=True)
def _mark_passes(origin, points, max_range, words, tables):  # noqa: C901 — a numba kernel
    """Mark the voxels of every ray's free pass (the sensor's voxel included, the endpoint's
    excluded; a far return's ray cut at ``max_range``); returns the (6,) int64 least and
    greatest voxel index along x, y, z that a walk reached (a box holding every mark)."""
    x_mark, y_mark, z_mark = tables
    one = np.uint64(1)
    ox, oy, oz = int(math.floor(origin[0])), int(math.floor(origin[1])), int(math.floor(origin[2]))
    box = np.array([ox, oy, oz, ox, oy, oz], np.int64)
    end = np.empty(3)
    for r in range(points.shape[0]):
        p = points[r]
        distance = _distance(p, origin)
        scale = 1.0 if distance <= max_range else max_range / distance
        for a in range(3):
            end[a] = origin[a] + (p[a] - origin[a]) * scale if scale < 1.0 else p[a]
        cx, cy, cz = ox, oy, oz
        ex, ey, ez = int(math.floor(end[0])), int(math.floor(end[1])), int(math.floor(end[2]))
        if cx == ex and cy == ey and cz == ez:
            continue
        dx, dy, dz = end[0] - origin[0], end[1] - origin[1], end[2] - origin[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        sx, tx, ddx = _axis_setup(origin[0], dx / length, cx)
        sy, ty, ddy = _axis_setup(origin[1], dy / length, cy)
        sz, tz, ddz = _axis_setup(origin[2], dz / length, cz)
        px, py, pz = x_mark[cx + 1], y_mark[cy + 1], z_mark[cz + 1]
        bit = px + py + pz
        if bit < 0:
            continue
        words[bit >> 6] |= one << np.uint64(bit & 63)
        # walk the Manhattan distance to the endpoint's voxel: a walk that gets there visits no
        # other voxel twice, nor that one before; one step is taken past each visited voxel
        steps, taken, stopped = abs(ex - cx) + abs(ey - cy) + abs(ez - cz), 0, False
        while True:
            if tx < ty:  # the axis OctoMap advances along: least t, ties to the later axis
                if tx < tz:
                    cx, tx = cx + sx, tx + ddx
                    px = x_mark[cx + 1]
                else:
                    cz, tz = cz + sz, tz + ddz
                    pz = z_mark[cz + 1]
            elif ty < tz:
                cy, ty = cy + sy, ty + ddy
                py = y_mark[cy + 1]
            else:
                cz, tz = cz + sz, tz + ddz
                pz = z_mark[cz + 1]
            taken += 1
            if taken == steps:
                break
            bit = px + py + pz
            if (tx > length and ty > length and tz > length) or bit < 0:
                stopped = True  # overshot the ray's length, or left the window
                break
            words[bit >> 6] |= one << np.uint64(bit & 63)
        while not (stopped or (cx == ex and cy == ey and cz == ez)):
            # a walk that veered off the endpoint's voxel: step by step as OctoMap does
            if min(tx, min(ty, tz)) > length:
                break
            bit = x_mark[cx + 1] + y_mark[cy + 1] + z_mark[cz + 1]
            if bit < 0:
                break
            words[bit >> 6] |= one << np.uint64(bit & 63)
            cx, cy, cz, tx, ty, tz = _advance(cx, cy, cz, tx, ty, tz, sx, sy, sz, ddx, ddy, ddz)
        # indices move one way along each axis: the last voxel reached bounds the walk
        box[0], box[1], box[2] = min(box[0], cx), min(box[1], cy), min(box[2], cz)
        box[3], box[4], box[5] = max(box[3], cx), max(box[4], cy), max(box[5], cz)
    return box


@njit(cache=True)
def _marked_bricks(words, layout, box):
    """The bricks of the bitset holding a mark, in store order, among those holding ``box``:
    (n, 5) int64 rows of the brick's index in the bitset, its first store value and its first
    voxel index along x, y, z."""
    fx, fy, fz, wbx, wby, wbz, mbx, mby = (layout[0], layout[1], layout[2], layout[3],
                                           layout[4], layout[5], layout[6], layout[7])  # fmt: skip
    x0, x1 = max((box[0] >> 4) - fx, 0), min((box[3] >> 4) - fx, wbx - 1)
    y0, y1 = max((box[1] >> 4) - fy, 0), min((box[4] >> 4) - fy, wby - 1)
    z0, z1 = max((box[2] >> 2) - fz, 0), min((box[5] >> 2) - fz, wbz - 1)
    bricks = np.empty((max(x1 - x0 + 1, 0) * max(y1 - y0 + 1, 0) * max(z1 - z0 + 1, 0), 5),
                      np.int64)  # fmt: skip
    n = 0
    for bz in range(z0, z1 + 1):
        for bx in range(x0, x1 + 1):
            for by in range(y0, y1 + 1):
                window = (bz * wbx + bx) * wby + by
                marked = np.uint64(0)
                for w in range(_WORDS):
                    marked |= words[window * _WORDS + w]
                if marked:
                    gx, gy, gz = bx + fx, by + fy, bz + fz
                    bricks[n, 0], bricks[n, 1] = window, ((gz * mbx + gx) * mby + gy) * BLOCK
                    bricks[n, 2], bricks[n, 3], bricks[n, 4] = gx * 16, gy * 16, gz * 4
                    n += 1
    return bricks[:n]


@njit(cache=True)
def _apply(store, offsets, deltas, bounds, words, bricks, hits, n_hits,  # noqa: C901 — a numba kernel: helpers taking arrays cost reference counting per call
           touched, cells, log, dirty, written, columns):  # fmt: skip
    """Apply the ``n_hits`` hits of ``hits`` (:func:`_mark_hits`), then one miss per bit of
    ``words`` in the ``bricks`` (:func:`_marked_bricks`), brick by brick in store order, zeroing
    the bitset; returns the number of logged changes (:func:`insert_scan`) and of misses.

    The voxel update is written once, in this loop: numba adds reference counting to every
    inlined helper that takes an array, which made the ray loop three times slower when it
    was such a helper (measured)."""
    x_offset, y_offset, z_offset = offsets
    col_x, col_y, layers, occupied_bound, known_count, occupied_count, col_changed = columns
    known_first, known_end = layers[0], layers[1]
    occupied_first, occupied_end = layers[2], layers[3]
    lo_min, lo_max = bounds[0], bounds[1]
    log_cell, log_old, log_new, first_misses = log
    counting_first = first_misses.shape[0] > 0
    n_bricks = bricks.shape[0]
    n_changes, n_misses, h, k, word, current = 0, 0, 0, -1, _WORDS - 1, np.uint64(0)
    at = ahead = base = ahead_base = vx = vy = vz = block = 0
    readable = wrote = False  # the block's voxels may be read; a voxel of it was written
    cz, z_cell, known_band, occupied_band = -1, OUTSIDE, False, False
    while True:
        if h < n_hits:
            if wrote:
                dirty[block] = written[block] = True
            cx, cy, z = hits[h, 0], hits[h, 1], hits[h, 2]
            i = x_offset[cx] + y_offset[cy] + z_offset[z]
            block = i >> 10
            readable, wrote = dirty[block], False
            hit = True
            h += 1
        else:
            z = cz
            while current == 0:  # the next mark, brick by brick in store order
                word += 1
                if word == _WORDS:
                    k, word = k + 1, 0
                    if wrote:
                        dirty[block] = written[block] = True
                    if k == n_bricks:
                        break
                    at, base = bricks[k, 0] * _WORDS, bricks[k, 1]
                    vx, vy, vz = bricks[k, 2], bricks[k, 3], bricks[k, 4]
                    block = base >> 10
                    readable, wrote = dirty[block], False
                    if k + 1 < n_bricks:
                        ahead, ahead_base = bricks[k + 1, 0] * _WORDS, bricks[k + 1, 1]
                    else:
                        ahead, ahead_base = at, base
                # ask for the lines the next brick's word will update (16 bits: one line)
                coming = words[ahead + word]
                if coming:
                    for line in range(_WORD // _LINE):
                        if (coming >> np.uint64(line * _LINE)) & np.uint64(0xFFFF):
                            _prefetch(store, ahead_base + word * _WORD + line * _LINE)
                current = words[at + word]
                if current:
                    words[at + word] = 0
                    z = vz + (word >> 2)  # a word: one z layer, one row of 4 × 16 voxels
            if k == n_bricks:
                break
            o = word * _WORD + trailing_zeros(current)
            current &= current - np.uint64(1)
            i = base + o  # the brick's voxel o (axis_offsets' bit fields)
            cx = vx + ((o >> 6) & 3) * 4 + ((o >> 2) & 3)
            cy = vy + ((o >> 4) & 3) * 4 + (o & 3)
            hit = False
            n_misses += 1
        if z != cz:  # what depends on the layer alone
            cz, z_cell = z, cells[2, z]
            known_band = known_first <= cz < known_end
            occupied_band = occupied_first <= cz < occupied_end
        delta = deltas[0] if hit else deltas[1]
        # unknown: 0, the log-odds a first update starts from; a brick not written since the
        # map was cleared is all unknown, and not reading it spares a page fault
        old = store[i] if readable else np.float32(0.0)
        known = is_known(old)
        new = min(max(old + delta, lo_min), lo_max)
        if not (known and new == old):
            store[i] = stored(new)
            wrote = True
            in_known = known_band and not known
            column = col_x[cx] + col_y[cy] if in_known or occupied_band else -1
            if column >= 0:  # the voxel counts in a navigation band of a grid column
                if in_known:
                    known_count[column] += 1
                    col_changed[column] = True
                if occupied_band:
                    was = known and old >= occupied_bound
                    now = stored(new) >= occupied_bound
                    if was != now:
                        occupied_count[column] += 1 if now else -1
                        col_changed[column] = True
            cell = cells[0, cx] + cells[1, cy] + z_cell
            if cell >= 0:  # inside the coarse grid
                if counting_first and not (known or hit):
                    if not first_misses[cell]:  # all zero on entry: its first this scan
                        touched[cell] = True
                    first_misses[cell] += 1
                else:
                    touched[cell] = True
                    if n_changes < log_cell.shape[0]:
                        log_cell[n_changes] = cell
                        log_old[n_changes] = old if known else np.float32(np.nan)
                        log_new[n_changes] = new
                    n_changes += 1
    return n_changes, n_misses
