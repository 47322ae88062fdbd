"""A scorecard's runs are checked against themselves when loaded (:mod:`nbv_gym.benchmark.runchecks`):
every edit of one figure that its episode fixes together with others — the clock, the curves, the
area under Q(t), the 70 % mark, a required figure or a curve's length — is one line naming the
run and the field; every shipped reference passes."""

from __future__ import annotations

import copy
import json

import pytest

from nbv_gym.benchmark.curves import TIME_GRID_S
from nbv_gym.benchmark.references import REFERENCE_DIR, reference_path
from nbv_gym.benchmark.runchecks import area_bounds, inconsistent_run
from nbv_gym.benchmark.validation import ScorecardError, validate_scorecard


@pytest.fixture(scope="module")
def reference() -> dict:
    """The shipped standard closest-frontier reference, as JSON."""
    return json.loads(reference_path("closest-frontier").read_text())


def _time_runs(card):
    return [run for run in card["runs"] if run["task"] == "time"]


def _budget_run(card):
    return next(run for run in card["runs"] if run["task"] == "budget")


def _drive(run, path_m, steps):
    """Set a run's path and scans, with the elapsed time the clock gives them."""
    run.update(path_length_m=path_m, steps=steps, elapsed_s=path_m + 10.0 * steps)


def _each_time_run(key, value):
    def edit(card):
        for run in _time_runs(card):
            run[key] = value(run) if callable(value) else value

    return edit


def _every_run(key, value):
    def edit(card):
        for run in card["runs"]:
            run[key] = value(run) if callable(value) else value

    return edit


#: The round-4 probes' edits (C01-C16) and more of their class, with the words of the refusal.
EDITS = {
    "area doubled (C01)": (
        _each_time_run("q_time_auc", lambda r: min(1.0, 2 * r["q_time_auc"])),
        "q_time_auc is 0.0832231 but its own Q(t) samples bound it to",
    ),
    "area halved": (
        _each_time_run("q_time_auc", lambda r: r["q_time_auc"] / 2),
        "q_time_auc is",
    ),
    "elapsed 1 s (C08)": (_every_run("elapsed_s", 1.0), "elapsed_s is 1 s but its path and scans"),
    "elapsed 5000 s (C09)": (_each_time_run("elapsed_s", 5000.0), "elapsed_s is 5000 s but"),
    "no scans (C10)": (_every_run("steps", 0), "steps 0 × 10 s"),
    "no path (C16)": (_every_run("path_length_m", 0.0), "path_length_m 0 m / 1 m/s"),
    "curves at 0.9 (C12)": (
        _every_run("q_time", lambda r: [0.9] * len(r["q_time"])),
        "q_time[0] is 0.9 but q_path[0] is",
    ),
    "path curve at 0.9": (
        _every_run("q_path", lambda r: [*r["q_path"][:1], *[0.9] * (len(r["q_path"]) - 1)]),
        "past the run's end at",
    ),
    "a time run past its budget": (
        lambda card: _drive(_time_runs(card)[0], 700.0, _time_runs(card)[0]["steps"]),
        "over its part's time budget of 600 s",
    ),
    "a budget run over its scans": (
        lambda card: _drive(_budget_run(card), _budget_run(card)["path_length_m"], 13),
        "steps is 13, more than its part allows (12)",
    ),
    "no Q": (_every_run("q", None), "q is null, but every run measures it"),
    "no discovered fraction": (_every_run("discovered", None), "discovered is null, but every"),
    "no area in a time run": (_each_time_run("q_time_auc", None), "q_time_auc is null in a time"),
    "an area in a budget run": (
        lambda card: _budget_run(card).update(q_time_auc=0.1),
        "q_time_auc is 0.1 in a budget-task run",
    ),
    "Q_paper at 70 % that never was": (
        lambda card: next(r for r in card["runs"] if r["q_paper_70"] is None).update(
            q_paper_70=0.5
        ),
        "q_paper_70 is 0.5 but the run never reached 70 % discovered",
    ),
    "area removed (C03)": (
        lambda card: [run.pop("q_time_auc") for run in card["runs"]],
        "'q_time_auc' is a required property",
    ),
    "area removed from one run (C04)": (
        lambda card: _time_runs(card)[3].pop("q_time_auc"),
        "at runs[3]: 'q_time_auc' is a required property",
    ),
    "elapsed removed (C05)": (
        lambda card: [run.pop("elapsed_s") for run in card["runs"]],
        "'elapsed_s' is a required property",
    ),
    "a 1-point Q(t) (C11)": (
        _every_run("q_time", lambda r: r["q_time"][:1]),
        "q_time: holds 1 values, at least 21 expected",
    ),
    "a longer Q(path)": (
        _every_run("q_path", lambda r: [*r["q_path"], 0.1]),
        "q_path: holds 20 values, at most 19 expected",
    ),
    "a newer protocol (C14)": (
        lambda card: card.update(protocol_version=3),
        "protocol version 3 is newer than this nbv-gym's (2)",
    ),
}


@pytest.mark.parametrize("case", EDITS)
def test_a_run_that_disagrees_with_itself_is_refused_naming_the_run_and_field(reference, case):
    edit, words = EDITS[case]
    card = copy.deepcopy(reference)
    edit(card)
    with pytest.raises(ScorecardError) as error:
        validate_scorecard(card, "cheat/scorecard.json")  # before any aggregate is recomputed
    message = str(error.value)
    assert words in message, message
    assert message.startswith("Scorecard cheat/scorecard.json") and "\n" not in message


def test_the_message_names_the_run(reference):
    card = copy.deepcopy(reference)
    _time_runs(card)[5]["elapsed_s"] += 1.0
    where = r"runs\[5\] \(split time-test, world test-05, noise 0, repeat 0\)"
    with pytest.raises(ScorecardError, match=where + r": elapsed_s is 600\.2\d* s but its path"):
        validate_scorecard(card, "x")


@pytest.mark.parametrize("path", sorted(REFERENCE_DIR.glob("*/*.json")), ids=lambda p: p.stem)
def test_every_shipped_reference_agrees_with_itself(path):
    assert inconsistent_run(json.loads(path.read_text())) is None


def test_the_area_bounds_hold_the_exact_area_of_a_rising_and_of_a_falling_curve():
    from nbv_gym.benchmark.curves import grid_curve
    from nbv_gym.metrics.effort import area_under

    budget = TIME_GRID_S[-1]
    times = [0.0, 13.0, 47.0, 300.5, 580.0]
    for q in ([0.01, 0.02, 0.03, 0.05, 0.06], [0.02, 0.05, 0.04, 0.045, 0.03]):
        curve = grid_curve(times, q, TIME_GRID_S)
        low, high = area_bounds(curve, q[-1], budget)
        assert low <= area_under(times, q, budget) <= high
    rising = [0.01, 0.02, 0.03, 0.05, 0.06]
    high = area_bounds(grid_curve(times, rising, TIME_GRID_S), 0.06, budget)[1]
    assert high < 1.1 * area_under(times, rising, budget)  # a doubled area lies far outside
