"""The test split: generated worlds held out from both the benchmark and the training pools.

The benchmark's twelve worlds (placement seeds 1–3, 50 assets, cluster radius 30 m, scales
0.7–1.3) are what the paper tuned on, and the asset-type ``random:`` training pools
(:mod:`nbv_gym.worlds.distribution`) draw from the same recipe with seeds ``1000 + k``. A policy
can fit either. The test split asks how it does on worlds of a *different recipe*
(:data:`RECIPE`): placement seeds from :data:`FIRST_SEED`, 30–80 assets, tighter clusters
(radius 8–22 m), 2–6 clusters, wider scale ranges, and mixes of two or four asset types besides
single types. The ``random:wide`` training distribution covers these ranges (with other seeds),
so the test split measures generalisation to new worlds of a familiar kind; the shift split
(:mod:`nbv_gym.benchmark.shiftsplit`) goes outside them.

Every number of world ``k``'s recipe comes from SHA-256 of ``"nbv-gym test split/k/field"``
(:meth:`~nbv_gym.worlds.recipe.Recipe.draw`), so the specs are the same on every machine and
with every numpy; changing them changes the suites' content hash
(:mod:`nbv_gym.benchmark.suites`), which flags every stored scorecard as stale.
"""

from __future__ import annotations

from nbv_gym.core.config import from_dict
from nbv_gym.worlds.recipe import ASSET_TYPES, Recipe, describe
from nbv_gym.worlds.spec import WorldSpec

#: Placement seed of test world 0; world ``k`` uses ``FIRST_SEED + k`` (training pools: 1000 + k).
FIRST_SEED = 500_000
#: Asset mixes of the worlds after the single-type ones (equal weights).
MIXES = (
    ("cuboids", "trees"),
    ("crosses", "helicoids"),
    ASSET_TYPES,
    ("helicoids", "trees"),
)
#: Worlds of the full test split: three of each asset type, then one of each mix.
SIZE = 3 * len(ASSET_TYPES) + len(MIXES)
#: The ranges of the test worlds' numbers (60 m windows, as the benchmark's).
RECIPE = Recipe(
    n_assets=(30, 80),
    n_parents=(2, 6),
    cluster_radius_m=(8.0, 22.0),
    scale_low=(0.5, 0.7),
    scale_high=(1.3, 1.6),
    mixes=(*((kind,) for kind in ASSET_TYPES), *MIXES),
)


def split_world(k: int) -> WorldSpec:
    """The spec of test world ``k`` (0 ≤ k < :data:`SIZE`), named ``test-00`` … ``test-15``."""
    kinds = (ASSET_TYPES[k % len(ASSET_TYPES)],) if k < 3 * len(ASSET_TYPES) else MIXES[k - 12]
    numbers = RECIPE.draw(f"nbv-gym test split/{k}", FIRST_SEED + k, kinds)
    description = f"Test world {k}: {describe(numbers)}"
    return from_dict(WorldSpec, {"name": f"test-{k:02d}", **numbers, "description": description})


def split_worlds(indices: range | tuple[int, ...] = range(SIZE)) -> tuple[WorldSpec, ...]:
    """The specs of the test worlds ``indices`` (default: all :data:`SIZE`)."""
    return tuple(split_world(k) for k in indices)
