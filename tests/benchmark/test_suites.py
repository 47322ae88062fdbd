"""The shipped suites: their contents, the test split's recipe, seeds and the content hash."""

from __future__ import annotations

from dataclasses import replace

import pytest

from nbv_gym.benchmark.shiftsplit import shift_worlds
from nbv_gym.benchmark.suiterun import part_config, write_world_specs
from nbv_gym.benchmark.suites import (
    BENCHMARK_WORLDS,
    HEADLINE_SPLIT,
    QUICK,
    STANDARD,
    SUITES,
    Part,
    get_suite,
)
from nbv_gym.benchmark.testsplit import FIRST_SEED, SIZE, split_world, split_worlds
from nbv_gym.core.config import to_dict
from nbv_gym.core.errors import UnknownNameError
from nbv_gym.env.task import TaskConfig
from nbv_gym.worlds import benchmark_names
from nbv_gym.worlds.distribution import FIRST_SEED as POOL_SEED
from nbv_gym.worlds.distribution import KINDS, POOL_SIZE, WorldDistribution


def test_standard_suite_runs_the_time_and_budget_tasks_on_both_splits_and_the_paper_protocol():
    parts = {part.split: part for part in STANDARD.parts}
    assert list(parts) == ["time-test", "time-shift", "time-benchmark", "benchmark", "test",
                           "explore"]  # fmt: skip
    assert sorted(parts["benchmark"].world_names) == benchmark_names()
    assert parts["time-benchmark"].world_names == parts["benchmark"].world_names
    assert parts["time-test"].world_names == parts["test"].world_names
    assert parts["explore"].world_names == BENCHMARK_WORLDS
    assert len(parts["test"].worlds) >= 12
    assert parts["time-shift"].world_names == tuple(w.name for w in shift_worlds())
    assert [p.task.name for p in parts.values()] == ["time"] * 3 + ["budget", "budget", "explore"]
    assert [p.metric for p in parts.values()] == ["q_time_auc"] * 3 + ["q", "q", "q_paper_70"]
    assert parts["time-shift"].task.time_budget_s == parts["time-test"].task.time_budget_s
    assert (parts["time-shift"].noise, parts["time-shift"].repeats) == ((0, 1, 2), 3)
    assert all(p.noise == (0, 1, 2) and p.repeats >= 2 for p in parts.values())
    assert (
        parts["benchmark"].task.budget_scans == 12 and parts["time-test"].task.time_budget_s == 600
    )
    assert HEADLINE_SPLIT == "time-test"
    episode = parts["time-test"].env_config().simulator.episode
    assert (episode.time_budget_s, episode.discovered_target) == (600, None)


def test_test_split_recipe_differs_from_the_benchmark_and_the_training_pools():
    worlds = split_worlds()
    assert [w.name for w in worlds] == [f"test-{k:02d}" for k in range(SIZE)]
    seeds = {w.placement.seed for w in worlds}
    assert seeds.isdisjoint({1, 2, 3}) and min(seeds) >= FIRST_SEED > POOL_SEED + POOL_SIZE
    assert all(30 <= w.placement.n_assets <= 80 for w in worlds)
    assert all(w.placement.cluster_radius_m < 30.0 for w in worlds)
    assert all(
        w.assets.scale_horizontal != (0.7, 1.3) or w.assets.scale_vertical != (0.7, 1.3)
        for w in worlds
    )
    assert sum(len(w.assets.mix) > 1 for w in worlds) >= 4  # asset mixes besides single types
    pools = {WorldDistribution(kind).spec(k).digest() for kind in KINDS for k in range(POOL_SIZE)}
    benchmark = {s.digest() for s in STANDARD.part("benchmark").specs()}
    digests = {w.digest() for w in worlds}
    assert len(digests) == SIZE and digests.isdisjoint(pools | benchmark)


def test_test_worlds_are_generated_the_same_every_time():
    assert split_world(7) == split_world(7)
    assert split_world(7).digest() == "99fc253daafa92a6"  # fixed: a change moves every score


def test_a_part_has_its_own_hash_so_adding_a_part_leaves_the_others_valid():
    """Each part's hash covers its worlds, noise, repeats, task settings, environment and the
    suite's seed, and nothing of the other parts: a scorecard of some parts (Suite.only) records
    the same part hashes as the whole suite, and a suite hash that is theirs."""
    seed = STANDARD.seed
    hashes = {p["split"]: p["hash"] for p in STANDARD.identity()["parts"]}
    assert hashes == {p.split: p.content_hash(seed) for p in STANDARD.parts}
    assert len(set(hashes.values())) == len(hashes)
    before = STANDARD.only(s for s in STANDARD.splits if s != "time-shift")
    assert before.splits == ("time-test", "time-benchmark", "benchmark", "test", "explore")
    assert all(p["hash"] == hashes[p["split"]] for p in before.identity()["parts"])
    assert before.content_hash() != STANDARD.content_hash()
    assert QUICK.part("time-test").content_hash(seed) != hashes["time-test"]  # fewer worlds
    assert replace(STANDARD.parts[0], repeats=4).content_hash(seed) != hashes["time-test"]
    assert STANDARD.parts[0].content_hash(seed + 1) != hashes["time-test"]
    assert "time-shift" not in QUICK.splits  # the quick suite is as it was


def test_quick_runs_are_a_subset_of_the_standard_runs(tmp_path):
    sources = write_world_specs(STANDARD, tmp_path)
    for quick_part in QUICK.parts:  # the standard suite's shift split has no quick twin
        standard_part = STANDARD.part(quick_part.split)
        assert set(quick_part.world_names) < set(standard_part.world_names)
        quick = _runs(QUICK, quick_part, sources)
        standard = _runs(STANDARD, standard_part, sources)
        assert quick < standard, quick_part.split


def _runs(suite, part, sources) -> set[tuple[str, int]]:
    """(key, seed) of every run of ``part``."""
    config = part_config(suite, part, "closest-frontier", sources)
    return {(spec.key, spec.seed) for spec in config.runs()}


def test_content_hash_is_stable_and_moves_with_what_fixes_results():
    assert STANDARD.content_hash() == STANDARD.content_hash()
    assert STANDARD.content_hash() != QUICK.content_hash()
    more = replace(STANDARD.parts[0], repeats=4)
    assert (
        replace(STANDARD, parts=(more, *STANDARD.parts[1:])).content_hash()
        != STANDARD.content_hash()
    )
    assert replace(STANDARD, seed=1).content_hash() != STANDARD.content_hash()
    assert replace(STANDARD, name="renamed").content_hash() == STANDARD.content_hash()


def test_content_hash_moves_when_an_environment_default_changes(monkeypatch):
    from nbv_gym.env import explore

    before = QUICK.content_hash()
    original = explore.EnvConfig

    def changed(*args, **kwargs):
        config = original(*args, **kwargs)
        return replace(config, nbv=replace(config.nbv, gain_floor=config.nbv.gain_floor * 2))

    monkeypatch.setattr(explore, "EnvConfig", changed)
    assert QUICK.content_hash() != before


def test_the_hashed_env_config_is_the_one_the_runs_use():
    sources = {w: w for w in BENCHMARK_WORLDS}
    for part in (STANDARD.part("benchmark"), STANDARD.part("explore")):
        used = to_dict(
            part_config(STANDARD, part, "closest-frontier", sources).env_config("pp2-trees", 1)
        )
        hashed = to_dict(part.env_config())
        for config in (used, hashed):
            del config["simulator"]["world"], config["simulator"]["noise"]
        assert used == hashed


def test_suites_by_name():
    assert get_suite("quick") is QUICK and set(SUITES) == {"standard", "quick", "team"}
    with pytest.raises(
        UnknownNameError, match=r"Unknown suite 'standrad'\. Did you mean 'standard'"
    ):
        get_suite("standrad")
    with pytest.raises(Exception, match="task: expected one of explore, budget"):
        Part("x", TaskConfig(name="sprint"), ("pp1-trees",))
