"""What only a re-run proves: a scorecard's runs run again here and compared figure by figure
(``nbv-gym leaderboard --verify N``).

A scorecard's self-checks (:mod:`nbv_gym.benchmark.runchecks`) prove that its figures are those
of *some* episodes. They cannot tell a self-consistent forgery — a run's Q curve and everything
derived from it scaled together — from the policy's own figures. A run is fixed by its suite
(worlds, seeds, settings), its world, noise level and repeat, and the policy's code, which the
card's ``code_hash`` names; so anyone holding the same policy can run it again.
:func:`verify_card` re-runs ``n`` of a card's runs, chosen with a seeded generator (the seed is
stated, so the same choice can be repeated, and a reviewer picks another), in this process with
the sweep worker's own run (:func:`~nbv_gym.sweep.worker.run_here`), and refuses the card at
the first figure that differs (:func:`run_difference`).

The comparison is the one the test suite holds the shipped references to
(``tests/benchmark/test_references.py``): every figure bit for bit (a run gives the same bits on
every x86-64 CPU), the per-run timings not at all.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.benchmark.cardtypes import RunEntry, Scorecard
from nbv_gym.benchmark.suites import Suite
from nbv_gym.core.errors import NbvGymError

#: Figures that time the machine, not the run: never compared.
TIMINGS = ("decision_time_s", "wall_time_s")


class VerifyError(NbvGymError):
    """A scorecard whose sampled runs do not reproduce here, or cannot be run again."""


def run_difference(stored: RunEntry, now: RunEntry) -> str | None:
    """The figures of the ``stored`` run (a scorecard's) that its re-run ``now`` does not give
    bit for bit, each as ``"FIELD: stored X, re-run Y"`` (a curve's first differing point),
    joined by "; "; None if every figure agrees (timings aside; a figure the stored run lacks,
    from an earlier protocol version, is not compared)."""
    moved = []
    for key, held in stored.items():
        if key in TIMINGS:
            continue
        again = now.get(key)
        where = _first_mismatch(held, again)
        if where is not None:
            moved.append(f"{key}{where}: stored {_show(held, where)}, re-run {_show(again, where)}")
    return "; ".join(moved) or None


def _first_mismatch(held: Any, again: Any) -> str | None:
    """``""`` if ``held`` and ``again`` differ (``"[k]"`` at a list's first differing item);
    None if they are the same (null and NaN alike)."""
    if isinstance(held, list) and isinstance(again, list) and len(held) == len(again):
        for k, (a, b) in enumerate(zip(held, again, strict=True)):
            if _first_mismatch(a, b) is not None:
                return f"[{k}]"
        return None
    if _number(held) and _number(again):
        return None if held == again else ""
    return None if (_blank(held) and _blank(again)) or held == again else ""


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _blank(value: Any) -> bool:
    return value is None or (isinstance(value, float) and math.isnan(value))


def _show(value: Any, where: str) -> str:
    if where and isinstance(value, list):
        value = value[int(where[1:-1])]
    return repr(value)


def sample_runs(card: Scorecard, n: int, seed: int) -> list[int]:
    """The indices (sorted) of ``n`` runs of ``card`` (all when it holds fewer), drawn without
    replacement by a generator seeded with ``seed``: the same seed, the same choice."""
    count = len(card["runs"])
    chosen = np.random.default_rng(seed).choice(count, size=min(n, count), replace=False)
    return sorted(int(i) for i in chosen)


def verify_card(
    card: Scorecard,
    suite: Suite,
    source: str,
    indices: list[int],
    say: Callable[[str], None] = lambda message: None,
) -> None:
    """Re-run the runs ``indices`` of ``card`` (a validated scorecard of ``suite``, read from
    ``source``) here and compare each with the card's; :class:`VerifyError` at the first run
    that does not reproduce, cannot run, or whose policy here is not the one the card names."""
    from nbv_gym.benchmark.suiterun import write_world_specs

    _check_policy_code(card, source)
    with tempfile.TemporaryDirectory(prefix="nbv-gym-verify-") as folder:
        sources = write_world_specs(suite, Path(folder) / "worlds")
        for number, index in enumerate(indices, 1):
            run = card["runs"][index]
            say(f"{source}: re-running run {number} of {len(indices)}: {_describe(index, run)}…")
            now, oracle = rerun(card, suite, sources, run)
            problem = run_difference(run, now)
            if problem is None and oracle and not card["policy"]["oracle"]:
                problem = "the policy read privileged values (an oracle), the card says it did not"
            if problem is not None:
                raise VerifyError(
                    f"{source}: {_describe(index, run)} does not reproduce — {problem}. The "
                    f"card's figures are not what {card['policy']['name']} gives here (it was "
                    f"scored with nbv-gym {card['nbv_gym']['version']}, commit "
                    f"{card['nbv_gym']['git_commit']}); refusing it."
                )


def rerun(
    card: Scorecard, suite: Suite, sources: dict[str, str], run: RunEntry
) -> tuple[RunEntry, bool]:
    """The scorecard figures of ``run`` (of ``card``, on ``suite`` whose worlds ``sources``
    names) run again here, and whether the policy ran as an oracle."""
    from nbv_gym.benchmark.suiterun import part_config, run_figures
    from nbv_gym.core.config import to_dict
    from nbv_gym.sweep.worker import RunTask, run_here

    part = suite.part(run["split"])
    config = part_config(suite, part, card["policy"]["name"], sources)
    spec = next(
        s for s in config.runs() if (s.world, s.noise, s.repeat) == (run["world"], run["noise"],
                                                                       run["repeat"])
    )  # fmt: skip
    env = to_dict(config.env_config(spec.world_source, spec.noise))
    try:
        outcome = run_here(RunTask(spec, env))
    except NbvGymError:
        raise
    except Exception as error:  # the policy's own failure: the card cannot be verified here
        raise VerifyError(
            f"re-running {spec.key} failed ({type(error).__name__}: {error}); a card whose runs "
            "cannot run again here is not verified."
        ) from None
    return run_figures(part, outcome), bool(outcome["run"]["oracle"])


def _check_policy_code(card: Scorecard, source: str) -> None:
    """:class:`VerifyError` unless the card's policy loads here from the very code it was scored
    with (its ``code_hash``): a re-run of other code proves nothing about the card."""
    from nbv_gym.benchmark.scorecard import file_hash, policy_file

    policy = card["policy"]
    path = policy_file(policy["name"])
    here = file_hash(path) if path is not None and path.is_file() else None
    if here != policy["code_hash"]:
        raise VerifyError(
            f"{source}: the policy {policy['name']!r} here ({path or 'no source file'}, code "
            f"hash {str(here)[:16]}) is not the code the card was scored with (code hash "
            f"{str(policy['code_hash'])[:16]}); --verify re-runs the card's own policy: run it "
            "where that code is."
        )


def _describe(index: int, run: RunEntry) -> str:
    return (
        f"runs[{index}] (split {run['split']}, world {run['world']}, noise {run['noise']}, "
        f"repeat {run['repeat']})"
    )


def verify_entries(
    entries: list[Any], n: int, seed: int, say: Callable[[str], None] = lambda message: None
) -> list[str]:
    """Re-run ``n`` sampled runs (:func:`sample_runs` with ``seed``) of each scorecard given on
    the command line among the leaderboard's ``entries`` (:class:`~nbv_gym.benchmark.ranking.Entry`;
    the shipped references are the test suite's to re-run); one line per card saying which runs
    reproduced. :class:`VerifyError` for a card that does not reproduce, whose suite nbv-gym
    does not ship (its worlds cannot be rebuilt from the card), or when no card is given."""
    from nbv_gym.benchmark.suites import shipped_suite

    given = [entry for entry in entries if not entry.reference]
    if not given:
        raise VerifyError("--verify re-runs the scorecards given on the command line; give one.")
    notes = []
    for entry in given:
        suite = shipped_suite(entry.card["suite"])
        if suite is None:
            raise VerifyError(
                f"{entry.source}: --verify re-runs runs of the suites nbv-gym ships; suite "
                f"{entry.card['suite']['name']!r} (your own worlds) cannot be rebuilt from the "
                "card, which names its worlds but does not hold them."
            )
        indices = sample_runs(entry.card, n, seed)
        verify_card(entry.card, suite, entry.source, indices, say)
        notes.append(
            f"{entry.source}: {len(indices)} of its {len(entry.card['runs'])} runs re-run here "
            f"reproduce (seed {seed}: runs {', '.join(map(str, indices))})"
        )
    return notes
