"""One scorecard on a leaderboard (:class:`Entry`) and the order a board ranks entries in: by
the first of :data:`RANK_SPLITS` a scorecard has, oracles apart; which entries another dominates
on (Q, path). The splits a board shows and their labels:
:data:`~nbv_gym.benchmark.suites.SPLIT_LABELS`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from nbv_gym.benchmark.suites import HEADLINE_SPLIT, SUITES

#: The splits whose score ranks the table, the first a scorecard has: the time task's test split,
#: else (a suite on your own worlds, ``nbv-gym score --world``, has no test split) the time task
#: on its worlds.
RANK_SPLITS = (HEADLINE_SPLIT, "time-benchmark")


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


def pareto_dominated(entries: list[Entry]) -> dict[str, str]:
    """Entry label → the label of an entry that dominates it on (IQM of Q at the time budget,
    mean path) of the ranking split, the figures the effort table shows: Q ≥ and path ≤, one of
    them strictly. Paths are compared to the metre, as the table shows them (a goal cell is
    1 m: a few centimetres of mean path are no less effort). Entries without those figures are
    left out."""
    points = {}
    for entry in entries:
        means = entry.aggregates().get("means", {})
        q, path = entry.effort().get("q_at_budget", {}).get("iqm"), means.get("path_length_m")
        if q is not None and path is not None and np.isfinite(q) and np.isfinite(path):
            points[entry.label] = (q, round(path))
    out = {}
    for label, (q, path) in points.items():
        for other, (q2, path2) in points.items():
            if other != label and q2 >= q and path2 <= path and (q2 > q or path2 < path):
                out[label] = other
                break
    return out
