"""``nbv-gym leaderboard`` on hand-made scorecards: ranking, oracles, refusals, files."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import pytest

from nbv_gym.benchmark.leaderboard import (
    LeaderboardError,
    baseline,
    build_leaderboard,
    check_comparable,
    gather,
    improvement,
    leaderboard_summary,
    pareto_dominated,
)
from nbv_gym.benchmark.ranking import Entry, ranked
from nbv_gym.benchmark.scorecard import build_scorecard, dumps_strict
from nbv_gym.benchmark.suites import STANDARD


def card(
    suite,
    name: str,
    level: float,
    oracle: bool = False,
    version: int | None = None,
    path_m: float = 10.0,
):
    """A scorecard of ``suite`` whose runs score ``level`` + a small spread per repeat (Q, and
    the area under Q(t) on time parts), driving ``path_m`` metres in 2 scans (consistent with
    itself: the clock, the curves and the area agree)."""
    from nbv_gym.benchmark.curves import PATH_GRID_M, TIME_GRID_S

    runs = []
    for part in suite.parts:
        for world in part.world_names:
            for noise in part.noise:
                for repeat in range(part.repeats):
                    q = level + 0.01 * repeat
                    runs.append(
                        dict(
                            split=part.split,
                            task=part.task.name,
                            world=world,
                            asset="crosses",
                            noise=noise,
                            repeat=repeat,
                            seed=repeat,
                            steps=2,
                            end_reason="reached max_steps = 2",
                            q=q,
                            q_paper=q,
                            q_paper_70=q,
                            discovered=0.75,
                            path_length_m=path_m,
                            elapsed_s=path_m + 20.0,
                            q_time_auc=q if part.task.name == "time" else None,
                            q_time=[round(q, 7)] * len(TIME_GRID_S),  # curves are rounded
                            q_path=[round(q, 7)] * len(PATH_GRID_M),
                            decision_time_s=0.001,
                            wall_time_s=0.1,
                        )
                    )
    policy = {
        "name": name,
        "class": "m:C",
        "oracle": oracle,
        "hashed_file": None,
        "code_hash": None,
    }
    scorecard = build_scorecard(suite, policy, runs, {"wall_time_s": 1.0, "workers": 1})
    if version is not None:
        scorecard["protocol_version"] = version
    return scorecard


def write(tmp_path, scorecard) -> object:
    folder = tmp_path / scorecard["policy"]["name"].replace(":", "_")
    folder.mkdir()
    (folder / "scorecard.json").write_text(dumps_strict(scorecard))
    return folder


def test_entries_rank_by_test_iqm_with_oracles_apart(tiny_suite, tmp_path):
    paths = [
        write(tmp_path, card(tiny_suite, "low", 0.2)),
        write(tmp_path, card(tiny_suite, "high", 0.6)),
        write(tmp_path, card(tiny_suite, "peek:Oracle", 0.9, oracle=True)),
        write(tmp_path, card(tiny_suite, "mid", 0.4)),
    ]
    entries = gather(paths, references=False)
    players, oracles = ranked(entries)
    assert [e.label for e in players] == ["high", "mid", "low"]
    assert [e.label for e in oracles] == ["peek:Oracle"]
    best = baseline(entries)  # no reference given: the best entry that is not an oracle
    assert best.label == "high"
    # every run of mid (0.40, 0.41) loses to every run of high (0.60, 0.61) on every task
    poi = improvement(players[1], best)
    assert (poi.mean, poi.low, poi.high) == (0.0, 0.0, 0.0)
    assert improvement(oracles[0], best).mean == 1.0


def test_leaderboard_writes_markdown_html_and_profiles(tiny_suite, tmp_path):
    paths = [write(tmp_path, card(tiny_suite, n, q)) for n, q in (("a", 0.3), ("b", 0.5))]
    paths.append(write(tmp_path, card(tiny_suite, "peek:Oracle", 0.9, oracle=True)))
    board = build_leaderboard(paths, False, tmp_path / "board")
    markdown, html = board.markdown, board.html
    text = markdown.read_text()
    assert text.index("| 1 | **`b`**") < text.index("| 2 | **`a`**")
    assert "## Oracles (ranked apart)" in text and "| oracle | **`peek:Oracle`**" in text
    assert "P(better than b, equal time)" in text and "0.00 [0.00, 0.00]" in text
    assert html.name == "leaderboard.html" and "<table>" in html.read_text()
    assert (tmp_path / "board" / "profiles.png").stat().st_size > 0
    assert "data:image/svg+xml;base64" in html.read_text()  # the figure travels with the page


def test_a_suite_on_your_own_worlds_ranks_by_its_time_task(tiny_suite, tmp_path):
    # nbv-gym score --world keeps the parts on the benchmark worlds: no test split
    time = replace(tiny_suite.part("time-test"), split="time-benchmark", worlds=("pp1-cuboids",))
    own = replace(tiny_suite, name="tiny-own", parts=(time, tiny_suite.part("benchmark")))
    paths = [write(tmp_path, card(own, n, q)) for n, q in (("a", 0.3), ("b", 0.5))]
    assert [e.rank_split for e in gather(paths, references=False)] == ["time-benchmark"] * 2
    text = build_leaderboard(paths, False, tmp_path / "board").markdown.read_text()
    assert "equal time, benchmark: IQM area under Q(t)" in text
    assert text.index("| 1 | **`b`**") < text.index("| 2 | **`a`**")


def test_a_policy_scored_twice_gets_two_labelled_entries(tiny_suite, tmp_path):
    first = write(tmp_path, card(tiny_suite, "a", 0.3))
    second = tmp_path / "again.json"
    second.write_text(dumps_strict(card(tiny_suite, "a", 0.4)))
    labels = [e.label for e in gather([first, second], references=False)]
    assert labels == ["a", f"a ({second})"]


def test_scorecards_of_different_suites_are_refused_naming_them(tiny_suite, tmp_path):
    other = replace(tiny_suite, name="other", seed=1)
    a = write(tmp_path, card(tiny_suite, "a", 0.3))
    b = write(tmp_path, card(other, "b", 0.3))
    with pytest.raises(LeaderboardError, match="different suites or protocol versions") as error:
        gather([a, b], references=False)
    message = str(error.value)
    assert f"suite tiny (hash {tiny_suite.content_hash()}, lidar os1-16)" in message
    assert f"suite other (hash {other.content_hash()}, lidar os1-16)" in message


def test_scorecards_of_different_protocol_versions_are_refused(tiny_suite, tmp_path):
    a = write(tmp_path, card(tiny_suite, "a", 0.3))
    b = write(tmp_path, card(tiny_suite, "b", 0.3, version=1))
    with pytest.raises(LeaderboardError, match=r"protocol version 2; .*protocol version 1"):
        gather([a, b], references=False)


def test_nothing_to_rank_is_an_error():
    with pytest.raises(LeaderboardError, match="No scorecard to rank"):
        gather([], references=False)


def test_the_cli_refuses_mixed_suites_in_one_line(tiny_suite, tmp_path):
    a = write(tmp_path, card(tiny_suite, "a", 0.3))
    b = write(tmp_path, card(replace(tiny_suite, seed=3), "b", 0.3))
    result = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "leaderboard", str(a), str(b), "--out", str(tmp_path / "o")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 2 and "Cannot merge scorecards" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "o").exists()


def test_entry_scores_are_nan_when_a_split_is_missing(tiny_suite):
    scorecard = card(tiny_suite, "a", 0.3)
    del scorecard["aggregates"]["time-test"]
    assert Entry("a", scorecard, "x").score() != Entry("a", scorecard, "x").score()  # NaN


def test_the_board_ranks_by_the_time_task_marks_the_pareto_front_and_draws_q_t(
    tiny_suite, tmp_path
):
    paths = [
        write(tmp_path, card(tiny_suite, "near", 0.3, path_m=10.0)),
        write(tmp_path, card(tiny_suite, "far", 0.5, path_m=18.0)),  # within the 40 s budget
        write(tmp_path, card(tiny_suite, "worse", 0.2, path_m=14.0)),  # near: more Q, less path
        write(tmp_path, card(tiny_suite, "cm-shorter", 0.25, path_m=9.96)),  # the same metre
    ]
    entries = gather(paths, references=False)
    assert [e.metric() for e in entries] == ["q_time_auc"] * 4
    assert pareto_dominated(entries) == {"worse": "near", "cm-shorter": "near"}
    markdown = build_leaderboard(paths, False, tmp_path / "board").markdown
    text = markdown.read_text()
    assert (
        text.index("| 1 | **`far`**")
        < text.index("| 2 | **`near`**")
        < text.index("| 3 | **`cm-shorter`**")
        < text.index("| 4 | **`worse`**")
    )
    assert "dominated by `near`" in text and text.count("| front |") == 2
    assert "equal time, test: IQM area under Q(t)" in text and "equal scans (travel free)" in text
    assert (tmp_path / "board" / "q-time.png").stat().st_size > 0


def test_stale_references_are_left_out_and_named_pending(tiny_suite, tmp_path, monkeypatch):
    import nbv_gym.benchmark.references as references

    old = card(tiny_suite, "old-reference", 0.9, version=1)
    monkeypatch.setattr(references, "load_references", lambda suite: [old])
    with pytest.raises(LeaderboardError, match=r"References for protocol version 2 .* pending"):
        gather([], references=True)
    mine = write(tmp_path, card(tiny_suite, "mine", 0.3))
    markdown = build_leaderboard([mine], True, tmp_path / "board").markdown
    text = markdown.read_text()
    assert "are pending" in text and "old-reference" in text  # named, not ranked
    assert "| 1 | **`mine`**" in text and "| 2 |" not in text


def test_leaderboard_of_the_shipped_references_ranks_the_current_ones_and_names_the_stale(tmp_path):
    """Whatever the state of the shipped references (all current, some scored under an earlier
    protocol version, or all of them), the board ranks exactly the current ones and names the
    stale ones as pending."""
    from nbv_gym.benchmark.references import current_references

    current, stale = current_references()
    if not current:  # every reference predates this protocol version: nothing to rank
        with pytest.raises(LeaderboardError, match="pending"):
            gather([], references=True)
        return
    text = build_leaderboard([], True, tmp_path).markdown.read_text()
    entries = gather([], references=True)
    assert {e.label for e in entries} == {c["policy"]["name"] for c in current}
    assert all(f"`{e.label}`" in text for e in entries)
    assert "(baseline)" in text and "the best reference" in text
    assert ("are pending" in text) == bool(stale)
    assert all(f"{c['policy']['name']}" in text for c in stale)


def test_the_summary_ranks_like_the_table_marks_given_scorecards_and_puts_oracles_last(
    tiny_suite, tmp_path, monkeypatch
):
    """The plain-text ranking that ``nbv-gym leaderboard`` prints: one line per entry in rank
    order, oracles last, ``*`` on the scorecards given on the command line."""
    import nbv_gym.benchmark.references as references

    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "references")
    (tmp_path / "references" / "tiny").mkdir(parents=True)
    for name, q in (("closest-frontier", 0.5), ("oracle-greedy", 0.9)):
        reference = card(tiny_suite, name, q, oracle=name == "oracle-greedy")
        (tmp_path / "references" / "tiny" / f"{name}.json").write_text(dumps_strict(reference))
    mine = write(tmp_path, card(tiny_suite, "mine", 0.3))
    lines = leaderboard_summary(gather([mine], references=True)).splitlines()
    assert lines[0].split()[:2] == ["rank", "policy"] and set(lines[1]) == {"-", " "}
    assert [line.split()[:2] for line in lines[2:5]] == [
        ["1", "closest-frontier"], ["2", "mine"], ["oracle", "oracle-greedy"]
    ]  # fmt: skip
    assert lines[3].split()[2] == "*" and "(baseline)" in lines[2]
    assert "0.00 [0.00, 0.00]" in lines[3]  # every run of mine loses to closest-frontier's
    assert lines[-1].startswith("* given on the command line")


def test_references_of_a_scorecards_suite_are_found_by_adding_its_folder(
    tiny_suite, tmp_path, monkeypatch
):
    """--references adds the references of the given scorecard's suite: with no folder for it,
    a one-line refusal naming the suites that have references; with the folder
    ``references/<suite>/`` holding scorecards of shipped policies, they join the board."""
    import nbv_gym.benchmark.references as references

    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "references")
    (tmp_path / "references" / "standard").mkdir(parents=True)
    standard = tmp_path / "references" / "standard" / "closest-frontier.json"
    standard.write_text(dumps_strict(card(STANDARD, "closest-frontier", 0.5)))
    mine = write(tmp_path, card(tiny_suite, "mine", 0.3))
    with pytest.raises(
        LeaderboardError, match=r"No reference scorecards of the 'tiny' suite"
    ) as error:
        gather([mine], references=True)
    assert "suites with references: standard" in str(error.value)
    (tmp_path / "references" / "tiny").mkdir()
    for name, q in (("random-free", 0.4), ("nbv-sigma", 0.6)):
        path = tmp_path / "references" / "tiny" / f"{name}.json"
        path.write_text(dumps_strict(card(tiny_suite, name, q)))
    entries = gather([mine], references=True)
    assert [e.label for e in entries] == ["random-free", "nbv-sigma", "mine"]  # shipped order
    assert [e.reference for e in entries] == [True, True, False]
    assert baseline(entries).label == "nbv-sigma"
    assert [e.label for e in gather([], references=True)] == ["closest-frontier"]  # standard


def test_the_cli_prints_the_ranking(tiny_suite, tmp_path):
    paths = [write(tmp_path, card(tiny_suite, n, q)) for n, q in (("a", 0.3), ("b", 0.5))]
    result = subprocess.run(
        [sys.executable, "-m", "nbv_gym", "leaderboard", *map(str, paths), "--out", str(tmp_path / "o")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    ranking = [line.split()[:2] for line in result.stdout.splitlines()[2:4]]
    assert ranking == [["1", "b"], ["2", "a"]]
    assert result.stdout.splitlines()[-1].startswith("leaderboard: ")


def test_the_references_of_another_suite_rank_by_name_and_suite_needs_no_scorecard(
    tiny_suite, tmp_path
):
    from nbv_gym.benchmark.references import reference_path, reference_suites, shipped_policies

    assert "quick" in reference_suites()
    entries = gather([], references=True, suite="quick")
    shipped = {n for n in shipped_policies() if reference_path(n, "quick").is_file()}
    assert {e.label for e in entries} == shipped
    assert {e.card["suite"]["name"] for e in entries} == {"quick"}
    with pytest.raises(LeaderboardError, match="--suite quick names whose references to rank"):
        gather([write(tmp_path, card(tiny_suite, "a", 0.3))], references=True, suite="quick")


def test_two_cards_of_one_suite_hash_that_list_other_parts_are_refused(tiny_suite, tmp_path):
    """The round-4 probe C24: an own-world card whose parts and runs were renamed to another
    world kept its suite hash (an own suite's hash cannot be recomputed from the card) and was
    ranked with the honest one, P(better) nan."""
    from nbv_gym.benchmark.scorecard import card_aggregates

    honest = write(tmp_path, card(tiny_suite, "honest", 0.3))
    renamed = card(tiny_suite, "renamed", 0.3)
    for part in renamed["suite"]["parts"]:
        part["worlds"] = [w.replace("tiny-test", "elsewhere") for w in part["worlds"]]
    for run in renamed["runs"]:
        run["world"] = run["world"].replace("tiny-test", "elsewhere")
    renamed["aggregates"] = card_aggregates(renamed["runs"], renamed["suite"]["parts"])
    with pytest.raises(LeaderboardError, match=r"with one hash \(\w+\) but different suite\.parts"):
        gather([honest, write(tmp_path, renamed)], references=False)


def test_the_shift_split_has_its_column_and_p_better_and_is_pending_where_missing(
    tiny_suite, tmp_path, monkeypatch
):
    """A reference scored before the shift part joined its suite ranks by its other parts; its
    shift cells and the board say the split is pending for it, and the shift ``P(better)`` is
    against the best reference that holds the split."""
    import nbv_gym.benchmark.references as references
    from nbv_gym.benchmark import suites

    shift = replace(tiny_suite.part("time-test"), split="time-shift")
    suite = replace(tiny_suite, parts=(tiny_suite.parts[0], shift, *tiny_suite.parts[1:]))
    monkeypatch.setitem(suites.SUITES, "tiny", suite)
    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "references")
    (tmp_path / "references" / "tiny").mkdir(parents=True)
    old = suite.only(s for s in suite.splits if s != "time-shift")
    for name, scored, q in (("closest-frontier", suite, 0.5), ("nbv-sigma", old, 0.6)):
        path = tmp_path / "references" / "tiny" / f"{name}.json"
        path.write_text(dumps_strict(card(scored, name, q)))
    mine = write(tmp_path, card(suite, "mine", 0.55))
    entries = gather([mine], references=True)
    assert [e.label for e in ranked(entries)[0]] == ["nbv-sigma", "mine", "closest-frontier"]
    assert baseline(entries).label == "nbv-sigma"
    assert baseline(entries, "time-shift").label == "closest-frontier"
    text = build_leaderboard([mine], True, tmp_path / "board").markdown.read_text()
    assert "equal time, shift: IQM area under Q(t)" in text
    assert "P(better than closest-frontier, shift)" in text
    row = next(line for line in text.splitlines() if line.startswith("| 1 | `nbv-sigma`"))
    assert row.count("| pending |") == 2  # its shift score and its shift P(better)
    assert "**The time-shift split is pending for nbv-sigma" in text
    mine_row = next(line for line in text.splitlines() if "**`mine`**" in line)
    assert mine_row.rstrip(" |").endswith("1.00 [1.00, 1.00]")  # every shift run beats cf's
    summary = leaderboard_summary(entries).splitlines()
    assert "P(better than closest-frontier, shift)" in summary[0]
    other = replace(suite, parts=(suite.parts[0], replace(shift, repeats=1), *suite.parts[2:]))
    pair = [Entry("mine", card(suite, "mine", 0.5), "a"), Entry("b", card(other, "b", 0.4), "b")]
    with pytest.raises(LeaderboardError, match="different suites or protocol versions"):
        check_comparable(pair)  # one split, two contents
