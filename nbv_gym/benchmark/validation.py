"""Scorecards checked before they are trusted: a leaderboard ranks only what its runs support.

:func:`validate_scorecard` runs on every scorecard :func:`~nbv_gym.benchmark.scorecard.load_scorecard`
reads (the shipped references too) and refuses, in one line naming the file and the field:

1. anything the shipped JSON schema (``scorecard.schema.json``) does not allow: a wrong type,
   a missing or unknown field (from protocol version 2 on, every run's elapsed time, area under
   Q(t) and both curves, each of its grid's length), a number out of range, another format or
   schema; a protocol version newer than this nbv-gym's;
2. runs that are not the suite's: a run twice, a run of no part, a part without its runs;
3. runs that disagree with themselves (:mod:`nbv_gym.benchmark.runchecks`: the clock against
   path and scans, the curves against the final Q, the area against its own Q(t) samples);
4. aggregates that its runs do not give (for every scorecard given on the command line; the
   shipped references are package files, checked against their runs by the test suite): every aggregate is recomputed from the runs with the
   scorecard module's own :func:`~nbv_gym.benchmark.scorecard.card_aggregates`, which its
   loader passes in (so a new aggregate is checked as soon as it is computed there), and
   compared field by field.

NaN and Infinity never get this far: scorecards are read as strict JSON
(:func:`nbv_gym.core.inputs.read_json`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path
from typing import Any

from nbv_gym.benchmark.cardtypes import Aggregate, PartDescription, PartEntry, RunEntry, Scorecard
from nbv_gym.core.errors import NbvGymError

#: The JSON schema of a scorecard (package data).
SCHEMA_PATH = Path(__file__).with_name("scorecard.schema.json")

#: Relative tolerance of a recomputed aggregate (the bootstrap is seeded, so the same runs give
#: the same figures; the tolerance absorbs the last bits of another machine's summation order).
AGGREGATE_RTOL = 1e-9
#: ``aggregates(runs, parts)``: the aggregates a card's runs give (the scorecard module's
#: :func:`~nbv_gym.benchmark.scorecard.card_aggregates`, passed in by its loader).
Aggregates = Callable[[Sequence[RunEntry], Sequence[PartDescription]], dict[str, Aggregate]]


class ScorecardError(NbvGymError):
    """A scorecard file is unreadable, not a scorecard, or not supported by its own runs; the
    message names the file and the field."""


def validate_scorecard(
    card: Any, path: str | Path, aggregates: Aggregates | None = None
) -> Scorecard:
    """``card`` after checking it against the schema, its runs against its suite's parts and
    (given ``aggregates``, the function that computes them) its aggregates against those its
    runs give (about 1 s a card: the bootstrap); :class:`ScorecardError` naming ``path`` and
    the first field that fails otherwise."""
    _check_schema(card, path)
    _check_version(card, path)
    _check_runs(card, path)
    _check_run_figures(card, path)
    if aggregates is not None:
        _check_aggregates(card, path, aggregates)
    return card


@cache
def _validator():
    from jsonschema import Draft202012Validator

    return Draft202012Validator(json.loads(SCHEMA_PATH.read_text(encoding="utf-8")))


def _check_schema(card: Any, path: str | Path) -> None:
    from jsonschema.exceptions import best_match

    error = best_match(_validator().iter_errors(card))
    if error is not None:
        where = _field(error.absolute_path) or "the top level"
        raise ScorecardError(
            f"Scorecard {path} does not fit the scorecard schema at {where}: "
            f"{_schema_problem(error)}; score the policy again with `nbv-gym score`."
        )


def _schema_problem(error) -> str:
    """jsonschema's message, shortened; an array of the wrong length by its length (the
    message would quote the whole array)."""
    if error.validator in ("minItems", "maxItems") and isinstance(error.instance, list):
        bound = "at least" if error.validator == "minItems" else "at most"
        return f"holds {len(error.instance)} values, {bound} {error.validator_value} expected"
    return _short(error.message)


def _check_version(card: Scorecard, path: str | Path) -> None:
    """A card of a protocol version this nbv-gym does not implement yet is refused: its figures
    follow rules unknown here, which would check and rank them under this version's."""
    from nbv_gym.benchmark.suites import PROTOCOL_VERSION

    version = card["protocol_version"]
    if version > PROTOCOL_VERSION:
        raise ScorecardError(
            f"Scorecard {path}: protocol version {version} is newer than this nbv-gym's "
            f"({PROTOCOL_VERSION}); rank it with the nbv-gym that scored it "
            f"({card['nbv_gym']['version']}) or a newer one."
        )


def _check_runs(card: Scorecard, path: str | Path) -> None:
    """Each run belongs to one part of the suite and appears once; each part has all its runs."""
    parts = {part["split"]: part for part in card["suite"]["parts"]}
    seen: dict[tuple, int] = {}
    for i, run in enumerate(card["runs"]):
        key = (run["split"], run["world"], run["noise"], run["repeat"])
        part = parts.get(run["split"])
        if key in seen:
            raise ScorecardError(
                f"Scorecard {path}: runs[{i}] repeats runs[{seen[key]}] (split {key[0]}, world "
                f"{key[1]}, noise {key[2]}, repeat {key[3]}); each run counts once."
            )
        seen[key] = i
        if part is None or not _in_part(run, part):
            raise ScorecardError(
                f"Scorecard {path}: runs[{i}] (split {key[0]}, world {key[1]}, noise {key[2]}, "
                f"repeat {key[3]}, task {run['task']}) is not a run of the suite's parts."
            )
    for split, part in parts.items():
        held = sum(1 for key in seen if key[0] == split)
        expected = len(part["worlds"]) * len(part["noise"]) * part["repeats"]
        if held != expected or part["runs"] != expected:
            raise ScorecardError(
                f"Scorecard {path}: the {split} split holds {held} runs; its part lists "
                f"{part['runs']} and {len(part['worlds'])} worlds × {len(part['noise'])} noise "
                f"levels × {part['repeats']} repeats make {expected}."
            )
    if len(parts) < len(card["suite"]["parts"]):
        raise ScorecardError(f"Scorecard {path}: suite.parts names a split twice.")


def _check_run_figures(card: Scorecard, path: str | Path) -> None:
    """Each run agrees with itself (:func:`~nbv_gym.benchmark.runchecks.inconsistent_run`)."""
    from nbv_gym.benchmark.runchecks import inconsistent_run

    found = inconsistent_run(card)
    if found is not None:
        index, problem = found
        run = card["runs"][index]
        raise ScorecardError(
            f"Scorecard {path}: runs[{index}] (split {run['split']}, world {run['world']}, noise "
            f"{run['noise']}, repeat {run['repeat']}): {problem}; the run's figures were edited "
            "or do not come from one nbv-gym episode. Score the policy again with `nbv-gym score`."
        )


def _in_part(run: RunEntry, part: PartEntry) -> bool:
    return (
        run["task"] == part["task"]
        and run["world"] in part["worlds"]
        and run["noise"] in part["noise"]
        and run["repeat"] < part["repeats"]
    )


def _check_aggregates(card: Scorecard, path: str | Path, aggregates: Aggregates) -> None:
    """Every aggregate equals the one its runs give (within :data:`AGGREGATE_RTOL`)."""
    expected = aggregates(card["runs"], card["suite"]["parts"])
    mismatch = _first_difference(card["aggregates"], expected, ("aggregates",))
    if mismatch is not None:
        where, held, computed = mismatch
        raise ScorecardError(
            f"Scorecard {path}: {where} is {_short(held)} but its runs give {_short(computed)}; "
            "the aggregates were edited or come from other runs. Score the policy again."
        )


def _first_difference(held: Any, computed: Any, where: tuple) -> tuple[str, Any, Any] | None:
    """(field, held, computed) of the first field where ``held`` and ``computed`` differ."""
    if isinstance(computed, dict) and isinstance(held, dict):
        for key in dict.fromkeys([*computed, *held]):
            if key not in held or key not in computed:
                return _field((*where, key)), held.get(key, "missing"), computed.get(key, "none")
            found = _first_difference(held[key], computed[key], (*where, key))
            if found is not None:
                return found
        return None
    return None if _same(held, computed) else (_field(where), held, computed)


def _same(held: Any, computed: Any) -> bool:
    computed = None if isinstance(computed, float) and not math.isfinite(computed) else computed
    if isinstance(held, bool) or isinstance(computed, bool) or not _is_number(computed):
        return held == computed
    if not _is_number(held):
        return False
    return math.isclose(held, computed, rel_tol=AGGREGATE_RTOL, abs_tol=AGGREGATE_RTOL)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _field(parts) -> str:
    """``aggregates.test.all.iqm``, ``runs[3].q``: a field's dotted path."""
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _short(value: Any, limit: int = 120) -> str:
    text = " ".join(str(value).split())
    return text if len(text) <= limit else text[: limit - 1] + "…"
