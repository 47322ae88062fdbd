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
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from nbv_gym.benchmark.scorecard import load_scorecard
from nbv_gym.benchmark.suites import PROTOCOL_VERSION, STANDARD, SUITES, Suite, get_suite

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


def load_references(suite: str = REFERENCE_SUITE.name) -> list[dict[str, Any]]:
    """The shipped reference scorecards of ``suite``, in :func:`shipped_policies` order (those
    that exist; none for a suite without references)."""
    paths = [reference_path(n, suite) for n in shipped_policies()]
    return [load_scorecard(path, recompute=False) for path in paths if path.is_file()]  # tested


def is_current(card: dict[str, Any], suite: str = REFERENCE_SUITE.name) -> bool:
    """Whether the reference scorecard ``card`` belongs to this package's protocol version and
    to ``suite`` as it is now (a stale one is never mixed into a leaderboard); a suite that is
    not shipped (a test's) is checked by name and version only."""
    shipped = SUITES.get(suite)
    return (
        card["protocol_version"] == PROTOCOL_VERSION
        and card["suite"]["name"] == suite
        and (shipped is None or card["suite"]["hash"] == shipped.content_hash())
    )


def current_references(
    suite: str = REFERENCE_SUITE.name,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(current, stale): the shipped reference scorecards of ``suite`` split by
    :func:`is_current`."""
    cards = load_references(suite)
    return [c for c in cards if is_current(c, suite)], [
        c for c in cards if not is_current(c, suite)
    ]


def pending_note(stale: list[dict[str, Any]], suite: str = REFERENCE_SUITE.name) -> str:
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
    args = parser.parse_args(argv)
    unknown = sorted(set(args.names) - set(shipped_policies()))
    if unknown:
        parser.error(
            f"not shipped policies: {', '.join(unknown)}; shipped: {', '.join(shipped_policies())}"
        )
    suite = get_suite(args.suite)
    regenerate(
        args.names or shipped_policies(), args.work, args.workers, _stderr, suite, args.scheduler
    )


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
