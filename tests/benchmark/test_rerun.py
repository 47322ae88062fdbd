"""What only a re-run proves (``nbv-gym leaderboard --verify N``, :mod:`nbv_gym.benchmark.rerun`):
a scorecard edited consistently with itself passes every self-check and is refused once one of
its edited runs is run again; an untouched shipped reference reproduces."""

from __future__ import annotations

import copy
import json
import math

import pytest

from nbv_gym.benchmark.references import reference_path
from nbv_gym.benchmark.rerun import (
    VerifyError,
    run_difference,
    sample_runs,
    verify_entries,
)
from nbv_gym.benchmark.scorecard import card_aggregates, load_scorecard
from tests.helpers import invoke

RUN = {"steps": 12, "end_reason": "reached max_steps = 12", "path_length_m": 31.25,
       "elapsed_s": 151.25, "q": 0.04, "q_paper": 0.03, "q_paper_70": None,
       "q_time": [0.01, 0.02, 0.04], "q_time_auc": None, "wall_time_s": 3.0}  # fmt: skip


@pytest.mark.parametrize(
    ("edit", "found"),
    [
        ({"steps": 13}, "steps: stored 12, re-run 13"),
        ({"end_reason": "no valid goal is reachable"}, "end_reason: stored"),
        ({"path_length_m": 31.25 + 1e-12}, "path_length_m: stored 31.25"),  # decisions exactly
        ({"q": 0.04 * (1 + 1e-15)}, "q: stored 0.04"),  # every figure bit for bit
        ({"q_time": [0.01, 0.03, 0.04]}, "q_time[1]: stored 0.02, re-run 0.03"),
        ({"q_time": [0.01, 0.02]}, "q_time: stored [0.01, 0.02, 0.04]"),
        ({"q_paper_70": 0.02}, "q_paper_70: stored None, re-run 0.02"),
    ],
)
def test_a_rerun_that_differs_names_the_figure(edit, found):
    assert found in run_difference(RUN, {**RUN, **edit})


def test_a_rerun_names_every_figure_that_moved():
    moved = run_difference(RUN, {**RUN, "q": 0.05, "q_time": [0.01, 0.02, 0.05]})
    assert moved == "q: stored 0.04, re-run 0.05; q_time[2]: stored 0.04, re-run 0.05"


def test_a_rerun_with_the_same_bits_and_other_timings_agrees():
    again = {**RUN, "q_paper_70": math.nan, "wall_time_s": 9.0}
    assert run_difference(RUN, again) is None
    assert run_difference(RUN, {**RUN, "new_figure": 1.0}) is None  # a newer version's figure


def test_the_runs_chosen_follow_the_seed_and_are_stated():
    card = {"runs": [{}] * 612}
    assert sample_runs(card, 3, 7) == sample_runs(card, 3, 7) != sample_runs(card, 3, 8)
    assert sample_runs(card, 3, 7) == sorted(set(sample_runs(card, 3, 7)))
    assert sample_runs({"runs": [{}] * 2}, 5, 0) == [0, 1]


def test_a_card_of_your_own_worlds_or_none_given_cannot_be_verified(tiny_suite):
    from nbv_gym.benchmark.ranking import Entry
    from tests.benchmark.test_leaderboard import card

    with pytest.raises(VerifyError, match="re-runs the scorecards given on the command line"):
        verify_entries([Entry("ref", card(tiny_suite, "ref", 0.3), "references")], 1, 0)
    own = Entry("mine", card(tiny_suite, "mine", 0.3), "mine.json")
    with pytest.raises(VerifyError, match=r"mine\.json: --verify re-runs runs of the suites"):
        verify_entries([own], 1, 0)


def test_a_card_whose_policy_code_is_not_here_is_refused():
    from nbv_gym.benchmark.ranking import Entry

    card = json.loads(reference_path("closest-frontier").read_text())
    card["policy"]["code_hash"] = "0" * 64
    with pytest.raises(VerifyError, match="is not the code the card was scored with"):
        verify_entries([Entry("cf", card, "cf.json")], 1, 0)


#: The seed whose one run of the closest-frontier reference is a budget run (12 scans: cheap).
SEED, INDEX = 12, 441


def _forged(card: dict, index: int, factor: float = 1.2) -> dict:
    """``card`` with run ``index``'s Q and every figure computed from it scaled by ``factor``,
    consistently (its curves, their final value, Q_paper), and the aggregates recomputed."""
    card = copy.deepcopy(card)
    run = card["runs"][index]
    final = round(round(run["q"], 7) * factor, 7)
    run.update(
        q=final,
        q_paper=run["q_paper"] * factor,
        q_time=[round(v * factor, 7) for v in run["q_time"]],
        q_path=[round(v * factor, 7) for v in run["q_path"]],
    )
    if run["q_paper_70"] is not None:
        run["q_paper_70"] *= factor
    card["aggregates"] = card_aggregates(card["runs"], card["suite"]["parts"])
    return card


@pytest.mark.slow  # two runs of 12 scans and a card's aggregates: about a minute
def test_a_self_consistent_forgery_is_refused_by_verify_and_the_reference_passes(
    tmp_path, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    reference = json.loads(reference_path("closest-frontier").read_text())
    assert sample_runs(reference, 1, SEED) == [INDEX]
    assert reference["runs"][INDEX]["task"] == "budget"
    (tmp_path / "forged.json").write_text(json.dumps(_forged(reference, INDEX)))
    load_scorecard(tmp_path / "forged.json")  # every self-check passes
    verify = ["--verify", "1", "--verify-seed", str(SEED)]
    refused = invoke("leaderboard", "forged.json", *verify, "--out", "b1")
    assert refused.code == 2 and "Traceback" not in refused.err, refused.err
    assert f"forged.json: runs[{INDEX}] (split benchmark, world " in refused.err
    assert "does not reproduce — q: stored" in refused.err and not (tmp_path / "b1").exists()
    passed = invoke("leaderboard", reference_path("closest-frontier"), *verify, "--out", "b2")
    assert passed.code == 0, passed.err
    assert f"1 of its 720 runs re-run here reproduce (seed {SEED}: runs {INDEX})" in passed.out
    assert "sampled runs were re-run here" in (tmp_path / "b2" / "leaderboard.md").read_text()
