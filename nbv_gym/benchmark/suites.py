"""The evaluation suites of ``nbv-gym score``: fixed, versioned data.

A :class:`Suite` is a few :class:`Part` s, each a sweep of one policy over worlds × noise levels ×
repeats under one task:

- ``time-test``: the time task (:data:`~nbv_gym.core.protocol.TIME_BUDGET_S` seconds of robot time,
  travel and scans charged) on the generated test split; score: the normalised area under Q
  against elapsed time over [0, budget] — the headline figure of the leaderboard;
- ``time-shift``: the time task on the generated shift split
  (:mod:`nbv_gym.benchmark.shiftsplit`), worlds of recipes outside every training distribution
  (denser, sparser, tighter clusters, larger forests); score as ``time-test``;
- ``time-benchmark``: the time task on the paper's twelve benchmark worlds;
- ``benchmark``: the budget task (:data:`~nbv_gym.core.protocol.BUDGET_SCANS` scans, no early end) on
  the paper's twelve benchmark worlds; score: Q after the budget;
- ``test``: the budget task on the generated test split (:mod:`nbv_gym.benchmark.testsplit`), whose
  recipe differs from the benchmark and the training pools; score: Q after the budget (equal
  scans, travel free);
- ``explore``: the paper's protocol (explore until 70 % of the ground is discovered, at most
  100 steps) on the twelve benchmark worlds; score: Q_paper at 70 % discovered.

The ``team`` suite is the team protocol (:mod:`nbv_gym.team`): parts whose ``robots`` is set run
the time task with that many robots on one map and one clock — ``team2-test``, ``team3-test``
(the test split), ``team2-shift``, ``team3-shift`` (the shift split) — and ``solo2-test``,
``solo3-test``: one robot on the test split with N × the budget, the same total robot time as a
team of N. Score: the normalised area under the team's Q(t) over its budget (equal to the mean
Q over the total robot time, so a team of N over T and one robot over N × T compare). Its
scorecards rank apart from single-robot ones.

Run seeds derive from the suite's seed, the world, the noise level and the repeat
(:meth:`~nbv_gym.sweep.config.SweepConfig.run_seed`), never from the policy, so every policy meets
the same first scan and localisation noise (paired runs). ``quick``'s runs are a subset of
``standard``'s (same seed, the first worlds and repeats).

:meth:`Part.content_hash` hashes everything that fixes the results of a part's runs — worlds
(their spec digests), noise levels, repeats, the suite's seed, task settings and the
environment's whole default config — and :meth:`Suite.content_hash` those of all its parts, so a
scorecard records which suite and which parts it belongs to, and a change to any default marks
stored scorecards as stale. A part added to a suite leaves the other parts' hashes as they were:
a scorecard of the suite's other parts (:meth:`Suite.only`) stays valid for them, and only the
new part's runs are missing. :data:`PROTOCOL_VERSION` numbers the scoring rules themselves (the
figures per run, the aggregates, the statistics); it is bumped by hand when they change.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

from nbv_gym.benchmark.cardtypes import Metric, PartDescription, PartEntry, SuiteEntry
from nbv_gym.benchmark.shiftsplit import shift_worlds
from nbv_gym.benchmark.testsplit import split_worlds
from nbv_gym.core.config import to_dict
from nbv_gym.core.errors import ConfigError, UnknownNameError
from nbv_gym.core.protocol import NOISE_LEVELS
from nbv_gym.env.task import TaskConfig
from nbv_gym.sensor.presets import DEFAULT_LIDAR, LIDAR_PRESETS
from nbv_gym.team.episode import Q_TARGET
from nbv_gym.team.simulator import check_team_size
from nbv_gym.worlds.spec import AnySpec, WorldSpec, load_spec

#: Version of the scoring protocol (per-run figures, aggregates, statistics); scorecards of
#: different versions are never compared.
PROTOCOL_VERSION = 2
#: The paper's twelve benchmark worlds.
BENCHMARK_WORLDS = tuple(
    f"pp{p}-{asset}" for p in (1, 2, 3) for asset in ("cuboids", "crosses", "helicoids", "trees")
)
#: The score of each task: the normalised area under Q(t) over the time budget; Q after the
#: scan budget; Q_paper at the explore task's 70 % discovered.
TASK_METRICS: dict[str, Metric] = {"time": "q_time_auc", "budget": "q", "explore": "q_paper_70"}
#: How tables and figures name each score (:data:`TASK_METRICS`).
METRIC_LABELS = {
    "q_time_auc": "area under Q(t) / budget",
    "q": "Q after the budget",
    "q_paper_70": "Q_paper at 70 %",
}
#: The split whose score ranks the leaderboard.
HEADLINE_SPLIT = "time-test"
#: The split of the time task on worlds outside every training distribution, shown beside it.
SHIFT_SPLIT = "time-shift"
#: The team sizes of the team suite.
TEAM_SIZES = (2, 3)


@dataclass(frozen=True)
class SplitLabels:
    """How the leaderboard names a split: ``score`` (its score and what it charges: a
    performance profile's panel) and ``column`` (the scores table's short column title)."""

    score: str
    column: str


#: The one table of the splits a leaderboard shows, in order (the scores table's columns, the
#: profile figure's panels), with their labels.
SPLIT_LABELS = {
    "time-test": SplitLabels(
        "area under Q(t) / budget, test split (equal robot time)",
        "equal time, test: IQM area under Q(t)",
    ),
    "time-shift": SplitLabels(
        "area under Q(t) / budget, shift split (equal robot time)",
        "equal time, shift: IQM area under Q(t)",
    ),
    "time-benchmark": SplitLabels(
        "area under Q(t) / budget, benchmark worlds (equal robot time)",
        "equal time, benchmark: IQM area under Q(t)",
    ),
    "test": SplitLabels(
        "Q after the scans, test split (equal scans, travel free)",
        "equal scans (travel free), test: IQM Q",
    ),
    "benchmark": SplitLabels(
        "Q after the scans, benchmark worlds (equal scans, travel free)",
        "equal scans (travel free), benchmark: IQM Q",
    ),
    "explore": SplitLabels(
        "Q_paper at 70 % discovered (the paper's protocol)", "paper's protocol: IQM Q_paper@70 %"
    ),
}

#: The team suite's splits a team leaderboard shows as columns, in order, with their labels
#: (a solo part's scores stand in its team size's test column, on the one-robot rows).
TEAM_SPLIT_LABELS = {
    f"team{n}-{split}": SplitLabels(
        f"area under the team's Q(t) / budget, {n} robots, {split} split (equal team time)",
        f"{n} robots, {split}: IQM area under Q(t)",
    )
    for n in TEAM_SIZES
    for split in ("test", "shift")
}
#: The splits that rank a team leaderboard, the first a scorecard has.
TEAM_RANK_SPLITS = tuple(f"team{n}-test" for n in reversed(TEAM_SIZES))


def solo_split(n_robots: int) -> str:
    """The split of one robot with ``n_robots`` × the budget (the team of ``n_robots``'s total
    robot time) on the test worlds."""
    return f"solo{n_robots}-test"


@dataclass(frozen=True)
class Part:
    """One sweep of a suite: ``split`` (its name in the scorecard), ``task`` (its settings,
    :class:`~nbv_gym.env.task.TaskConfig`: the task — ``time``, ``budget`` or ``explore`` —, its
    budget or truncation and the lidar preset; its ``noise`` is replaced by each of the part's),
    ``worlds`` (benchmark world names or generated :class:`WorldSpec` s), localisation ``noise``
    levels (the part's grid) and ``repeats`` per world and noise level; ``robots``: None for the
    single-robot protocol, else the team protocol's robots (time task only; 1: one robot run as
    a team of one)."""

    split: str
    task: TaskConfig
    worlds: tuple[str | WorldSpec, ...]
    noise: tuple[int, ...] = tuple(NOISE_LEVELS)
    repeats: int = 3
    robots: int | None = None

    def __post_init__(self) -> None:
        if self.robots is not None:
            check_team_part(self.robots, self.task.name)

    @property
    def team(self) -> bool:
        """Whether the part is of the team protocol (``robots`` set: run with the team task's
        runner, :mod:`nbv_gym.benchmark.teamrun`), even with one robot."""
        return self.robots is not None

    @property
    def metric(self) -> Metric:
        """The per-run score of this part (:data:`TASK_METRICS`)."""
        return TASK_METRICS[self.task.name]

    @property
    def world_names(self) -> tuple[str, ...]:
        """The names of the part's worlds, in order: what its runs record (a spec file's by
        the ``name`` it holds, not by its path)."""
        return tuple(spec.name for spec in self.specs())

    @property
    def runs(self) -> int:
        """Number of runs of the part: worlds × noise levels × repeats."""
        return len(self.worlds) * len(self.noise) * self.repeats

    def specs(self) -> tuple[AnySpec, ...]:
        """The world specs of the part (benchmark names loaded)."""
        return tuple(w if isinstance(w, WorldSpec) else load_spec(w) for w in self.worlds)

    def env_config(self):
        """The :class:`~nbv_gym.env.explore.EnvConfig` every run of the part uses (world and
        noise aside): the defaults, with the task's episode settings."""
        from nbv_gym.env.explore import EnvConfig

        config = self.task.env_config(EnvConfig().simulator.world)
        default = EnvConfig().simulator
        return replace(config, simulator=replace(config.simulator, noise=default.noise))

    def content(self) -> dict[str, Any]:
        """Everything that fixes the results of the part's runs but the suite's seed, as plain
        data: its :meth:`description`, its worlds' spec digests and the environment config."""
        env = to_dict(self.env_config())
        del env["simulator"]["world"], env["simulator"]["noise"]
        worlds = {spec.name: spec.digest() for spec in self.specs()}
        return {**self.description(), "worlds": worlds, "env": env}

    def content_hash(self, seed: int) -> str:
        """SHA-256 (16 hex digits) of :meth:`content` with the suite's ``seed``: the same in
        every suite that holds this part with this seed."""
        return _hash({"seed": seed, "part": self.content()})

    def description(self) -> PartDescription:
        """The part as plain data for the scorecard (:meth:`Suite.identity` adds its hash)."""
        task = self.task
        described: PartDescription = {
            "split": self.split,
            "task": task.name,
            "metric": self.metric,
            "worlds": list(self.world_names),
            "noise": list(self.noise),
            "repeats": self.repeats,
            "budget_scans": task.budget_scans if task.name == "budget" else None,
            "max_steps": task.max_steps if task.name == "explore" else None,
            "time_budget_s": task.time_budget_s if task.name == "time" else None,
            "runs": self.runs,
        }
        if task.lidar != DEFAULT_LIDAR:  # only another preset is named: the benchmark's
            described["lidar"] = task.lidar  # scorecards keep their content
        if self.robots is not None:  # the team protocol's parts only: single-robot parts
            described["robots"] = self.robots  # keep their content and hashes
            described["q_target"] = Q_TARGET
        return described


def check_team_part(robots: object, task: str) -> None:
    """ConfigError unless ``robots`` is a team size (an integer ≥ 1) and ``task`` the time
    task (the team task's)."""
    check_team_size(robots, None)
    if task != "time":
        raise ConfigError(f"a team part runs the time task (the team task), not the {task} task")


@dataclass(frozen=True)
class Suite:
    """A named, fixed set of :class:`Part` s; ``seed`` is the base of every run seed."""

    name: str
    parts: tuple[Part, ...]
    seed: int
    description: str = ""

    def __post_init__(self) -> None:
        if len({part.team for part in self.parts}) > 1:
            raise ConfigError(
                f"suite {self.name}: its parts are all of the team protocol (robots set) or "
                "none; a scorecard ranks with one kind only"
            )

    @property
    def team(self) -> bool:
        """Whether the suite is of the team protocol (its parts' ``robots`` set)."""
        return any(part.team for part in self.parts)

    @property
    def runs(self) -> int:
        """Number of runs of the suite, over all its parts."""
        return sum(part.runs for part in self.parts)

    def with_lidar(self, lidar: str) -> Suite:
        """This suite run with the lidar preset ``lidar`` (:mod:`nbv_gym.sensor.presets`); its
        content hash changes unless it is the default, so its scorecards rank apart."""
        parts = tuple(replace(part, task=replace(part.task, lidar=lidar)) for part in self.parts)
        return replace(self, parts=parts)

    def with_worlds(self, worlds: tuple[str, ...]) -> Suite:
        """This suite's shape on your own ``worlds`` (spec files or benchmark names): its parts
        on the benchmark worlds (budget, explore, time), with those worlds, noise levels and
        repeats; not its parts on the generated test split (the benchmark's own held-out
        worlds). Another suite: its scorecards rank apart."""
        names: dict[str, str] = {}
        for world in worlds:  # a bad world fails before any run
            name = load_spec(world).name
            if name in names:
                raise ConfigError(
                    f"{names[name]} and {world} are both named {name!r}: a suite's runs are "
                    "told apart by world name; give one of them another name."
                )
            names[name] = world
        parts = tuple(
            replace(part, worlds=tuple(worlds))
            for part in self.parts
            if not any(isinstance(w, WorldSpec) for w in part.worlds)
        )
        listed = ", ".join(worlds)
        return replace(self, name=f"{self.name}-own", parts=parts,
                       description=f"{self.name}'s benchmark-world parts on {listed}")  # fmt: skip

    def part(self, split: str) -> Part:
        """The part of split ``split`` (``StopIteration`` if the suite has none)."""
        return next(p for p in self.parts if p.split == split)

    @property
    def splits(self) -> tuple[str, ...]:
        """The parts' splits, in order."""
        return tuple(part.split for part in self.parts)

    def only(self, splits: Iterable[str]) -> Suite:
        """This suite with only its parts of ``splits`` (in the suite's order; other names are
        ignored): what a scorecard of some of its parts belongs to. Those parts keep their
        hashes; the suite's hash is theirs (:meth:`content_hash`)."""
        wanted = set(splits)
        return replace(self, parts=tuple(p for p in self.parts if p.split in wanted))

    def content(self) -> dict[str, Any]:
        """Everything that fixes the results of a run of the suite, as plain data."""
        return {"seed": self.seed, "parts": [part.content() for part in self.parts]}

    def content_hash(self) -> str:
        """SHA-256 (16 hex digits) of :meth:`content`."""
        return _hash(self.content())

    def identity(self) -> SuiteEntry:
        """The suite as a scorecard records it: name, content hash, seed, description, parts
        (each with its :meth:`Part.content_hash`)."""
        return {
            "name": self.name,
            "hash": self.content_hash(),
            "seed": self.seed,
            "description": self.description,
            "parts": [
                PartEntry(**part.description(), hash=part.content_hash(self.seed))
                for part in self.parts
            ],
        }


_TIME, _BUDGET, _EXPLORE = (TaskConfig(name=task) for task in ("time", "budget", "explore"))


def _solo(n_robots: int) -> TaskConfig:
    """The time task of one robot with the total robot time of a team of ``n_robots``."""
    return replace(_TIME, time_budget_s=n_robots * _TIME.time_budget_s)


def _hash(content: dict[str, Any]) -> str:
    """SHA-256 (16 hex digits) of ``content`` as sorted JSON."""
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def shipped_suite(recorded: Mapping[str, Any]) -> Suite | None:
    """The shipped suite a scorecard's ``suite`` entry names, with the lidar preset its parts
    name and only the parts it records (:meth:`Suite.only`), or None for a suite nbv-gym does
    not ship (a test's, or your own worlds': those are checked against their own parts only)."""
    if recorded.get("name") not in SUITES:
        return None
    parts = recorded.get("parts", [])
    lidars = {part.get("lidar", DEFAULT_LIDAR) for part in parts}
    suite = SUITES[recorded["name"]]
    if len(lidars) == 1 and lidars != {DEFAULT_LIDAR} and next(iter(lidars)) in LIDAR_PRESETS:
        suite = suite.with_lidar(next(iter(lidars)))
    return suite.only(part.get("split") for part in parts)


def shipped_identity(recorded: Mapping[str, Any]) -> SuiteEntry | None:
    """What a scorecard of the shipped suite it names must record as its ``suite``: the
    identity of :func:`shipped_suite` (None for a suite nbv-gym does not ship)."""
    suite = shipped_suite(recorded)
    return None if suite is None else suite.identity()


#: Base seed of the shipped suites' run seeds.
SUITE_SEED = 7919

STANDARD = Suite(
    "standard",
    (
        Part("time-test", _TIME, split_worlds()),
        Part("time-shift", _TIME, shift_worlds()),
        Part("time-benchmark", _TIME, BENCHMARK_WORLDS),
        Part("benchmark", _BUDGET, BENCHMARK_WORLDS),
        Part("test", _BUDGET, split_worlds()),
        Part("explore", _EXPLORE, BENCHMARK_WORLDS),
    ),
    SUITE_SEED,
    "time task (equal robot time, travel and scans charged) and budget task (equal scans, "
    "travel free) on the 16 test worlds and the 12 benchmark worlds, time task on the 12 shift "
    "worlds, explore task (the paper's protocol) on the 12 benchmark worlds; noise 0, 1, 2; "
    "3 repeats",
)
_QUICK_WORLDS = tuple(w for w in BENCHMARK_WORLDS if w.startswith("pp1-"))
QUICK = Suite(
    "quick",
    (
        Part("time-test", _TIME, split_worlds(range(4)), repeats=2),
        Part("time-benchmark", _TIME, _QUICK_WORLDS, repeats=2),
        Part("benchmark", _BUDGET, _QUICK_WORLDS, repeats=2),
        Part("test", _BUDGET, split_worlds(range(4)), repeats=2),
        Part("explore", _EXPLORE, _QUICK_WORLDS, repeats=2),
    ),
    SUITE_SEED,
    "the standard suite's shape, small: pp1-* and test-00…03, noise 0, 1, 2, 2 repeats",
)
TEAM = Suite(
    "team",
    (
        *(Part(f"team{n}-test", _TIME, split_worlds(), robots=n) for n in TEAM_SIZES),
        *(Part(f"team{n}-shift", _TIME, shift_worlds(), robots=n) for n in TEAM_SIZES),
        *(Part(solo_split(n), _solo(n), split_worlds(), robots=1) for n in TEAM_SIZES),
    ),
    SUITE_SEED,
    "the team task (N robots on one map and one clock, 600 s of team time, travel and scans "
    "charged) with 2 and 3 robots on the 16 test worlds and the 12 shift worlds, and one robot "
    "with N × 600 s on the test worlds (the same total robot time); noise 0, 1, 2; 3 repeats",
)
#: The shipped suites by name.
SUITES = {suite.name: suite for suite in (STANDARD, QUICK, TEAM)}


def get_suite(name: str) -> Suite:
    """The shipped suite ``name``; :class:`UnknownNameError` (with the near miss) otherwise."""
    if name not in SUITES:
        raise UnknownNameError("suite", name, SUITES)
    return SUITES[name]
