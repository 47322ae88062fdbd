"""The shipped reference scorecards are current: a change that moves a reference's results fails
here until the references are regenerated (``python -m nbv_gym.benchmark.references``).

Cheap detectors, from the broadest to the most direct: the suite's content hash (worlds, seeds,
every environment default) and the protocol version; each policy's code or model hash; the
aggregates recomputed from the stored runs (the statistics code); and a few stored runs re-run
here and compared figure by figure (the simulator, mapping, metrics and policies)."""

from __future__ import annotations

import json

import pytest

from nbv_gym.benchmark.references import (
    REFERENCE_DIR,
    REFERENCE_SUITE,
    ReferenceUpdateError,
    complete,
    is_current,
    load_references,
    missing_parts,
    pending,
    reference_path,
    reference_suites,
    shipped_policies,
)
from nbv_gym.benchmark.scorecard import (
    SCHEMA_PATH,
    aggregate,
    dumps_strict,
    file_hash,
    load_scorecard,
    policy_file,
)
from nbv_gym.benchmark.suites import PROTOCOL_VERSION, get_suite, shipped_identity


def close(a, b, rel: float = 1e-9) -> bool:
    """``a`` equals ``b`` (nested dicts and lists), numbers to ``rel``, the rest exactly."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(close(a[k], b[k], rel) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(close(x, y, rel) for x, y in zip(a, b, strict=True))
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool):
        return a == pytest.approx(b, rel=rel)
    return a == b


REGENERATE = "regenerate the references: python -m nbv_gym.benchmark.references"
SHIPPED = shipped_policies()
#: While a shipped reference predates the protocol version (a new version is scored once, at
#: the end of the change that brought it), the tests that hold it to the current suite,
#: aggregates and runs are expected to fail — strictly: once regenerated, they must pass.
STALE = pytest.mark.xfail(
    reason=f"the references of protocol version {PROTOCOL_VERSION} are pending; {REGENERATE}",
    raises=AssertionError,  # a check that fails, not a loader that breaks
    strict=True,
)
#: Every suite that has references (the standard suite's always ship), by every shipped policy.
SUITES = reference_suites()


def case(suite: str, name: str):
    """The test case of ``name``'s reference on ``suite``, marked :data:`STALE` when the shipped
    file predates this protocol version or suite."""
    path = reference_path(name, suite)
    stale = path.is_file() and not is_current(load_scorecard(path, recompute=False), suite)
    return pytest.param(suite, name, marks=[STALE] if stale else [])


CASES = [case(suite, name) for suite in SUITES for name in SHIPPED]


def whole_case(suite: str, name: str):
    """The test case that ``name``'s reference on ``suite`` holds every part of the suite,
    marked as expected to fail — strictly, so the mark goes once the part is scored — while a
    part that joined the suite after the reference was scored is pending (its other parts
    stand)."""
    path = reference_path(name, suite)
    lacking = (
        ", ".join(missing_parts(load_scorecard(path, recompute=False))) if path.is_file() else ""
    )
    if not lacking:
        return pytest.param(suite, name)
    reason = (f"the {lacking} split is pending for {name}: python -m nbv_gym.benchmark.references "
              f"{name} --suite {suite} --part {lacking.replace(', ', ' --part ')}")  # fmt: skip
    mark = pytest.mark.xfail(reason=reason, raises=AssertionError, strict=True)
    return pytest.param(suite, name, marks=[mark])


WHOLE_CASES = [whole_case(suite, name) for suite in SUITES for name in SHIPPED]


def stored(name: str, suite: str = REFERENCE_SUITE.name) -> dict:
    """The reference scorecard of ``name`` on ``suite``; the test is skipped when there is none
    (the test below names every missing one)."""
    if not reference_path(name, suite).is_file():
        pytest.skip(f"no reference scorecard of {name} on the {suite} suite")
    return load_scorecard(reference_path(name, suite))


def test_the_standard_suite_has_references_and_every_folder_is_a_suite():
    assert REFERENCE_SUITE.name in SUITES
    folders = {p.name for p in REFERENCE_DIR.iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert folders <= set(SUITES), f"reference folders of no suite: {folders - set(SUITES)}"
    assert not list(REFERENCE_DIR.glob("*.json")), "a reference outside its suite's folder"


@pytest.mark.parametrize("suite", SUITES)
def test_every_shipped_policy_has_a_reference_unless_pending_and_nothing_else_does(suite):
    files = {p.stem for p in (REFERENCE_DIR / suite).glob("*.json")}
    missing = sorted(set(SHIPPED) - files - set(pending(suite)))
    unknown = sorted(files - set(SHIPPED))
    assert not missing and not unknown, (
        f"no {suite} reference of {missing}, a reference of no shipped policy {unknown}: "
        f"{REGENERATE} --suite {suite} {' '.join(missing)} (and delete the others)"
    )
    assert set(pending(suite)) <= set(SHIPPED) and not files & set(pending(suite)), (
        "a pending reference exists or names no shipped policy: update PENDING"
    )


@pytest.mark.parametrize(("suite", "name"), CASES)
def test_reference_belongs_to_the_current_suite_protocol_and_policy_code(suite, name):
    card = stored(name, suite)
    held = get_suite(suite).only(part["split"] for part in card["suite"]["parts"])
    assert card["suite"]["name"] == suite and held.parts
    assert card["suite"] == shipped_identity(card["suite"]), (
        f"the {suite} suite's parts changed since {name}'s reference was scored; {REGENERATE}"
    )
    assert [p["hash"] for p in card["suite"]["parts"]] == [
        p.content_hash(held.seed) for p in held.parts
    ]
    assert card["protocol_version"] == PROTOCOL_VERSION, REGENERATE
    assert card["policy"]["name"] == name and card["policy"]["oracle"] in (True, False)
    assert card["policy"]["code_hash"] == file_hash(policy_file(name)), (
        f"{policy_file(name).name} changed since {name}'s reference was scored; {REGENERATE}"
    )
    assert len(card["runs"]) == held.runs


@pytest.mark.parametrize(("suite", "name"), WHOLE_CASES)
def test_reference_holds_every_part_of_its_suite(suite, name):
    card = stored(name, suite)
    assert not missing_parts(card), f"{name}'s {suite} reference lacks {missing_parts(card)}"


@pytest.mark.parametrize(("suite", "name"), CASES)
def test_reference_validates_and_its_aggregates_follow_from_its_runs(suite, name):
    import jsonschema

    card = stored(name, suite)
    jsonschema.validate(card, json.loads(SCHEMA_PATH.read_text()))
    assert card["protocol_version"] == PROTOCOL_VERSION, (
        f"{name}'s reference is stale; {REGENERATE}"
    )
    for part in get_suite(suite).only(p["split"] for p in card["suite"]["parts"]).parts:
        again = json.loads(dumps_strict(aggregate(card["runs"], part.split, part.metric)))
        assert close(again, card["aggregates"][part.split]), (
            f"the aggregation or statistics code changed; {REGENERATE}"
        )


#: Stored runs re-run here: (policy, split, world, noise, repeat) — a frontier baseline, the
#: statistic policies' two gain paths (the count and the spherical variance), the volumetric
#: information gain, the explore task, and the time task on a shift world (its part joined the
#: suite after the others: the run of a reference completed with it).
RERUNS = (
    ("closest-frontier", "benchmark", "pp1-cuboids", 0, 0),
    ("nbv-nobs", "benchmark", "pp1-crosses", 1, 0),
    ("nbv-sigma", "benchmark", "pp1-helicoids", 2, 0),
    ("ig-unknown", "benchmark", "pp1-trees", 1, 0),
    ("random-frontier", "explore", "pp1-cuboids", 2, 1),
    ("closest-frontier", "time-shift", "shift-03", 1, 0),
)


@pytest.mark.parametrize(("name", "split", "world", "noise", "repeat"), RERUNS)
def test_a_stored_run_gives_the_same_figures_when_run_again(
    name, split, world, noise, repeat, tmp_path
):
    from nbv_gym.benchmark.rerun import run_difference
    from nbv_gym.benchmark.suiterun import part_config, run_figures, write_world_specs
    from nbv_gym.core.config import to_dict
    from nbv_gym.sweep.worker import RunTask, _run

    reference = stored(name)
    if split in missing_parts(reference):
        pytest.skip(f"the {split} split is pending for {name}")
    part = REFERENCE_SUITE.part(split)
    sources = write_world_specs(REFERENCE_SUITE.only([split]), tmp_path)  # generated: files
    config = part_config(REFERENCE_SUITE, part, name, sources)
    spec = next(s for s in config.runs() if (s.world, s.noise, s.repeat) == (world, noise, repeat))
    # the worker's run itself, in this process (execute_run would reconfigure numba's threads)
    outcome = _run(RunTask(spec, to_dict(config.env_config(sources[world], noise))), None)
    now = run_figures(part, outcome)
    then = next(
        r
        for r in reference["runs"]
        if (r["split"], r["world"], r["noise"], r["repeat"]) == (split, world, noise, repeat)
    )
    # the figures the stored run holds (a newer protocol version adds figures, never moves one),
    # compared as `nbv-gym leaderboard --verify` compares a card's: bit for bit, timings aside
    moved = run_difference(then, json.loads(dumps_strict(now)))
    assert moved is None, f"{name}'s run {spec.key} gives other figures ({moved}); {REGENERATE}"


@pytest.mark.parametrize("suite", SUITES)
def test_load_references_follows_the_shipped_order(suite):
    assert [c["policy"]["name"] for c in load_references(suite)] == [
        n for n in SHIPPED if reference_path(n, suite).is_file()
    ]


def test_completing_parts_every_reference_holds_says_so_and_scores_nothing(tmp_path):
    said: list[str] = []
    assert complete([], ["time-shift"], tmp_path / "work", say=said.append) == []
    assert said == ["every standard reference holds time-shift: nothing to score"]
    with pytest.raises(ReferenceUpdateError, match=r"suite standard has no part \['nonsense'\]"):
        complete([], ["nonsense"], tmp_path / "work", say=said.append)
    assert not (tmp_path / "work").exists()
