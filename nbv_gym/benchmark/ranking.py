"""One scorecard on a leaderboard (:class:`Entry`) and the order a board ranks entries in: by
the first of :data:`RANK_SPLITS` a scorecard has, oracles apart; the baseline and each entry's
``P(better)`` against it; which entries another dominates on (Q, path). The splits a board
shows and their labels: :data:`~nbv_gym.benchmark.suites.SPLIT_LABELS`."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from nbv_gym.benchmark.cardtypes import Aggregate, Effort, Metric, Scorecard, value_of
from nbv_gym.benchmark.suites import HEADLINE_SPLIT, SUITES, TEAM_RANK_SPLITS

if TYPE_CHECKING:
    from nbv_gym.reporting.inference import Interval

#: The splits whose score ranks the table, the first a scorecard has: the time task's test split,
#: else (a suite on your own worlds, ``nbv-gym score --world``, has no test split) the time task
#: on its worlds; a team scorecard's: the largest team's test split.
RANK_SPLITS = (HEADLINE_SPLIT, "time-benchmark", *TEAM_RANK_SPLITS)


@dataclass(frozen=True)
class Entry:
    """One scorecard on the board: its ``label``, the ``card`` and where it came from
    (``source``: a path, or ``"references"``)."""

    label: str
    card: Scorecard
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

    def aggregates(self, split: str | None = None) -> Aggregate | None:
        """The aggregates of ``split`` (default: :attr:`rank_split`; None if missing)."""
        return self.card["aggregates"].get(split or self.rank_split)

    def metric(self, split: str | None = None) -> Metric:
        """The score of ``split`` (its aggregates' ``metric``; ``q`` if the split is missing)."""
        found = self.aggregates(split)
        return found["metric"] if found else "q"

    def effort(self, split: str | None = None) -> Effort | None:
        """The ``effort`` aggregates of ``split`` (None if missing)."""
        found = self.aggregates(split)
        return found.get("effort") if found else None

    def score(self, split: str | None = None) -> float:
        """The IQM of ``split``'s score (NaN if undefined or the split is missing)."""
        found = self.aggregates(split)
        value = found["all"]["iqm"] if found else None
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
        given = [value_of(run, metric) for run in runs]
        values = np.array([np.nan if value is None else value for value in given], float)
        return values, [(r["world"], r["noise"]) for r in runs]


def is_team(card: Scorecard) -> bool:
    """Whether ``card`` is of the team protocol (its parts name their ``robots``)."""
    return any("robots" in part for part in card["suite"]["parts"])


def rank_split(card: Scorecard) -> str:
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
        found, effort = entry.aggregates(), entry.effort()
        at_budget = effort["q_at_budget"] if effort else None
        q = at_budget["iqm"] if at_budget else None
        path = found["means"].get("path_length_m") if found else None
        if q is not None and path is not None and np.isfinite(q) and np.isfinite(path):
            points[entry.label] = (q, round(path))
    out = {}
    for label, (q, path) in points.items():
        for other, (q2, path2) in points.items():
            if other != label and q2 >= q and path2 <= path and (q2 > q or path2 < path):
                out[label] = other
                break
    return out


def baseline(entries: list[Entry], split: str | None = None) -> Entry:
    """The best reference that is not an oracle (or, with no such reference, the best entry that
    is not an oracle, or the best entry), among the entries that hold ``split`` if given (the
    first entry when none does)."""
    holding = [e for e in entries if split is None or e.has(split)] or entries
    players, oracles = ranked(holding)
    references = [e for e in players if e.reference]
    return (references or players or oracles)[0]


def improvement(entry: Entry, best: Entry, seed: int = 0, split: str | None = None) -> Interval:
    """``P(entry > best)`` on the score of ``split`` (default: the ranking split) with its
    stratified bootstrap interval."""
    from nbv_gym.reporting.inference import probability_of_improvement_interval

    split = split or entry.rank_split
    a, tasks_a = entry.runs(split, entry.metric(split))
    b, tasks_b = best.runs(split, best.metric(split))
    label = int.from_bytes(hashlib.sha256(entry.label.encode()).digest()[:4], "big")
    rng = np.random.default_rng([seed, label])
    return probability_of_improvement_interval(a, tasks_a, b, tasks_b, rng)
