"""``score_policy`` end to end on a tiny suite: schema, strict JSON, determinism, resuming."""

from __future__ import annotations

import hashlib
import json
import math
import sys
import textwrap

import numpy as np
import pytest

from nbv_gym.benchmark.scorecard import (
    SCHEMA_PATH,
    ScorecardError,
    dumps_strict,
    join_scorecards,
    load_scorecard,
    policy_identity,
    summary,
)
from nbv_gym.benchmark.suiterun import ScoreError, score_policy
from nbv_gym.benchmark.suites import PROTOCOL_VERSION
from nbv_gym.core.errors import NbvGymError


def strict_json(text: str):
    """``json.loads`` that refuses NaN and ±Infinity, as Node's JSON.parse and jq do."""

    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def without_timings(value):
    """``value`` without the fields that measure time (they differ from run to run)."""
    if isinstance(value, dict):
        return {
            k: without_timings(v)
            for k, v in value.items()
            if k not in ("created", "timing") and not k.startswith("decision_time_s")
            and k != "wall_time_s"
        }  # fmt: skip
    if isinstance(value, list):
        return [without_timings(v) for v in value]
    return value


def validate(card: dict) -> None:
    import jsonschema

    schema = json.loads(SCHEMA_PATH.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(card, schema, cls=jsonschema.Draft202012Validator)


@pytest.fixture(scope="module")
def scored(tiny_suite, tmp_path_factory):
    """The tiny suite scored for closest-frontier: (folder, scorecard)."""
    out = tmp_path_factory.mktemp("score") / "cf"
    card = score_policy("closest-frontier", tiny_suite, out, workers=1, progress=False, say=print)
    return out, card


def test_scorecard_validates_against_the_shipped_schema(scored):
    out, card = scored
    written = strict_json((out / "scorecard.json").read_text())
    validate(written)
    assert written == strict_json(dumps_strict(card))
    assert len(written["runs"]) == 8
    assert written["policy"]["name"] == "closest-frontier" and written["policy"]["oracle"] is False
    assert written["suite"]["name"] == "tiny" and written["protocol_version"] == PROTOCOL_VERSION


def test_schema_rejects_a_scorecard_that_lost_a_field(scored):
    import jsonschema

    card = strict_json((scored[0] / "scorecard.json").read_text())
    del card["runs"][0]["q"]
    with pytest.raises(jsonschema.ValidationError, match="'q' is a required property"):
        validate(card)


def test_runs_carry_their_figures_and_undefined_values_are_null(scored):
    out, card = scored
    runs = strict_json((out / "scorecard.json").read_text())["runs"]
    budget = [r for r in runs if r["task"] == "budget"]
    explore = [r for r in runs if r["task"] == "explore"]
    assert all(r["steps"] == 2 and r["end_reason"].startswith("reached max_steps") for r in budget)
    assert {r["world"] for r in runs if r["split"] == "test"} == {"tiny-test"}
    # three steps discover far less than 70 %: Q_paper at 70 % is undefined
    assert all(r["discovered"] < 0.7 and r["q_paper_70"] is None for r in explore)
    assert all(r["decision_time_s"] > 0 and 0 <= r["q"] <= 1 for r in runs)
    assert card["aggregates"]["explore"]["all"]["n"] == 0
    assert card["aggregates"]["explore"]["all"]["iqm"] is None or math.isnan(
        card["aggregates"]["explore"]["all"]["iqm"]
    )


def test_aggregates_summarise_the_runs(scored):
    card = strict_json((scored[0] / "scorecard.json").read_text())
    test = card["aggregates"]["test"]
    q = [r["q"] for r in card["runs"] if r["split"] == "test"]
    assert test["metric"] == "q" and test["all"]["n"] == 2
    assert test["all"]["mean"] == pytest.approx(np.mean(q))
    assert test["all"]["optimality_gap"] == pytest.approx(1 - np.mean(q))
    assert test["all"]["mean_low"] <= test["all"]["mean"] <= test["all"]["mean_high"]
    assert set(test["by_asset"]) == {"crosses"}
    assert "scorecard: `closest-frontier`" in (scored[0] / "scorecard.md").read_text().lower()


def test_time_runs_carry_q_over_effort_computed_from_their_steps(scored):
    """Each time-task run's area under Q(t), elapsed time and Q on the grids, recomputed here
    from the sweep's steps table by hand; the effort aggregates are their means."""
    import pandas as pd

    from nbv_gym.benchmark.curves import PATH_GRID_M, TIME_GRID_S

    out, card = scored
    steps = pd.read_csv(out / "parts" / "time-test" / "steps.csv")
    runs = [r for r in card["runs"] if r["split"] == "time-test"]
    budget = 40.0
    for run in runs:
        mine = steps[steps["repeat"] == run["repeat"]].sort_values("step")
        t, q, path = (mine[c].to_numpy() for c in ("elapsed_s", "q", "path_length_m"))
        assert np.allclose(t, path / 1.0 + mine["step"].to_numpy() * 10.0)  # the effort model
        held = sum(q[i] * (min(t[i + 1], budget) - t[i]) for i in range(len(t) - 1))
        held += q[-1] * (budget - t[-1])
        assert run["q_time_auc"] == pytest.approx(held / budget, rel=1e-12)
        assert run["elapsed_s"] == pytest.approx(t[-1]) and t[-1] <= budget
        assert run["end_reason"].startswith("time budget spent")
        for grid, values, effort in (
            (TIME_GRID_S, run["q_time"], t),
            (PATH_GRID_M, run["q_path"], path),
        ):
            for x, value in zip(grid, values, strict=True):
                assert value == pytest.approx(q[effort <= x][-1], abs=1e-7)
    effort = card["aggregates"]["time-test"]["effort"]
    assert card["aggregates"]["time-test"]["metric"] == "q_time_auc"
    assert effort["q_at_budget"]["mean"] == pytest.approx(np.mean([r["q"] for r in runs]))
    index = PATH_GRID_M.index(25.0)
    assert effort["q_at_path"]["25"]["mean"] == pytest.approx(
        np.mean([r["q_path"][index] for r in runs])
    )
    assert effort["q_time"]["mean"] == pytest.approx(np.mean([r["q_time"] for r in runs], axis=0))
    assert all(r["q_time_auc"] is None for r in card["runs"] if r["task"] != "time")
    assert card["aggregates"]["test"]["effort"]["q_at_budget"] is None
    assert "Q over effort" in (out / "scorecard.md").read_text()


def test_a_second_scoring_gives_the_same_scorecard_apart_from_timings(scored, tiny_suite, tmp_path):
    first = strict_json((scored[0] / "scorecard.json").read_text())
    again = score_policy("closest-frontier", tiny_suite, tmp_path, workers=1, progress=False)
    assert without_timings(strict_json(dumps_strict(again))) == without_timings(first)


def test_scoring_on_a_dask_cluster_gives_the_local_scorecard(scored, tiny_suite, tmp_path):
    pytest.importorskip("distributed")
    first = strict_json((scored[0] / "scorecard.json").read_text())
    again = score_policy(
        "closest-frontier", tiny_suite, tmp_path, workers=2, progress=False, scheduler="local"
    )
    assert without_timings(strict_json(dumps_strict(again))) == without_timings(first)


def test_a_killed_scoring_resumes_with_the_missing_runs_only(scored, tiny_suite, capsys):
    out = scored[0]
    first = strict_json((out / "scorecard.json").read_text())
    lost = sorted((out / "parts" / "test" / "runs").glob("*.json"))[0]
    lost.unlink()
    (out / "scorecard.json").unlink()
    card = score_policy("closest-frontier", tiny_suite, out, workers=1, progress=False)
    assert without_timings(strict_json(dumps_strict(card))) == without_timings(first)
    assert lost.exists()


def test_a_part_added_to_a_suite_is_scored_alone_and_joins_the_reference(
    scored, tiny_suite, tmp_path, monkeypatch
):
    """A reference scored before a part joined its suite stands for its other parts (current,
    the part named pending); ``complete`` scores only that part and joins it: the scorecard a
    scoring of the whole suite gives. (The runs are resumed from a whole scoring's folders.)"""
    import shutil

    from nbv_gym.benchmark import references, suites

    out, whole = scored
    monkeypatch.setitem(suites.SUITES, "tiny", tiny_suite)
    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "references")
    rest = tiny_suite.only(s for s in tiny_suite.splits if s != "time-test")
    for folder in ("old", "tiny/closest-frontier+time-test"):
        shutil.copytree(out, tmp_path / folder)
    old = score_policy("closest-frontier", rest, tmp_path / "old", workers=1, progress=False)
    assert [p["hash"] for p in old["suite"]["parts"]] == [
        p.content_hash(tiny_suite.seed) for p in rest.parts
    ]  # a part's hash is the same in the suite and in its part of it
    path = references.reference_path("closest-frontier", "tiny")
    path.parent.mkdir(parents=True)
    path.write_text(dumps_strict(old))
    assert references.is_current(old, "tiny") and references.missing_parts(old) == ["time-test"]
    note = references.references_note("tiny")
    assert note.startswith("The time-test split is pending for closest-frontier")
    assert "--part time-test" in note
    written = references.complete(
        ["closest-frontier"], ["time-test"], tmp_path, 1, print, tiny_suite
    )
    joined = load_scorecard(path)
    assert written == [path] and references.missing_parts(joined) == []
    assert without_timings(joined) == without_timings(strict_json(dumps_strict(whole)))
    with pytest.raises(ScorecardError, match="both hold a split"):
        join_scorecards(tiny_suite, [old, old])


def test_a_folder_holding_another_policys_scorecard_is_refused(scored, tiny_suite):
    with pytest.raises(ScoreError, match="holds the scorecard of 'closest-frontier'; score"):
        score_policy("random-free", tiny_suite, scored[0], workers=1, progress=False)


def test_policy_identity_hashes_the_policy_module_and_flags_oracles(tmp_path, monkeypatch):
    import nbv_gym.policies.frontier as frontier

    identity = policy_identity("closest-frontier")
    expected = hashlib.sha256(open(frontier.__file__, "rb").read()).hexdigest()
    assert identity["code_hash"] == expected and identity["hashed_file"] == "frontier.py"
    source = textwrap.dedent(
        """
        class Peeker:
            privileged = True
            observation_layers = ()
            def reset(self, seed=None):
                pass
            def act(self, observation, info):
                return 0
        """
    )
    (tmp_path / "scored_oracle.py").write_text(source)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "scored_oracle", raising=False)  # imported below, then gone
    oracle = policy_identity("scored_oracle:Peeker")
    assert oracle["oracle"] is True and oracle["class"] == "scored_oracle:Peeker"
    assert oracle["code_hash"] == hashlib.sha256(source.encode()).hexdigest()


def test_summary_with_one_run_per_stratum_has_point_intervals():
    values = (("a", 0.1), ("b", 0.2), ("c", 0.6), ("d", 0.9))
    runs = [{"world": w, "noise": 0, "q": q} for w, q in values]
    s = summary(runs, "q", "label")
    assert s["n"] == 4 and s["mean"] == s["mean_low"] == s["mean_high"] == pytest.approx(0.45)
    assert s["iqm"] == s["iqm_low"] == s["iqm_high"] == pytest.approx(0.4)  # mean of 0.2, 0.6
    assert s["optimality_gap"] == pytest.approx(0.55)


def test_strict_json_writes_nan_as_null():
    text = dumps_strict({"a": float("nan"), "b": [np.float32(0.5), float("inf")], "c": np.int64(3)})
    assert strict_json(text) == {"a": None, "b": [0.5, None], "c": 3}


def test_load_scorecard_refuses_other_files(tmp_path):
    path = tmp_path / "x.json"
    path.write_text('{"runs": []}')
    with pytest.raises(ScorecardError, match="is not an nbv-gym scorecard"):
        load_scorecard(path)
    path.write_text("{nope")
    with pytest.raises(NbvGymError, match=r"Scorecard .* is not valid JSON"):
        load_scorecard(path)
