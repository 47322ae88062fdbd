"""One scorecard on a leaderboard (:class:`Entry`), the splits a board shows and the order it
ranks entries in: by the first of :data:`RANK_SPLITS` a scorecard has, oracles apart."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from nbv_gym.benchmark.suites import HEADLINE_SPLIT, SUITES

#: The splits whose score ranks the table, the first a scorecard has: the time task's test split,
#: else (a suite on your own worlds, ``nbv-gym score --world``, has no test split) the time task
#: on its worlds.
RANK_SPLITS = (HEADLINE_SPLIT, "time-benchmark")
#: The splits shown, in order (the scores table's columns, the profile figure's panels), with
#: the label of their score and what it charges.
SPLITS = {
    "time-test": "area under Q(t) / budget, test split (equal robot time)",
    "time-shift": "area under Q(t) / budget, shift split (equal robot time)",
    "time-benchmark": "area under Q(t) / budget, benchmark worlds (equal robot time)",
    "test": "Q after the scans, test split (equal scans, travel free)",
    "benchmark": "Q after the scans, benchmark worlds (equal scans, travel free)",
    "explore": "Q_paper at 70 % discovered (the paper's protocol)",
}
#: Short column titles of :data:`SPLITS`.
SPLIT_COLUMNS = {
    "time-test": "equal time, test: IQM area under Q(t)",
    "time-shift": "equal time, shift: IQM area under Q(t)",
    "time-benchmark": "equal time, benchmark: IQM area under Q(t)",
    "test": "equal scans (travel free), test: IQM Q",
    "benchmark": "equal scans (travel free), benchmark: IQM Q",
    "explore": "paper's protocol: IQM Q_paper@70 %",
}


@dataclass(frozen=True)
class Entry:
    """One scorecard on the board: its ``label``, the ``card`` and where it came from
    (``source``: a path, or ``"references"``)."""

    label: str
    card: dict[str, Any]
    source: str

    @property
    def reference(self) -> bool:
        """Whether the entry is a shipped reference scorecard."""
        return self.source == "references"

    @property
    def oracle(self) -> bool:
        """Whether the entry's policy reads privileged values (an oracle, ranked apart)."""
        return bool(self.card["policy"]["oracle"])

    @property
    def rank_split(self) -> str:
        """The split that ranks the entry: the first of :data:`RANK_SPLITS` its card has."""
        return rank_split(self.card)

    def aggregates(self, split: str | None = None) -> dict[str, Any]:
        """The aggregates of ``split`` (default: :attr:`rank_split`; {} if missing)."""
        return self.card["aggregates"].get(split or self.rank_split, {})

    def metric(self, split: str | None = None) -> str:
        """The score of ``split`` (its aggregates' ``metric``; ``q`` if the split is missing)."""
        return self.aggregates(split).get("metric", "q")

    def effort(self, split: str | None = None) -> dict[str, Any]:
        """The ``effort`` aggregates of ``split`` ({} if missing)."""
        return self.aggregates(split).get("effort") or {}

    def score(self, split: str | None = None) -> float:
        """The IQM of ``split``'s score (NaN if undefined or the split is missing)."""
        value = self.aggregates(split).get("all", {}).get("iqm")
        return np.nan if value is None else float(value)

    def has(self, split: str) -> bool:
        """Whether the entry's scorecard holds ``split``."""
        return split in self.card["aggregates"]

    @property
    def suite_splits(self) -> tuple[str, ...]:
        """The splits of the entry's suite: the shipped suite's (a reference scored before a
        part joined it lacks that part), else the scorecard's own."""
        suite = SUITES.get(self.card["suite"]["name"])
        return suite.splits if suite else tuple(p["split"] for p in self.card["suite"]["parts"])

    def runs(self, split: str, metric: str) -> tuple[np.ndarray, list[tuple[str, int]]]:
        """(n,) values of ``metric`` over ``split``'s runs (NaN for null) and their tasks."""
        runs = [r for r in self.card["runs"] if r["split"] == split]
        values = np.array([np.nan if r[metric] is None else r[metric] for r in runs], float)
        return values, [(r["world"], r["noise"]) for r in runs]


def rank_split(card: dict[str, Any]) -> str:
    """The first of :data:`RANK_SPLITS` the scorecard ``card`` has (the first if none)."""
    return next((s for s in RANK_SPLITS if s in card["aggregates"]), RANK_SPLITS[0])


def split_metric(entries: list[Entry], split: str) -> str:
    """The score of ``split`` on the board: its metric in the first entry that holds it."""
    return next((e.metric(split) for e in entries if e.has(split)), "q")


def ranked(entries: list[Entry]) -> tuple[list[Entry], list[Entry]]:
    """(non-oracles, oracles), each sorted by :meth:`Entry.score`, best first (undefined last)."""

    def key(entry: Entry) -> tuple[bool, float]:
        score = entry.score()
        return (np.isnan(score), -score if not np.isnan(score) else 0.0)

    return (
        sorted((e for e in entries if not e.oracle), key=key),
        sorted((e for e in entries if e.oracle), key=key),
    )
