"""The occupancy map's voxel store: float32 log-odds in which all-zero bits mean "unknown", kept
in memory whose pages the map never wrote are never resident.

A voxel is unknown iff its value is 0 (all bits zero); a known log-odds of exactly 0 is stored as
:data:`KNOWN_ZERO`, the smallest positive float32 (2⁻¹⁴⁹), which adds as 0 to any update and
compares like 0 with any threshold a configuration can give, so kernels test one float: known iff
``value != 0``, occupied iff ``value >= threshold and value != 0``.

So a fresh store is a zero-filled anonymous memory mapping whose pages the system maps on first
write, and forgetting voxels hands their pages back (``madvise(MADV_DONTNEED)`` on Linux;
elsewhere they are zero-filled). Writers flag the :data:`BLOCK`-value blocks (one page, one brick
of the map) they write; forgetting zeroes only those. The occupancy map zeroes an episode's
pages in place at a reset, keeping them mapped for the next episode, and hands back those of
the episode before that the last one did not write: only the pages of the volume the last two
episodes' scans reached are resident (each about an eighth of the default 147.5 MB map).

The price of a page not resident yet is a fault on its first write (~2 µs of CPU on a virtual
machine), which an episode pays only where the one before did not write.

Kernels read a voxel with :func:`is_known` and write a known value with :func:`stored`; numpy
readers convert whole arrays with :func:`decoded` (NaN = unknown) and :func:`encoded`.
"""

from __future__ import annotations

import mmap
import sys

import numpy as np
from numba import njit

#: The stored form of a known log-odds of exactly 0.
KNOWN_ZERO = np.float32(np.finfo(np.float32).smallest_subnormal)
#: Values per block (4 KiB: a page on x86-64), the unit in which writes are flagged and pages
#: are handed back.
BLOCK = 1024
#: Pages are returned to the system only where ``madvise`` zero-fills them (Linux).
_RELEASES_PAGES = sys.platform.startswith("linux") and hasattr(mmap, "MADV_DONTNEED")


@njit(cache=True, inline="always")
def is_known(value) -> bool:
    """Whether a stored voxel value holds a log-odds."""
    return value != 0.0


@njit(cache=True, inline="always")
def stored(logodds):
    """The stored form of a known float32 log-odds: :data:`KNOWN_ZERO` for 0, else itself."""
    return logodds if logodds != 0.0 else KNOWN_ZERO


def decoded(values: np.ndarray) -> np.ndarray:
    """float32 log-odds of stored ``values``: NaN where unknown, 0 for :data:`KNOWN_ZERO`."""
    out = np.where(values == KNOWN_ZERO, np.float32(0.0), values)
    out[values == 0] = np.nan
    return out


def encoded(logodds: np.ndarray) -> np.ndarray:
    """The stored form of float32 ``logodds`` (NaN = unknown)."""
    out = np.where(logodds == 0, KNOWN_ZERO, logodds).astype(np.float32)
    out[np.isnan(out)] = 0.0
    return out


class ZeroPages:
    """A flat float32 array of ``n`` zeros in an anonymous memory mapping: pages are resident
    from their first write until :meth:`zero` or :meth:`zero_blocks` hands them back.

    Attributes:
        array: (n,) float32, zero at first.
        n_blocks: number of :data:`BLOCK`-value blocks covering it.
    """

    def __init__(self, n: int):
        self.n_blocks = max(-(-n // BLOCK), 1)
        private = {"flags": mmap.MAP_PRIVATE} if hasattr(mmap, "MAP_PRIVATE") else {}  # not Windows
        self._buffer = mmap.mmap(-1, self.n_blocks * BLOCK * 4, **private)  # shared: not zeroed
        self._blocks = np.frombuffer(self._buffer, np.float32).reshape(self.n_blocks, BLOCK)
        self.array = self._blocks.reshape(-1)[:n]

    @property
    def blocks(self) -> np.ndarray:
        """(n_blocks, :data:`BLOCK`) float32 view of the whole mapping, block by block."""
        return self._blocks

    def zero_blocks(self, blocks: np.ndarray, resident: np.ndarray) -> None:
        """Zero the blocks flagged in the (n_blocks,) bool ``blocks`` (the others must be zero
        already): those also flagged in ``resident`` in place (their pages stay mapped, for writes
        expected soon), the others handed back to the system — in one call per run of blocks
        between kept ones, not per run of flagged blocks (the unflagged ones between are zero)."""
        flagged = np.flatnonzero(blocks)
        if not len(flagged):
            return
        lo, hi = int(flagged[0]), int(flagged[-1]) + 1  # work on the flagged span only
        blocks, resident, values = blocks[lo:hi], resident[lo:hi], self._blocks[lo:hi]
        keep = blocks & resident
        if not _RELEASES_PAGES:
            values[blocks] = 0.0
            return
        values[keep] = 0.0
        flagged = np.concatenate(([0], np.cumsum(blocks & ~resident)))
        change = np.diff(keep.view(np.int8), prepend=1, append=1)  # −1: a run starts; +1: ends
        first, end = np.flatnonzero(change < 0) + lo, np.flatnonzero(change > 0) + lo
        released = flagged[end - lo] > flagged[first - lo]
        if mmap.PAGESIZE != 4 * BLOCK:  # blocks are not pages: zero() rounds to whole pages
            for a, b in zip(first[released], end[released], strict=True):
                self.zero(int(a) * BLOCK, int(b) * BLOCK)
            return
        for offset, length in zip(first[released] * 4 * BLOCK, (end - first)[released] * 4 * BLOCK,
                                  strict=True):  # fmt: skip
            self._buffer.madvise(mmap.MADV_DONTNEED, int(offset), int(length))

    def zero(self, start: int, stop: int) -> None:
        """Zero ``array[start:stop]``, returning the whole pages inside it to the system."""
        page = mmap.PAGESIZE // 4
        first, last = -(-start // page) * page, stop // page * page
        if not (_RELEASES_PAGES and last > first):
            self._blocks.reshape(-1)[start:stop] = 0.0
            return
        flat = self._blocks.reshape(-1)
        flat[start:first] = 0.0
        flat[last:stop] = 0.0
        self._buffer.madvise(mmap.MADV_DONTNEED, first * 4, (last - first) * 4)

    def __getstate__(self) -> dict:
        """Pickle the nonzero values only (a mapping cannot be pickled)."""
        index = np.flatnonzero(self.array.view(np.uint32))
        return {"n": len(self.array), "index": index, "values": self.array[index]}

    def __setstate__(self, state: dict) -> None:
        ZeroPages.__init__(self, state["n"])
        self.array[state["index"]] = state["values"]
