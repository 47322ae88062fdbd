"""Reference scorecards: every shipped policy scored on a suite, shipped in
``nbv_gym/benchmark/references/<suite>/<name>.json``, so that scoring a new policy runs only that
policy and ``nbv-gym leaderboard --references`` ranks it against all of them, on the suite its
scorecard was scored on. The standard suite's references ship; a suite gets references by adding
its folder of scorecards (nothing else to change).

Regenerate them (after a change that moves results; a test says when) with::

    python -m nbv_gym.benchmark.references [NAME ...] [--suite SUITE] [--work DIR] [--workers N]
        [--scheduler ADDRESS]

which scores each named shipped policy (default: all of :func:`shipped_policies`) on the suite
(default: standard) with :func:`~nbv_gym.benchmark.suiterun.score_policy` into
``DIR/<suite>/<name>/`` (resumable, default ``references-work``) and copies its
``scorecard.json`` into the suite's folder of the package.

A part added to a suite leaves the references' other parts valid (each part has its own hash,
:meth:`~nbv_gym.benchmark.suites.Part.content_hash`): a reference that lacks it is current for
the parts it holds, and the leaderboard says that the new part is pending for it. Score only
the missing part and join it to the reference with::

    python -m nbv_gym.benchmark.references [NAME ...] --part SPLIT [--part SPLIT ...]

(default: every reference that lacks one of them; resumable like the rest). ``--restamp``
rewrites the references' record of their suite — its description and the parts' hashes — when
the runs they hold are still those of the suite (their recorded suite hash is the hash of the
same parts now), without running anything.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Callable
from pathlib import Path

from nbv_gym.benchmark.cardtypes import Scorecard
from nbv_gym.benchmark.scorecard import dumps_strict, join_scorecards, load_scorecard
from nbv_gym.benchmark.suites import (
    PROTOCOL_VERSION,
    STANDARD,
    SUITES,
    Suite,
    get_suite,
    shipped_identity,
    shipped_suite,
)
from nbv_gym.core.errors import NbvGymError

#: The folder of the shipped reference scorecards, one subfolder per suite.
REFERENCE_DIR = Path(__file__).with_name("references")
#: The suite references are scored on unless another is named (the one whose references ship).
REFERENCE_SUITE = STANDARD
#: Per suite, the shipped policies whose reference scorecard is not shipped (yet), with the
#: reason. The leaderboard names them; a test keeps this honest for every suite that has
#: references (no file for a pending policy, and every other shipped policy has one). Generate
#: one with ``python -m nbv_gym.benchmark.references NAME --suite SUITE`` and delete its entry.
PENDING: dict[str, dict[str, str]] = {
    suite: {
        "oracle-time": "the time task's teacher, new: its reference is scored with the next "
        "references"
    }
    for suite in ("standard", "quick")
}


class ReferenceUpdateError(NbvGymError):
    """A reference cannot be completed or re-stamped as asked; the message says what to do."""


def pending(suite: str) -> dict[str, str]:
    """The shipped policies without a reference on ``suite``, with the reason (:data:`PENDING`)."""
    return PENDING.get(suite, {})


def shipped_policies() -> list[str]:
    """Every policy the package ships: the registered ones, then the trained models."""
    from nbv_gym.policies import MODELS, POLICIES

    return [*POLICIES, *MODELS]


def reference_path(name: str, suite: str = REFERENCE_SUITE.name) -> Path:
    """The reference scorecard file of the shipped policy ``name`` on ``suite``."""
    return REFERENCE_DIR / suite / f"{name}.json"


def reference_suites() -> list[str]:
    """The suites (in :data:`~nbv_gym.benchmark.suites.SUITES` order) whose folder holds
    reference scorecards."""
    return [name for name in SUITES if any((REFERENCE_DIR / name).glob("*.json"))]


def load_references(suite: str = REFERENCE_SUITE.name) -> list[Scorecard]:
    """The shipped reference scorecards of ``suite``, in :func:`shipped_policies` order (those
    that exist; none for a suite without references)."""
    paths = [reference_path(n, suite) for n in shipped_policies()]
    return [load_scorecard(path, recompute=False) for path in paths if path.is_file()]  # tested


def is_current(card: Scorecard, suite: str = REFERENCE_SUITE.name) -> bool:
    """Whether the reference scorecard ``card`` belongs to this package's protocol version and
    to ``suite`` as it is now — every part it holds is the suite's part of that split, hash and
    all (a stale one is never mixed into a leaderboard); it may lack parts
    (:func:`missing_parts`). A suite that is not shipped (a test's) is checked by name and
    version only."""
    return (
        card["protocol_version"] == PROTOCOL_VERSION
        and card["suite"]["name"] == suite
        and (suite not in SUITES or card["suite"] == shipped_identity(card["suite"]))
    )


def missing_parts(card: Scorecard) -> list[str]:
    """The splits of the shipped suite the scorecard ``card`` names that it does not hold (none
    for a suite that is not shipped)."""
    suite = SUITES.get(card["suite"]["name"])
    held = {part["split"] for part in card["suite"]["parts"]}
    return [split for split in suite.splits if split not in held] if suite else []


def current_references(
    suite: str = REFERENCE_SUITE.name,
) -> tuple[list[Scorecard], list[Scorecard]]:
    """(current, stale): the shipped reference scorecards of ``suite`` split by
    :func:`is_current`."""
    cards = load_references(suite)
    return [c for c in cards if is_current(c, suite)], [
        c for c in cards if not is_current(c, suite)
    ]


def pending_note(stale: list[Scorecard], suite: str = REFERENCE_SUITE.name) -> str:
    """One sentence saying that references of ``suite`` for this protocol version are pending,
    naming the versions the ``stale`` ones were scored under ("" if none is stale)."""
    if not stale:
        return ""
    versions = sorted({c["protocol_version"] for c in stale})
    names = ", ".join(c["policy"]["name"] for c in stale)
    return (
        f"References for protocol version {PROTOCOL_VERSION} (suite {suite}, "
        f"hash {SUITES[suite].content_hash() if suite in SUITES else '—'}) are pending: the shipped references of {names} "
        f"were scored under protocol version {', '.join(map(str, versions))} or another suite, "
        "and are left out rather than mixed in (regenerate them: python -m "
        "nbv_gym.benchmark.references)."
    )


def missing_note(cards: list[Scorecard]) -> str:
    """One sentence per missing split naming the references ``cards`` that lack it (""
    when none does): what the leaderboard and the tests say while a new part is pending."""
    missing: dict[str, list[str]] = {}
    for card in cards:
        for split in missing_parts(card):
            missing.setdefault(split, []).append(card["policy"]["name"])
    return " ".join(
        f"The {split} split is pending for {', '.join(names)}: the references were scored "
        f"before it joined the suite (their other splits stand); score only it: python -m "
        f"nbv_gym.benchmark.references {' '.join(names)} --part {split}."
        for split, names in missing.items()
    )


def references_note(suite: str = REFERENCE_SUITE.name) -> str:
    """What a leaderboard says about the references of ``suite``: :func:`pending_note` of the
    stale ones and :func:`missing_note` of the current ones ("" when there is nothing to say)."""
    current, stale = current_references(suite)
    return " ".join(filter(None, [pending_note(stale, suite), missing_note(current)]))


def regenerate(
    names: list[str],
    work: Path,
    workers: int | None = None,
    say: Callable[[str], None] = print,
    suite: Suite = REFERENCE_SUITE,
    scheduler: str | None = None,
) -> list[Path]:
    """Score each of ``names`` on ``suite`` into ``work/<suite>/<name>`` (locally, or on the Dask
    ``scheduler``) and copy the scorecard into the suite's reference folder; the written
    reference files."""
    from nbv_gym.benchmark.suiterun import score_policy

    written = []
    (REFERENCE_DIR / suite.name).mkdir(parents=True, exist_ok=True)
    for name in names:
        out = work / suite.name / name
        score_policy(name, suite, out, workers, progress=False, say=say, scheduler=scheduler)
        target = reference_path(name, suite.name)
        written.append(Path(shutil.copyfile(out / "scorecard.json", target)))
        say(f"{name}: reference written to {target}")
    return written


def complete(
    names: list[str],
    splits: list[str],
    work: Path,
    workers: int | None = None,
    say: Callable[[str], None] = print,
    suite: Suite = REFERENCE_SUITE,
    scheduler: str | None = None,
) -> list[Path]:
    """Score only the parts ``splits`` of ``suite`` that each reference of ``names`` lacks, into
    ``work/<suite>/<name>`` (resumable), and join them to the reference
    (:func:`~nbv_gym.benchmark.scorecard.join_scorecards`); the rewritten reference files.
    :class:`ReferenceUpdateError` for a reference that is missing, stale, or whose policy code
    changed since it was scored (regenerate it whole)."""
    from nbv_gym.benchmark.scorecard import file_hash, policy_file
    from nbv_gym.benchmark.suiterun import score_policy
    from nbv_gym.core.outputs import write_text

    unknown = sorted(set(splits) - set(suite.splits))
    if unknown:
        raise ReferenceUpdateError(f"suite {suite.name} has no part {unknown}; its parts: "
                             f"{', '.join(suite.splits)}")  # fmt: skip
    if not names:
        say(f"every {suite.name} reference holds {', '.join(splits)}: nothing to score")
    written = []
    for name in names:
        path = reference_path(name, suite.name)
        if not path.is_file():
            raise ReferenceUpdateError(f"{name} has no {suite.name} reference to complete; score it "
                                 f"whole: python -m nbv_gym.benchmark.references {name}")  # fmt: skip
        card = load_scorecard(path, recompute=False)
        todo = [split for split in splits if split in missing_parts(card)]
        if not todo:
            say(f"{name}: its reference holds {', '.join(splits)} already")
            continue
        hashed = policy_file(name)
        if not is_current(card, suite.name) or card["policy"]["code_hash"] != (
            file_hash(hashed) if hashed else None
        ):
            raise ReferenceUpdateError(
                f"{name}'s {suite.name} reference is stale (another protocol version, suite or "
                f"policy code): regenerate it whole: python -m nbv_gym.benchmark.references {name} "
                "(or, if only its record of the suite is old, re-stamp it first: --restamp)"
            )
        out = work / suite.name / f"{name}+{'+'.join(todo)}"
        part = score_policy(name, suite.only(todo), out, workers, progress=False, say=say,
                            scheduler=scheduler)  # fmt: skip
        write_text(path, dumps_strict(join_scorecards(suite, [card, part])))
        written.append(path)
        say(f"{name}: {', '.join(todo)} joined to its reference {path}")
    return written


def restamp(suite: Suite = REFERENCE_SUITE, say: Callable[[str], None] = print) -> list[Path]:
    """Rewrite the ``suite`` entry of every reference of ``suite`` to the suite's record of the
    parts it holds (description, part hashes), when its runs are still those parts' (its
    recorded hash is their hash now); the rewritten files, each validated before it is written.
    :class:`ReferenceUpdateError`, before any file is written, for a reference whose parts
    changed (regenerate it)."""
    from nbv_gym.benchmark.validation import validate_scorecard
    from nbv_gym.core.inputs import read_json
    from nbv_gym.core.outputs import write_text

    paths = [reference_path(n, suite.name) for n in shipped_policies()]
    cards = {path: read_json(path, "Reference scorecard") for path in paths if path.is_file()}
    stamps = {}
    for path, card in cards.items():
        now = shipped_suite(card["suite"])
        if (
            card["protocol_version"] != PROTOCOL_VERSION
            or now is None
            or (card["suite"]["hash"] != now.content_hash())
        ):
            raise ReferenceUpdateError(
                f"{path.name}: its runs are not those of suite {suite.name}'s parts now (another "
                f"protocol version or part content); regenerate it: python -m "
                f"nbv_gym.benchmark.references {card['policy']['name']}"
            )
        stamps[path] = validate_scorecard({**card, "suite": now.identity()}, path)
    changed = [path for path in cards if stamps[path] != cards[path]]
    for path in changed:
        write_text(path, dumps_strict(stamps[path]))
        say(f"{path.name}: re-stamped")
    return changed


def main(argv: list[str] | None = None) -> None:
    """``python -m nbv_gym.benchmark.references``: see the module docstring."""
    parser = argparse.ArgumentParser(
        prog="python -m nbv_gym.benchmark.references",
        description="Score shipped policies on a suite and store their scorecards as the "
        "package's references of that suite.",
    )
    parser.add_argument("names", nargs="*", help="shipped policies [default: all]")
    parser.add_argument("--work", type=Path, default=Path("references-work"),
                        help="folder for the runs (resumable) [default: references-work]")  # fmt: skip
    parser.add_argument("--workers", type=int, default=None, help="worker processes")
    parser.add_argument("--scheduler", default=None,
                        help="a Dask scheduler address or 'local' (as nbv-gym score)")  # fmt: skip
    parser.add_argument("--suite", default=REFERENCE_SUITE.name, choices=list(SUITES),
                        help=f"the suite [default: {REFERENCE_SUITE.name}]")  # fmt: skip
    parser.add_argument("--part", action="append", default=[], metavar="SPLIT",
                        help="score only this part and join it to the existing references "
                        "(repeatable) [default: every reference that lacks it]")  # fmt: skip
    parser.add_argument("--restamp", action="store_true",
                        help="rewrite the references' record of the suite, running nothing")  # fmt: skip
    args = parser.parse_args(argv)
    unknown = sorted(set(args.names) - set(shipped_policies()))
    if unknown:
        parser.error(
            f"not shipped policies: {', '.join(unknown)}; shipped: {', '.join(shipped_policies())}"
        )
    if args.restamp and args.part:
        parser.error("--restamp runs nothing, so it scores no --part; give one or the other")
    suite = get_suite(args.suite)
    try:
        if args.restamp:
            restamp(suite, _stderr)
        elif args.part:
            names = args.names or [
                c["policy"]["name"]
                for c in load_references(suite.name)
                if set(args.part) & set(missing_parts(c))
            ]
            complete(names, args.part, args.work, args.workers, _stderr, suite, args.scheduler)
        else:
            names = args.names or shipped_policies()
            regenerate(names, args.work, args.workers, _stderr, suite, args.scheduler)
    except NbvGymError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
