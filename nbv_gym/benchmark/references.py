"""Reference scorecards: every shipped policy scored on the standard suite, shipped in
``nbv_gym/benchmark/references/<name>.json``, so that scoring a new policy runs only that policy
and ``nbv-gym leaderboard --references`` ranks it against all of them.

Regenerate them (after a change that moves results; a test says when) with::

    python -m nbv_gym.benchmark.references [NAME ...] [--work DIR] [--workers N] [--scheduler ADDRESS]

which scores each named shipped policy (default: all of :func:`shipped_policies`) with
:func:`~nbv_gym.benchmark.scoring.score_policy` into ``DIR/<name>/`` (resumable, default
``references-work``) and copies its ``scorecard.json`` into the package folder.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from nbv_gym.benchmark.scorecard import load_scorecard
from nbv_gym.benchmark.suites import PROTOCOL_VERSION, STANDARD

#: The folder of the shipped reference scorecards.
REFERENCE_DIR = Path(__file__).with_name("references")
#: The suite the references are scored on.
REFERENCE_SUITE = STANDARD
#: Shipped policies whose reference scorecard is not shipped (yet), with the reason. The
#: leaderboard names them; a test keeps this honest (no file for a pending policy, and every
#: other shipped policy has one). Generate one with ``python -m nbv_gym.benchmark.references
#: NAME`` and delete its entry here.
PENDING: dict[str, str] = {}


def shipped_policies() -> list[str]:
    """Every policy the package ships: the registered ones, then the trained models."""
    from nbv_gym.policies import MODELS, POLICIES

    return [*POLICIES, *MODELS]


def reference_path(name: str) -> Path:
    """The reference scorecard file of the shipped policy ``name``."""
    return REFERENCE_DIR / f"{name}.json"


def load_references() -> list[dict[str, Any]]:
    """The shipped reference scorecards, in :func:`shipped_policies` order (those that exist)."""
    return [
        load_scorecard(reference_path(n), recompute=False)  # package data, tested
        for n in shipped_policies()
        if reference_path(n).is_file()
    ]


def is_current(card: dict[str, Any]) -> bool:
    """Whether the reference scorecard ``card`` belongs to this package's protocol version and
    reference suite (a stale one is never mixed into a leaderboard)."""
    suite = card["suite"]
    return (
        card["protocol_version"] == PROTOCOL_VERSION
        and suite["name"] == REFERENCE_SUITE.name
        and suite["hash"] == REFERENCE_SUITE.content_hash()
    )


def current_references() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(current, stale): the shipped reference scorecards split by :func:`is_current`."""
    cards = load_references()
    return [c for c in cards if is_current(c)], [c for c in cards if not is_current(c)]


def references_pending() -> bool:
    """Whether some shipped reference scorecard is stale (:func:`is_current`): the references
    of this protocol version are still to be generated."""
    return bool(current_references()[1])


def pending_note(stale: list[dict[str, Any]]) -> str:
    """One sentence saying that references for this protocol version are pending, naming the
    versions the ``stale`` ones were scored under ("" if none is stale)."""
    if not stale:
        return ""
    versions = sorted({c["protocol_version"] for c in stale})
    names = ", ".join(c["policy"]["name"] for c in stale)
    return (
        f"References for protocol version {PROTOCOL_VERSION} (suite {REFERENCE_SUITE.name}, "
        f"hash {REFERENCE_SUITE.content_hash()}) are pending: the shipped references of {names} "
        f"were scored under protocol version {', '.join(map(str, versions))} or another suite, "
        "and are left out rather than mixed in (regenerate them: python -m "
        "nbv_gym.benchmark.references)."
    )


def regenerate(
    names: list[str],
    work: Path,
    workers: int | None = None,
    say: Callable[[str], None] = print,
    scheduler: str | None = None,
) -> list[Path]:
    """Score each of ``names`` on :data:`REFERENCE_SUITE` into ``work/<name>`` (locally, or on
    the Dask ``scheduler``) and copy the scorecard into :data:`REFERENCE_DIR`; the written
    reference files."""
    from nbv_gym.benchmark.scoring import score_policy

    written = []
    REFERENCE_DIR.mkdir(exist_ok=True)
    for name in names:
        out = work / name
        score_policy(
            name, REFERENCE_SUITE, out, workers, progress=False, say=say, scheduler=scheduler
        )
        written.append(Path(shutil.copyfile(out / "scorecard.json", reference_path(name))))
        say(f"{name}: reference written to {reference_path(name)}")
    return written


def main(argv: list[str] | None = None) -> None:
    """``python -m nbv_gym.benchmark.references``: see the module docstring."""
    parser = argparse.ArgumentParser(
        prog="python -m nbv_gym.benchmark.references",
        description="Score shipped policies on the standard suite and store their scorecards "
        "as the package's references.",
    )
    parser.add_argument("names", nargs="*", help="shipped policies [default: all]")
    parser.add_argument("--work", type=Path, default=Path("references-work"),
                        help="folder for the runs (resumable) [default: references-work]")  # fmt: skip
    parser.add_argument("--workers", type=int, default=None, help="worker processes")
    parser.add_argument("--scheduler", default=None,
                        help="a Dask scheduler address or 'local' (as nbv-gym score)")  # fmt: skip
    args = parser.parse_args(argv)
    unknown = sorted(set(args.names) - set(shipped_policies()))
    if unknown:
        parser.error(
            f"not shipped policies: {', '.join(unknown)}; shipped: {', '.join(shipped_policies())}"
        )
    regenerate(args.names or shipped_policies(), args.work, args.workers, _stderr, args.scheduler)


def _stderr(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
