"""The scorecard's shape as Python types: one :class:`~typing.TypedDict` per object of the JSON
schema that ships beside this module (``scorecard.schema.json``), with the same keys, required
and optional (``NotRequired``: a key that cards of protocol version 1, or of the benchmark's
lidar, leave out). The schema checks a card on load; these let the type checker check the code
that builds and reads one. ``null`` in the schema is ``None`` here; a figure computed as NaN is
written as ``null`` (:func:`~nbv_gym.benchmark.scorecard.dumps_strict`), so a number that may be
undefined is ``float | None``."""

from collections.abc import Mapping, Sequence
from typing import Any, Literal, NotRequired, TypedDict

#: A number the schema allows to be null (``number_or_null``, ``score``).
Figure = float | None
#: A split's score: the time, budget or explore task's (``TASK_METRICS`` of the suites).
Metric = Literal["q_time_auc", "q", "q_paper_70"]


class PartDescription(TypedDict):
    """A part of the suite as :meth:`~nbv_gym.benchmark.suites.Part.description` gives it:
    everything of :class:`PartEntry` but its hash."""

    split: str
    task: str
    metric: Metric
    worlds: list[str]
    noise: list[int]
    repeats: int
    budget_scans: int | None
    max_steps: int | None
    time_budget_s: NotRequired[float | None]
    runs: int
    lidar: NotRequired[str]
    robots: NotRequired[int]
    q_target: NotRequired[float]


class PartEntry(PartDescription):
    """One part of ``suite.parts`` (schema ``$defs/part``)."""

    hash: str


class SuiteEntry(TypedDict):
    """The scorecard's ``suite``."""

    name: str
    hash: str
    seed: int
    description: str
    parts: list[PartEntry]


class NbvGymEntry(TypedDict):
    """The scorecard's ``nbv_gym``: the version and git commit that scored it."""

    version: str
    git_commit: str


#: The scorecard's ``policy`` (``class`` is a keyword: the functional form).
PolicyEntry = TypedDict(
    "PolicyEntry",
    {"name": str, "class": str, "oracle": bool, "hashed_file": str | None, "code_hash": str | None},
)


class RobotEntry(TypedDict):
    """One robot of a team run's ``per_robot`` (schema ``$defs/robot``): its scans after its
    first, its path (m) and the change of Q of its own scans."""

    steps: int
    path_length_m: float
    delta_q: float


class RunEntry(TypedDict):
    """One run of ``runs`` (schema ``$defs/run``; ``run_v2`` makes the effort figures required
    from protocol version 2 on). The team protocol's runs add ``time_to_q_s`` to
    ``contribution_spread``."""

    split: str
    task: str
    world: str
    asset: str
    noise: int
    repeat: int
    seed: int
    steps: int
    end_reason: str
    q: Figure
    q_paper: Figure
    q_paper_70: Figure
    discovered: Figure
    path_length_m: float
    elapsed_s: NotRequired[float]
    q_time_auc: NotRequired[Figure]
    q_time: NotRequired[Sequence[Figure]]
    q_path: NotRequired[Sequence[Figure]]
    decision_time_s: Figure
    wall_time_s: float
    time_to_q_s: NotRequired[Figure]
    per_robot: NotRequired[list[RobotEntry]]
    overlap_rate: NotRequired[float]
    longest_path_m: NotRequired[float]
    contribution_spread: NotRequired[float]


class Summary(TypedDict):
    """IQM, mean and optimality gap of a score with their 95 % intervals (``$defs/summary``)."""

    n: int
    iqm: Figure
    iqm_low: Figure
    iqm_high: Figure
    mean: Figure
    mean_low: Figure
    mean_high: Figure
    optimality_gap: Figure
    optimality_gap_low: Figure
    optimality_gap_high: Figure


class Band(TypedDict):
    """A mean curve with its 25th and 75th percentiles over runs (``$defs/band``)."""

    mean: list[float]
    low: list[float]
    high: list[float]


class Effort(TypedDict):
    """The ``effort`` aggregates of a split: Q at matched path, Q at the time budget, the mean
    elapsed time and the mean curves."""

    q_at_path: dict[str, Summary]
    q_at_budget: Summary | None
    elapsed_s: Figure
    q_time: Band
    q_path: Band


class Aggregate(TypedDict):
    """The aggregates of one split (``$defs/aggregate``); ``means``: the plain means of
    :data:`~nbv_gym.benchmark.scorecard.MEAN_FIGURES`."""

    metric: Metric
    all: Summary
    by_asset: dict[str, Summary]
    means: dict[str, Figure]
    effort: NotRequired[Effort]


class Timing(TypedDict):
    """The scorecard's ``timing``: wall time (s) and worker processes."""

    wall_time_s: float
    workers: int


class Scorecard(TypedDict):
    """A whole scorecard (``scorecard.json``)."""

    format: str
    protocol_version: int
    suite: SuiteEntry
    nbv_gym: NbvGymEntry
    versions: dict[str, str]
    policy: PolicyEntry
    optimality_target: float
    runs: list[RunEntry]
    aggregates: dict[str, Aggregate]
    created: str
    timing: Timing


def value_of(entry: Mapping[str, object], name: str) -> Any:
    """The figure ``name`` of a run (or another card object) named at run time (a split's
    ``metric``, a curve's key): the value as stored, ``None`` for null; KeyError if absent."""
    return entry[name]
