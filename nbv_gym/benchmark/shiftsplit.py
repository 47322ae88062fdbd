"""The shift split: generated worlds from recipes outside every training distribution.

The test split (:mod:`nbv_gym.benchmark.testsplit`) holds new worlds of a familiar kind: the
``random:wide`` training distribution covers its ranges. The shift split asks how a policy does
when the world is of a kind no training pool holds: each of its :data:`RECIPES` has at least one
range that shares no value with the same range of any training recipe
(:data:`~nbv_gym.worlds.pools.RECIPES`; a test keeps it so), and keeps the test split's other
ranges, so a drop from the test split is the named shift's:

- ``dense``: 150–200 assets (training pools: at most 120);
- ``sparse``: 6–14 assets (training pools: at least 20);
- ``clumps``: clusters of radius 1.5–3.5 m (training pools: at least 5 m);
- ``forest``: trees only, 130–170 of them spread by clusters of radius 45–60 m (training pools:
  at most 120 assets, radius at most 35 m).

Every recipe keeps the 60 m window: a larger one would grow the 60 × 60 goal grid that a trained
agent acts on, and the agent could not run there. World ``k`` (``shift-00`` … ``shift-11``) is
world ``k % 3`` of recipe ``k // 3``, with placement seed :data:`FIRST_SEED` ``+ k`` and its
numbers from SHA-256 of ``"nbv-gym shift split/k/field"``, so the specs are the same on every
machine.
"""

from __future__ import annotations

from nbv_gym.core.config import from_dict
from nbv_gym.worlds.recipe import ASSET_TYPES, Recipe, describe
from nbv_gym.worlds.spec import WorldSpec

#: Placement seed of shift world 0; world ``k`` uses ``FIRST_SEED + k``.
FIRST_SEED = 600_000
#: The test split's scale ranges, kept by every shift recipe.
_SCALES = {"scale_low": (0.5, 0.7), "scale_high": (1.3, 1.6)}
_MIXES = (ASSET_TYPES, ("cuboids", "trees"), ("crosses", "helicoids"))
#: The shift recipes by name; world ``i`` of a recipe uses its ``mixes[i]``.
RECIPES = {
    "dense": Recipe((150, 200), (3, 8), (10.0, 25.0), **_SCALES, mixes=_MIXES),
    "sparse": Recipe((6, 14), (2, 3), (10.0, 25.0), **_SCALES, mixes=_MIXES),
    "clumps": Recipe((40, 80), (4, 8), (1.5, 3.5), **_SCALES, mixes=_MIXES),
    "forest": Recipe((130, 170), (3, 6), (45.0, 60.0), **_SCALES, mixes=(("trees",),) * 3),
}
#: Worlds per recipe.
PER_RECIPE = 3
#: Worlds of the shift split.
SIZE = PER_RECIPE * len(RECIPES)


def shift_world(k: int) -> WorldSpec:
    """The spec of shift world ``k`` (0 ≤ k < :data:`SIZE`), named ``shift-00`` … ``shift-11``."""
    group = recipe_of(k)
    recipe = RECIPES[group]
    kinds = recipe.mixes[k % PER_RECIPE]
    numbers = recipe.draw(f"nbv-gym shift split/{k}", FIRST_SEED + k, kinds)
    description = f"Shift world {k} ({group}): {describe(numbers)}"
    return from_dict(WorldSpec, {"name": f"shift-{k:02d}", **numbers, "description": description})


def shift_worlds() -> tuple[WorldSpec, ...]:
    """The specs of the :data:`SIZE` shift worlds."""
    return tuple(shift_world(k) for k in range(SIZE))


def recipe_of(k: int) -> str:
    """The name of shift world ``k``'s recipe."""
    return list(RECIPES)[k // PER_RECIPE]
