"""The shift split: recipes outside every training distribution, worlds generated like the test
split's, and no world of any pool equal to a suite's world."""

from __future__ import annotations

from itertools import pairwise

import pytest

from nbv_gym.benchmark import shiftsplit, testsplit
from nbv_gym.benchmark.shiftsplit import RECIPES, SIZE, recipe_of, shift_world, shift_worlds
from nbv_gym.benchmark.suites import BENCHMARK_WORLDS, SUITES
from nbv_gym.configs import config_file, shipped_configs
from nbv_gym.rl.config import load_train_config
from nbv_gym.worlds import pools
from nbv_gym.worlds.distribution import WorldDistribution, is_distribution
from nbv_gym.worlds.recipe import AXES, Recipe, outside
from nbv_gym.worlds.spec import load_spec

#: The training configs of the shipped agents, kept as those were trained (evaluated on pp3-*).
AS_TRAINED = ("ppo", "ppo-time")
#: Every training distribution's recipe, by name.
TRAINING = {f"random:{kind}": recipe for kind, recipe in pools.RECIPES.items()}


def numbers(spec) -> dict[str, float]:
    """The recipe numbers of a generated world spec, by :data:`AXES`."""
    x0, y0, x1, y1 = spec.placement.window_m
    lows = (spec.assets.scale_horizontal[0], spec.assets.scale_vertical[0])
    highs = (spec.assets.scale_horizontal[1], spec.assets.scale_vertical[1])
    return {
        "n_assets": spec.placement.n_assets,
        "n_parents": spec.placement.parents,
        "cluster_radius_m": spec.placement.cluster_radius_m,
        "window_side_m": max(x1 - x0, y1 - y0),
        "scale_low": lows,
        "scale_high": highs,
    }


def inside(recipe: Recipe, spec) -> bool:
    """Whether every number of ``spec`` lies in ``recipe``'s ranges and its mix is one of its."""
    found = numbers(spec)
    for axis in AXES:
        low, high = recipe.ranges[axis]
        values = found[axis] if isinstance(found[axis], tuple) else (found[axis],)
        if not all(low - 1e-9 <= v <= high + 1e-9 for v in values):
            return False
    return tuple(spec.assets.mix) in recipe.mixes


@pytest.mark.parametrize("shift", list(RECIPES))
def test_every_shift_recipe_lies_outside_every_training_recipe(shift):
    for name, training in TRAINING.items():
        apart = [a for a in AXES if outside(RECIPES[shift].ranges[a], training.ranges[a])]
        assert apart, f"the {shift} recipe overlaps {name} on every range"
    wide = pools.WIDE_RECIPE  # and, being outside, outside the test split it covers
    assert any(outside(RECIPES[shift].ranges[a], wide.ranges[a]) for a in AXES)


def test_the_wide_training_recipe_covers_and_exceeds_the_test_split():
    wide, test = pools.WIDE_RECIPE.ranges, testsplit.RECIPE.ranges
    for axis in AXES:
        assert wide[axis][0] <= test[axis][0] and test[axis][1] <= wide[axis][1], axis
    exceeded = [a for a in AXES if wide[a][0] < test[a][0] or test[a][1] < wide[a][1]]
    assert set(exceeded) == set(AXES)  # every range wider: density, clusters, windows, scales
    assert set(testsplit.RECIPE.mixes) < set(pools.WIDE_RECIPE.mixes)
    assert {(kind,) for kind in pools.ASSET_TYPES} <= set(pools.WIDE_RECIPE.mixes)  # forests


def test_generated_worlds_lie_in_their_recipes():
    assert all(inside(RECIPES[recipe_of(k)], shift_world(k)) for k in range(SIZE))
    assert all(inside(testsplit.RECIPE, w) for w in testsplit.split_worlds())
    wide = WorldDistribution("wide", pools.WIDE_POOL_SIZE)
    assert all(inside(pools.WIDE_RECIPE, wide.spec(k)) for k in range(wide.pool_size))
    assert all(inside(pools.WIDE_RECIPE, load_spec(n)) for n in _heldout("wide", 64))
    assert all(inside(pools.BENCHMARK_RECIPE, load_spec(w)) for w in BENCHMARK_WORLDS)
    for kind in (*pools.ASSET_TYPES, "mixed"):
        assert inside(pools.BENCHMARK_RECIPE, WorldDistribution(kind).spec(5))


def test_the_shift_split_is_twelve_fixed_worlds_three_per_recipe():
    worlds = shift_worlds()
    assert SIZE == len(worlds) >= 12 and len({w.digest() for w in worlds}) == SIZE
    assert [w.name for w in worlds] == [f"shift-{k:02d}" for k in range(SIZE)]
    assert [w.placement.seed for w in worlds] == [shiftsplit.FIRST_SEED + k for k in range(SIZE)]
    assert [recipe_of(k) for k in range(SIZE)] == [r for r in RECIPES for _ in range(3)]
    assert {tuple(w.assets.mix) for w in worlds if recipe_of(int(w.name[-2:])) == "forest"} == {
        ("trees",)
    }
    assert shift_world(4) == shift_world(4)
    assert shift_world(4).digest() == "c4494b0e6ffaf458"  # fixed: a change moves every score


def test_no_pool_world_equals_a_world_of_any_shipped_suite_by_content():
    """By the spec digest (the content, the name left out): the worlds every training
    distribution can draw (each pool at the largest size a training config or the defaults
    give, and held-out worlds beyond any evaluation's), the worlds every shipped training
    config trains and evaluates on, against every world of every part of every shipped suite.
    The recipes of the shipped agents (:data:`AS_TRAINED`) keep the pp3 evaluation they were
    trained with; they are the only exception, and they say so."""
    suite_worlds = {
        spec.digest(): f"{suite.name}/{part.split}/{spec.name}"
        for suite in SUITES.values()
        for part in suite.parts
        for spec in part.specs()
    }
    pool = {}
    names = [n for n, c in shipped_configs().items() if c.kind == "train"]
    configs = [load_train_config(config_file(n, "train")) for n in names if n not in AS_TRAINED]
    for name in AS_TRAINED:
        kept = load_train_config(config_file(name, "train"))
        assert set(kept.eval_worlds) <= set(BENCHMARK_WORLDS)
        assert "the shipped" in config_file(name, "train").read_text()
    for kind in pools.KINDS:
        size = max([pools.POOL_SIZE, pools.WIDE_POOL_SIZE] +
                   [c.world_pool_size for c in configs])  # fmt: skip
        distribution = WorldDistribution(kind, size)
        pool.update({distribution.spec(k).digest(): distribution.spec(k).name for k in range(size)})
        pool.update({load_spec(n).digest(): n for n in _heldout(kind, 64)})
    for config in configs:
        for world in (*config.train_worlds, *config.eval_worlds):
            if not is_distribution(world):
                pool[load_spec(world).digest()] = world
    shared = {suite_worlds[d]: pool[d] for d in set(suite_worlds) & set(pool)}
    assert not shared, f"training or evaluation worlds equal suite worlds: {shared}"
    assert len(pool) > 5 * pools.WIDE_POOL_SIZE


def test_the_seeds_of_pools_and_splits_are_disjoint_by_construction():
    top = pools.MAX_POOL_SIZE
    ranges = {
        "benchmark": range(1, 4),
        "pools": range(pools.FIRST_SEED, pools.FIRST_SEED + top),
        "held-out": range(pools.HELDOUT_FIRST_SEED, pools.HELDOUT_FIRST_SEED + top),
        "test split": range(testsplit.FIRST_SEED, testsplit.FIRST_SEED + testsplit.SIZE),
        "shift split": range(shiftsplit.FIRST_SEED, shiftsplit.FIRST_SEED + SIZE),
        "wide": range(pools.WIDE_FIRST_SEED, pools.WIDE_FIRST_SEED + top),
        "wide held-out": range(pools.WIDE_HELDOUT_FIRST_SEED, pools.WIDE_HELDOUT_FIRST_SEED + top),
    }
    spans = sorted((r.start, r.stop, name) for name, r in ranges.items())
    for (_, stop, a), (start, _, b) in pairwise(spans):
        assert stop <= start, f"{a} and {b} share seeds"


def _heldout(kind: str, count: int) -> list[str]:
    return [pools.member_name(kind, k, heldout=True) for k in range(count)]
