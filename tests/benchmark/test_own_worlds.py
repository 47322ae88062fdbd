"""``nbv-gym score --world WORLD.toml``: a suite's parts on the benchmark worlds run on your own, a suite
of its own (its scorecards rank apart from the benchmark's)."""

from __future__ import annotations

import pytest

from nbv_gym.benchmark.leaderboard import gather
from nbv_gym.benchmark.suiterun import score_policy
from nbv_gym.benchmark.suites import QUICK, Part, Suite
from nbv_gym.core.errors import ConfigError, NbvGymError
from nbv_gym.env.task import TaskConfig
from nbv_gym.worlds import load_spec
from tests.helpers import write_tiny_world


def test_a_suite_on_your_worlds_keeps_its_parts_on_the_benchmark_worlds(tmp_path):
    spec = str(write_tiny_world(tmp_path))
    own = QUICK.with_worlds((spec,))
    kept = ["time-benchmark", "benchmark", "explore"]  # the parts on the benchmark worlds
    assert [p.split for p in own.parts] == kept
    for part, original in zip(own.parts, map(QUICK.part, kept), strict=True):
        assert part.worlds == (spec,) and part.task == original.task
        assert (part.noise, part.repeats) == (original.noise, original.repeats)
    assert own.name == "quick-own" and own.runs == 3 * (3 * 2)  # parts × (noise × repeats)
    assert own.content_hash() != QUICK.content_hash()
    worlds = own.content()["parts"][0]["worlds"]
    assert worlds == {"tiny-cuboids": load_spec(spec).digest()}


def test_a_bad_world_fails_before_any_run(tmp_path):
    with pytest.raises(NbvGymError, match="does not exist"):
        QUICK.with_worlds((str(tmp_path / "missing.toml"),))


def test_two_world_files_of_one_name_are_refused(tmp_path):
    a, b = (str(write_tiny_world(tmp_path, name)) for name in ("a.toml", "b.toml"))
    with pytest.raises(ConfigError, match=r"are both named 'tiny-cuboids'"):
        QUICK.with_worlds((a, b))


def test_a_scorecard_on_your_world_file_passes_the_leaderboards_checks(tmp_path):
    spec = str(write_tiny_world(tmp_path))  # the file tiny.toml holds the world tiny-cuboids
    part = Part(
        "time-benchmark",
        TaskConfig(name="time", time_budget_s=20.0),
        ("pp1-cuboids",),
        (0,),
        repeats=1,
    )
    own = Suite("tiny", (part,), seed=0).with_worlds((spec,))
    card = score_policy("closest-frontier", own, tmp_path / "score", workers=1, progress=False)
    assert card["suite"]["parts"][0]["worlds"] == ["tiny-cuboids"]
    assert [run["world"] for run in card["runs"]] == ["tiny-cuboids"]
    [entry] = gather([tmp_path / "score" / "scorecard.json"], references=False)
    assert entry.rank_split == "time-benchmark"
