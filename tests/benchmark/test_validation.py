"""Scorecards are checked before a leaderboard trusts them (:mod:`nbv_gym.benchmark.validation`):
every tampering — an edited aggregate, a wrong type, NaN, a foreign schema, runs missing,
repeated or foreign, the same file twice, no test split — is one line naming the file and the
field, and names from a file cannot inject rows into leaderboard.md."""

from __future__ import annotations

import copy
import json

import pytest

from nbv_gym.benchmark.leaderboard import (
    LeaderboardError,
    build_leaderboard,
    gather,
    leaderboard_markdown,
)
from nbv_gym.benchmark.scorecard import (
    ScorecardError,
    card_aggregates,
    dumps_strict,
    load_scorecard,
)
from nbv_gym.benchmark.validation import validate_scorecard
from nbv_gym.cli.main import app
from nbv_gym.core.errors import NbvGymError
from nbv_gym.reporting.formatting import markdown_code, markdown_text
from tests.benchmark.test_leaderboard import card


def _set(path: str, value):
    """An edit that sets the field ``path`` (dots; ``runs.0.q``) of a card to ``value``."""

    def edit(data):
        *parents, last = path.split(".")
        for key in parents:
            data = data[int(key)] if isinstance(data, list) else data[key]
        if isinstance(data, list):
            data[int(last)] = value
        else:
            data[last] = value

    return edit


def _delete_test_split(data):
    data["suite"]["parts"] = [p for p in data["suite"]["parts"] if p["split"] != "time-test"]
    data["runs"] = [r for r in data["runs"] if r["split"] != "time-test"]
    del data["aggregates"]["time-test"]  # the tiny suite's only time-task split


#: Tamperings of a scorecard file's JSON and the words of the refusal.
TAMPERED = {
    "edited IQM": (_set("aggregates.test.all.iqm", 0.99), "aggregates.test.all.iqm is 0.99 but"),
    "edited interval": (_set("aggregates.test.all.iqm_high", 0.98), "aggregates.test.all.iqm_high"),
    "edited count": (_set("aggregates.benchmark.all.n", 7), "aggregates.benchmark.all.n is 7"),
    "edited mean figure": (_set("aggregates.test.means.path_length_m", 1.0), "means.path_length_m"),
    "edited asset": (_set("aggregates.test.by_asset.crosses.mean", 0.5), "by_asset.crosses.mean"),
    "a run edited after scoring": (_set("runs.2.q_paper", 0.9), "but its runs give"),
    "a final Q its curves do not end at": (_set("runs.2.q", 0.9), "but its final Q is 0.9"),
    "a string for a number": (_set("runs.0.q", "0.3"), "runs[0].q: '0.3' is not of type"),
    "a boolean for a count": (_set("runs.0.steps", True), "runs[0].steps"),
    "a score above 1": (_set("runs.0.q", 7.0), "runs[0].q: 7.0 is greater than the maximum"),
    "a string protocol": (_set("protocol_version", "1"), "protocol_version"),
    "an oracle flag of text": (_set("policy.oracle", "no"), "policy.oracle"),
    "a foreign field": (_set("injected", 1), "'injected' was unexpected"),
    "a foreign format": (_set("format", "other scorecard"), "not an nbv-gym scorecard"),
    "no runs": (_set("runs", []), "split holds 0 runs"),
    "a run twice": (_set("runs.1", "COPY0"), "runs[1] repeats runs[0]"),
    "a run of no part": (
        _set("runs.0.world", "elsewhere"),
        "is not a run of the suite's parts",
    ),
    "a part claiming more runs": (_set("suite.parts.0.runs", 3), "its part lists 3"),
    "an aggregate of no part": (_set("aggregates.extra", "COPYTEST"), "aggregates.extra"),
}


def _tampered(tiny_suite, tmp_path, edit) -> object:
    data = json.loads(dumps_strict(card(tiny_suite, "mine", 0.3)))
    edit(data)
    if data.get("runs") and data["runs"][1:] and data["runs"][1] == "COPY0":
        data["runs"][1] = copy.deepcopy(data["runs"][0])
    if data["aggregates"].get("extra") == "COPYTEST":
        data["aggregates"]["extra"] = copy.deepcopy(data["aggregates"]["test"])
    path = tmp_path / "scorecard.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("case", TAMPERED)
def test_a_tampered_scorecard_is_refused_naming_the_field(tiny_suite, tmp_path, case):
    edit, words = TAMPERED[case]
    path = _tampered(tiny_suite, tmp_path, edit)
    with pytest.raises(NbvGymError) as error:
        gather([path], references=False)
    message = str(error.value)
    assert words in message and str(path) in message and "\n" not in message


@pytest.mark.parametrize("constant", ["NaN", "Infinity", "-Infinity"])
def test_a_scorecard_holding_a_constant_json_lacks_is_refused(tiny_suite, tmp_path, constant):
    path = tmp_path / "scorecard.json"
    path.write_text(dumps_strict(card(tiny_suite, "mine", 0.3)).replace("0.001", constant, 1))
    with pytest.raises(NbvGymError, match=f"{constant} is not JSON"):
        gather([path], references=False)


def test_the_same_file_twice_is_refused(tiny_suite, tmp_path):
    path = _tampered(tiny_suite, tmp_path, lambda data: None)
    with pytest.raises(LeaderboardError, match="given twice"):
        gather([path, tmp_path, tmp_path / "." / "scorecard.json"], references=False)


def test_a_scorecard_without_a_test_split_is_refused(tiny_suite, tmp_path):
    path = _tampered(tiny_suite, tmp_path, _delete_test_split)
    with pytest.raises(
        LeaderboardError, match="has no time-task split \\(time-test or time-benchmark\\)"
    ):
        gather([path], references=False)


def test_an_untouched_scorecard_passes(tiny_suite, tmp_path):
    path = _tampered(tiny_suite, tmp_path, lambda data: None)
    assert [e.label for e in gather([path], references=False)] == ["mine"]


@pytest.mark.parametrize("case", ["edited IQM", "a string for a number", "a run twice"])
def test_the_cli_refuses_a_tampered_scorecard_in_one_line(tiny_suite, tmp_path, capsys, case):
    path = _tampered(tiny_suite, tmp_path, TAMPERED[case][0])
    with pytest.raises(SystemExit) as exit:
        app(["leaderboard", str(path), "--out", str(tmp_path / "board")], prog_name="nbv-gym")
    err = capsys.readouterr().err
    assert exit.value.code == 2 and len(err.strip().splitlines()) == 1
    assert err.startswith("Error: Scorecard") and not (tmp_path / "board").exists()


@pytest.mark.parametrize(
    "name",
    ["evil\n| 1 | **injected** | 1.0 |", "a|b|c", "back`tick``s", "![x](/etc/passwd)", "\r\u2028"],
)
def test_a_policy_name_cannot_inject_rows_or_markup(tiny_suite, tmp_path, name):
    honest = card(tiny_suite, "honest", 0.3)
    path = tmp_path / "scorecard.json"
    path.write_text(dumps_strict(card(tiny_suite, name, 0.5)))
    (tmp_path / "honest.json").write_text(dumps_strict(honest))
    board = build_leaderboard([path, tmp_path / "honest.json"], False, tmp_path / "b")
    markdown, html = board.markdown, board.html
    text = markdown.read_text()
    rows = [line for line in text.splitlines() if line.startswith("| ")]
    assert len(rows) == 2 * 3  # two tables: a header and two policies each
    assert all(row.count(" | ") == rows[0].count(" | ") for row in rows[:3])
    page = html.read_text()
    assert "injected</strong>" not in page and 'src="/etc/passwd' not in page


def test_the_shipped_references_pass_and_their_leaderboard_is_unchanged_by_escaping(monkeypatch):
    """Every reference's aggregates are what its runs give, and escaping names changes nothing
    for the shipped names: the reference leaderboard is the one written with plain backticks."""
    from nbv_gym.benchmark import leaderboard
    from nbv_gym.benchmark.references import REFERENCE_DIR

    for path in sorted(REFERENCE_DIR.glob("*.json")):
        data = json.loads(path.read_text())
        validate_scorecard(data, path, card_aggregates)  # recomputes every aggregate
        assert (
            card_aggregates(data["runs"], data["suite"]["parts"]).keys()
            == data["aggregates"].keys()
        )
    from nbv_gym.benchmark.references import current_references

    if not current_references()[0]:
        pytest.skip("the references of this protocol version are pending")
    entries = gather([], references=True)
    names = [e.label for e in entries] + [entries[0].card["suite"]["description"]]
    assert all(markdown_text(n) == n and markdown_code(n) == f"`{n}`" for n in names)
    escaped = leaderboard_markdown(entries)
    monkeypatch.setattr(leaderboard, "markdown_code", lambda text: f"`{text}`")
    monkeypatch.setattr(leaderboard, "markdown_text", str)
    assert escaped == leaderboard_markdown(entries)


def test_validation_needs_no_copy_of_the_aggregation(tiny_suite, monkeypatch, tmp_path):
    """A new aggregate computed by the scorecard module is checked at once: validation calls the
    scorecard module's own function (one home)."""
    from nbv_gym.benchmark import scorecard

    original = scorecard.aggregate

    def with_more(runs, split, metric):
        return {**original(runs, split, metric), "new": 0.123}

    path = _tampered(tiny_suite, tmp_path, lambda data: None)
    monkeypatch.setattr(scorecard, "aggregate", with_more)
    with pytest.raises(ScorecardError, match=r"aggregates\.[a-z-]+\.new is missing"):
        load_scorecard(path)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda suite: suite["parts"][3].update(budget_scans=20), "parts"),  # hash kept
        (lambda suite: suite.update(hash="0123456789abcdef"), "hash"),  # another nbv-gym's
        (lambda suite: suite.update(seed=1), "seed"),
    ],
)
def test_a_card_of_a_shipped_suite_records_that_suite_as_this_nbv_gym_defines_it(
    tmp_path, edit, field
):
    from nbv_gym.benchmark.suites import QUICK
    from tests.benchmark.test_leaderboard import write

    good = card(QUICK, "fine", 0.3)
    assert [e.label for e in gather([write(tmp_path, good)], references=False)] == ["fine"]
    vlp = card(QUICK.with_lidar("vlp-16"), "vlp", 0.3)  # another lidar: that suite's identity
    assert gather([write(tmp_path, vlp)], references=False)[0].label == "vlp"
    edited = card(QUICK, "edited", 0.3)
    edit(edited["suite"])
    with pytest.raises(LeaderboardError, match=rf"differs from this nbv-gym's \(suite\.{field}\)"):
        gather([write(tmp_path, edited)], references=False)
