"""World distributions for training: ``random:cuboids``, ``random:crosses``, ``random:helicoids``,
``random:trees``, ``random:mixed`` and ``random:wide``.

A distribution is a bounded pool of ``pool_size`` procedural worlds; world ``k`` is
:func:`~nbv_gym.worlds.pools.member_data` (name ``random:<kind>/<k>``). The asset-type and
``mixed`` pools use the benchmark worlds' recipe (50 assets, Poisson cluster process, 60 m
window) with placement seed :data:`FIRST_SEED` ``+ k`` — disjoint from the benchmark's seeds
(1–3), so the benchmark worlds stay held out; ``random:mixed`` mixes the four asset types in
equal shares in every world. ``random:wide`` draws each world's asset count, clusters, cluster
radius, window, scale ranges and asset mix from :data:`~nbv_gym.worlds.pools.WIDE_RECIPE`, which
covers and exceeds the test split's ranges. Each pool has held-out worlds of its recipe
(``random:<kind>/heldout-<k>``, other seeds) for a training's own evaluation.

Worlds are built on first use and kept in the world cache
(:func:`~nbv_gym.worlds.world.load_world`), so building is paid once per world and the cache
holds at most ``pool_size`` worlds per distribution (about 1.5 MB per world of cuboids, crosses
or helicoids; 18 MB per world of 50 trees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nbv_gym.core.config import check
from nbv_gym.core.errors import UnknownNameError
from nbv_gym.worlds.pools import (
    FIRST_SEED,
    KINDS,
    MAX_POOL_SIZE,
    POOL_SIZE,
    PREFIX,
    WIDE_POOL_SIZE,
    is_distribution,
    member_name,
)
from nbv_gym.worlds.spec import WorldSpec, member_spec
from nbv_gym.worlds.world import World, load_world


@dataclass(frozen=True)
class WorldDistribution:
    """The pool of ``pool_size`` worlds behind ``random:<kind>``; ``kind`` is one of
    :data:`~nbv_gym.worlds.pools.KINDS`."""

    kind: str
    pool_size: int = POOL_SIZE

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise UnknownNameError("world distribution", PREFIX + self.kind, distribution_names())
        check(
            1 <= self.pool_size <= MAX_POOL_SIZE,
            "world_pool_size",
            f"must be from 1 to {MAX_POOL_SIZE}, got {self.pool_size}",
        )

    @classmethod
    def from_name(cls, name: str, pool_size: int = POOL_SIZE) -> WorldDistribution:
        """The distribution of ``"random:<kind>"``."""
        return cls(str(name).removeprefix(PREFIX), pool_size)

    @property
    def name(self) -> str:
        """The distribution's world name (``random:KIND``)."""
        return PREFIX + self.kind

    def spec(self, index: int) -> WorldSpec:
        """The spec of the pool's world ``index`` (0 ≤ index < ``pool_size``)."""
        check(0 <= index < self.pool_size, "index", f"expected [0, {self.pool_size}), got {index}")
        return member_spec(self.kind, index)

    def draw(self, rng: np.random.Generator) -> int:
        """A uniformly drawn index into the pool."""
        return int(rng.integers(self.pool_size))

    def world(self, index: int) -> World:
        """The pool's world ``index``, from the cache (built and cached on first use)."""
        return load_world(self.spec(index))


__all__ = [
    "FIRST_SEED", "KINDS", "MAX_POOL_SIZE", "POOL_SIZE", "PREFIX", "WIDE_POOL_SIZE",
    "WorldDistribution", "distribution_names", "heldout_names", "is_distribution", "member_name",
]  # fmt: skip


def distribution_names() -> list[str]:
    """``random:cuboids`` … ``random:wide``."""
    return [PREFIX + kind for kind in KINDS]


def heldout_names(kind: str, count: int) -> tuple[str, ...]:
    """The world names of held-out worlds 0 … ``count - 1`` of ``random:<kind>``."""
    return tuple(member_name(kind, index, heldout=True) for index in range(count))
