"""Scans tried on a scratch copy of the exploration state's map and cell totals, then undone —
the source state is never written (a one-step look-ahead's evaluation).

The scratch map has its own store. :meth:`ScanTrial.restore` makes it equal to the source by
copying, from the source, every block either map has written (a block neither wrote is unknown
in both), and the cell totals: a copy of the written part of the map (an eighth of it after a
long episode), once per state of the source. :meth:`ScanTrial.undo` then undoes a trial by
copying back only the blocks its insertion wrote (the map's journal), so a trial costs about its
insertion.
"""

from __future__ import annotations

import copy

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.mapping.occupancy import OccupancyMap, ScanUpdate
from nbv_gym.mapping.state import ExplorationState
from nbv_gym.mapping.tally import CellTally


class ScanTrial:
    """A scratch copy of ``state``'s occupancy map and cell totals (``state`` must keep cell
    totals: built with an unobserved band).

    Attributes:
        map: the scratch :class:`OccupancyMap` (equal to the source's after :meth:`restore`).
        tally: the scratch :class:`~nbv_gym.mapping.tally.CellTally`.
    """

    def __init__(self, state: ExplorationState):
        if state.tally is None:
            raise NbvGymError("a scan trial needs a state that keeps cell totals")
        self.source = state
        source = state.occupancy
        self.map = OccupancyMap(source.grid, **source.params)
        self.tally: CellTally = copy.deepcopy(state.tally)
        self.region = state.statistics.grid

    def restore(self) -> None:
        """Make the scratch map and totals equal to the source's now (before the first trial
        on a state of the source)."""
        source = self.source.occupancy
        self.map.take_journal()
        self.map.copy_blocks(source, source.written_blocks() | self.map.written_blocks())
        self._restore_totals()

    def undo(self) -> None:
        """Undo the trials since the last :meth:`restore` or :meth:`undo` (the source unchanged
        since that restore): copy back the blocks they wrote, and the cell totals."""
        self.map.copy_blocks(self.source.occupancy, self.map.take_journal())
        self._restore_totals()

    def _restore_totals(self) -> None:
        for name in ("sums", "outside", "crossed"):
            np.copyto(getattr(self.tally, name), getattr(self.source.tally, name))

    def insert(self, origin: FloatArray, points: FloatArray) -> ScanUpdate:
        """Insert a scan into the scratch map and totals (as :meth:`ExplorationState.apply`
        inserts it into the source's); ``touched`` is over G."""
        return self.map.insert(origin, points, self.region, self.tally)
