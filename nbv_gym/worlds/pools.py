"""The training distributions' worlds as data: kinds, seeds, recipes and member names.

``random:<kind>`` is a pool of worlds for training (:class:`~nbv_gym.worlds.distribution.WorldDistribution`
draws from it); each pool also has held-out worlds of the same recipe with other seeds, for a
training's own evaluation. Every world of a pool has a name that works wherever a world name
does (``nbv-gym run --world``, sweeps, a training's ``eval_worlds``):

- ``random:<kind>/<k>``: world ``k`` of the pool;
- ``random:<kind>/heldout-<k>``: held-out world ``k``.

Kinds: ``cuboids``, ``crosses``, ``helicoids``, ``trees`` and ``mixed`` (all four, equal shares)
use the benchmark's recipe (50 assets in three clusters of radius 30 m, a 60 m window, scales
0.7–1.3; :data:`BENCHMARK_RECIPE`); ``wide`` draws every world's numbers from
:data:`WIDE_RECIPE`, whose ranges cover and exceed the test split's.

Placement seeds, disjoint by construction for every index below :data:`MAX_POOL_SIZE`: the
benchmark 1–3; ``random:<asset kind or mixed>`` 1000 + k, held out 101 000 + k; the test split
500 000 + k; the shift split 600 000 + k; ``random:wide`` 2 000 000 + k, held out
2 100 000 + k.

This module is data only; the spec module builds the specs (:func:`member_data`).
"""

from __future__ import annotations

from typing import Any

from nbv_gym.worlds.recipe import ASSET_TYPES, EVERY_MIX, Recipe

#: Prefix of a distribution's name: ``random:<kind>``.
PREFIX = "random:"
#: The distributions' kinds: an asset type, ``mixed`` or ``wide``.
KINDS = (*ASSET_TYPES, "mixed", "wide")
#: The most worlds a pool (and its held-out set) holds: keeps every pool's seeds disjoint.
MAX_POOL_SIZE = 100_000
#: Worlds of an asset-type or ``mixed`` pool unless configured otherwise (the environment's
#: default ``world_pool_size``).
POOL_SIZE = 32
#: Worlds of the ``random:wide`` pool a training draws from by default.
WIDE_POOL_SIZE = 256
#: Placement seed of world 0 of the asset-type and ``mixed`` pools, and of their held-out worlds.
FIRST_SEED = 1000
HELDOUT_FIRST_SEED = 101_000
#: Placement seed of world 0 of ``random:wide`` and of its held-out worlds.
WIDE_FIRST_SEED = 2_000_000
WIDE_HELDOUT_FIRST_SEED = 2_100_000
#: Text keys of the numbers of ``random:wide``'s worlds (:meth:`Recipe.draw`).
WIDE_KEY = "nbv-gym random:wide"

#: The recipe of the benchmark worlds and of the asset-type and ``mixed`` pools (their specs
#: leave these numbers at the spec's defaults: three clusters are ``max(2, 50 // 20 + 1)``).
BENCHMARK_RECIPE = Recipe(
    n_assets=(50, 50),
    n_parents=(3, 3),
    cluster_radius_m=(30.0, 30.0),
    mixes=(*((kind,) for kind in ASSET_TYPES), ASSET_TYPES),
)
#: The recipe of ``random:wide``: sparser and denser than the test split (30–80 assets), fewer
#: and more clusters (2–6), tighter and looser ones (8–22 m), smaller windows besides the 60 m
#: one (a larger window would grow the 60 × 60 goal grid a trained agent acts on), wider and
#: narrower scale ranges (0.5–0.7 to 1.3–1.6), and every single asset type and mix of them.
WIDE_RECIPE = Recipe(
    n_assets=(20, 120),
    n_parents=(2, 10),
    cluster_radius_m=(5.0, 35.0),
    window_side_m=(40.0, 60.0),
    scale_low=(0.45, 0.8),
    scale_high=(1.2, 1.7),
    mixes=EVERY_MIX,
)
#: Each distribution's training recipe.
RECIPES = {**dict.fromkeys((*ASSET_TYPES, "mixed"), BENCHMARK_RECIPE), "wide": WIDE_RECIPE}


def is_distribution(world: str) -> bool:
    """Whether ``world`` names a distribution (``random:…``) rather than one world (a benchmark
    name, a spec file or a pool's member ``random:<kind>/…``)."""
    return str(world).startswith(PREFIX) and "/" not in str(world)


def member_name(kind: str, index: int, heldout: bool = False) -> str:
    """The world name of world ``index`` of ``random:<kind>``'s pool (or held-out set)."""
    return f"{PREFIX}{kind}/{'heldout-' if heldout else ''}{index}"


def parse_member(name: str) -> tuple[str, int, bool] | None:
    """(kind, index, held out) of a member name ``random:<kind>/[heldout-]<k>`` (None for any
    other name; a kind or index out of range is returned as written, for the caller to
    refuse)."""
    text = str(name)
    if not text.startswith(PREFIX) or "/" not in text:
        return None
    kind, _, rest = text.removeprefix(PREFIX).partition("/")
    heldout = rest.startswith("heldout-")
    digits = rest.removeprefix("heldout-")
    if not digits.isdigit() or not digits.isascii():
        return None
    return kind, int(digits), heldout


def is_member_like(name: str) -> bool:
    """Whether ``name`` looks meant as a pool's world (``random:<kind>/…``, a known kind) but is
    no :func:`parse_member` name (its index is no whole number, or it has more parts)."""
    kind, slash, _ = str(name).removeprefix(PREFIX).partition("/")
    return str(name).startswith(PREFIX) and bool(slash) and kind in KINDS


def member_data(kind: str, index: int, heldout: bool = False) -> dict[str, Any]:
    """The spec (as a table: name, placement, assets, description) of world ``index`` of
    ``random:<kind>``'s pool, or of its held-out set; ``ValueError`` for an unknown kind or an
    index outside [0, :data:`MAX_POOL_SIZE`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown distribution kind {kind!r}")
    if not 0 <= index < MAX_POOL_SIZE:
        raise ValueError(f"index {index} outside [0, {MAX_POOL_SIZE})")
    which = "Held-out world" if heldout else "World"
    label = f"{kind}-heldout" if heldout else kind
    if kind == "wide":
        seed = (WIDE_HELDOUT_FIRST_SEED if heldout else WIDE_FIRST_SEED) + index
        numbers = WIDE_RECIPE.draw(f"{WIDE_KEY}/{seed}", seed)
    else:
        seed = (HELDOUT_FIRST_SEED if heldout else FIRST_SEED) + index
        mix = ASSET_TYPES if kind == "mixed" else (kind,)
        numbers = {"placement": {"seed": seed}, "assets": {"mix": dict.fromkeys(mix, 1.0)}}
    return {
        "name": f"random-{label}-{index:04d}",
        **numbers,
        "description": f"{which} {index} of {PREFIX}{kind} (placement seed {seed})",
    }
