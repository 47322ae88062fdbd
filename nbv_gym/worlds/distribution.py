"""World distributions for training: ``random:cuboids``, ``random:crosses``, ``random:helicoids``,
``random:trees`` and ``random:mixed``.

A distribution is a bounded pool of ``pool_size`` procedural worlds, world ``k`` generated from the
benchmark worlds' recipe (50 assets, Poisson cluster process, 60 m window) with placement seed
:data:`FIRST_SEED` ``+ k`` — disjoint from the benchmark's seeds (1–3), so the benchmark worlds
stay held out. ``random:mixed`` mixes the four asset types in equal shares in every world. Worlds
are built on first use and kept in the world cache (:func:`~nbv_gym.worlds.world.load_world`), so
building is paid once per world and the cache holds at most ``pool_size`` worlds per
distribution (about 1.5 MB per world of cuboids, crosses or helicoids; 18 MB per world of trees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.core.config import check
from nbv_gym.core.errors import UnknownNameError
from nbv_gym.worlds.spec import ASSET_TYPES, AssetConfig, PlacementConfig, WorldSpec
from nbv_gym.worlds.world import World, load_world

#: Prefix of a distribution's name: ``random:<asset type>`` or ``random:mixed``.
PREFIX = "random:"
#: The distributions' names after the prefix.
KINDS = (*ASSET_TYPES, "mixed")
#: Placement seed of a pool's world 0; world ``k`` uses ``FIRST_SEED + k``.
FIRST_SEED = 1000
#: Worlds in a pool unless configured otherwise.
POOL_SIZE = 32


def is_distribution(world: str) -> bool:
    """Whether ``world`` names a distribution (``random:…``) rather than one world."""
    return str(world).startswith(PREFIX)


@dataclass(frozen=True)
class WorldDistribution:
    """The pool of ``pool_size`` worlds behind ``random:<kind>``; ``kind`` is an asset type or
    ``"mixed"``."""

    kind: str
    pool_size: int = POOL_SIZE

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise UnknownNameError("world distribution", PREFIX + self.kind, distribution_names())
        check(self.pool_size >= 1, "world_pool_size", f"must be ≥ 1, got {self.pool_size}")

    @classmethod
    def from_name(cls, name: str, pool_size: int = POOL_SIZE) -> WorldDistribution:
        """The distribution of ``"random:<kind>"``."""
        return cls(str(name).removeprefix(PREFIX), pool_size)

    @property
    def name(self) -> str:
        """The distribution's world name (``dist:KIND``)."""
        return PREFIX + self.kind

    def spec(self, index: int) -> WorldSpec:
        """The spec of the pool's world ``index`` (0 ≤ index < ``pool_size``)."""
        check(0 <= index < self.pool_size, "index", f"expected [0, {self.pool_size}), got {index}")
        mix = {kind: 1.0 for kind in ASSET_TYPES} if self.kind == "mixed" else {self.kind: 1.0}
        return WorldSpec(
            name=f"random-{self.kind}-{index:04d}",
            placement=PlacementConfig(seed=FIRST_SEED + index),
            assets=AssetConfig(mix=mix),
            description=f"World {index} of {self.name} (placement seed {FIRST_SEED + index})",
        )

    def draw(self, rng: np.random.Generator) -> int:
        """A uniformly drawn index into the pool."""
        return int(rng.integers(self.pool_size))

    def world(self, index: int) -> World:
        """The pool's world ``index``, from the cache (built and cached on first use)."""
        return load_world(self.spec(index))


def distribution_names() -> list[str]:
    """``random:cuboids`` … ``random:mixed``."""
    return [PREFIX + kind for kind in KINDS]
