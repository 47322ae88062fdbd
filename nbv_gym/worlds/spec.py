"""World specs: the small TOML files that define a world, and the registry of benchmark worlds.

A spec fixes everything a world is generated from: the point process (seed, asset count,
clusters, window), the asset mix and pose ranges, the tree library and the ground plane. The
benchmark's twelve specs ship in the package (``worlds/`` in the source tree); a user passes the
path of their own file wherever a world name is accepted.
"""

from __future__ import annotations

import hashlib
import importlib.resources
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from nbv_gym.core.config import check, from_dict, parse_toml, read_text, to_dict
from nbv_gym.core.errors import ConfigError, UnknownNameError, missing_file
from nbv_gym.core.grid import MAX_WINDOW_M
from nbv_gym.core.names import check_name
from nbv_gym.worlds import pools
from nbv_gym.worlds.recipe import ASSET_TYPES
from nbv_gym.worlds.scenes.spec import SceneSpec, parse_scene_spec
from nbv_gym.worlds.trees import TreeConfig

#: Upper bounds of the values that size a world's memory and build time (the benchmark worlds
#: hold 50 assets from a library of 15 trees; 1000 assets in the 60 m window overlap already).
MAX_ASSETS = 1000
MAX_TREE_LIBRARY = 100


@dataclass(frozen=True)
class PlacementConfig:
    """Asset positions: a Poisson cluster (Neyman–Scott) process in ``window_m``
    (x_min, y_min, x_max, y_max); ``n_parents = 0`` means ``max(2, int(n_assets / 20) + 1)``
    (pointpats' process needs two clusters at least). No asset footprint enters the disc of
    ``clear_radius_m`` around the start (the origin)."""

    seed: int
    n_assets: int = 50
    n_parents: int = 0
    cluster_radius_m: float = 30.0
    window_m: tuple[float, float, float, float] = (-30.0, -30.0, 30.0, 30.0)
    clear_radius_m: float = 2.0

    def __post_init__(self) -> None:
        check(self.seed >= 0, "seed", "must be ≥ 0")
        check(
            2 <= self.n_assets <= MAX_ASSETS,
            "n_assets",
            f"must be from 2 to {MAX_ASSETS}, got {self.n_assets}",
        )
        check(
            self.n_parents == 0 or self.n_parents >= 2,
            "n_parents",
            "must be ≥ 2, or 0 for max(2, int(n_assets / 20) + 1)",
        )
        check(self.parents <= self.n_assets, "n_parents", "must not exceed n_assets")
        check(0 < self.cluster_radius_m < math.inf, "cluster_radius_m", "must be > 0 and finite")
        check(all(map(math.isfinite, self.window_m)), "window_m", "must be finite")
        x0, y0, x1, y1 = self.window_m
        check(x0 < 0 < x1 and y0 < 0 < y1, "window_m", "must contain the start (0, 0)")
        check(
            max(x1 - x0, y1 - y0) <= MAX_WINDOW_M,
            "window_m",
            f"its sides must be at most {MAX_WINDOW_M:g} m (the largest window the map grows "
            f"to), got {x1 - x0:g} m × {y1 - y0:g} m",
        )
        check(0 <= self.clear_radius_m < math.inf, "clear_radius_m", "must be ≥ 0 and finite")
        nearest = min(-x0, -y0, x1, y1)
        check(
            self.clear_radius_m < nearest,
            "clear_radius_m",
            f"the clear disc around the start must lie inside window_m (radius < {nearest:g} m, "
            f"its nearest edge), got {self.clear_radius_m:g}: assets would be pushed out of it",
        )

    @property
    def parents(self) -> int:
        """The number of cluster parents."""
        return self.n_parents or max(2, int(self.n_assets / 20) + 1)


@dataclass(frozen=True)
class AssetConfig:
    """Asset mix and poses: ``mix`` maps asset types to relative weights; yaw is uniform in
    [0, 2π); horizontal and vertical scale factors are uniform in their ranges."""

    mix: dict[str, float]
    scale_horizontal: tuple[float, float] = (0.7, 1.3)
    scale_vertical: tuple[float, float] = (0.7, 1.3)
    tree_library_seed: int = 0
    tree_library_size: int = 15
    tree: TreeConfig = field(default_factory=TreeConfig)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.mix) - set(ASSET_TYPES))
        check(not unknown, "mix", f"unknown asset type(s) {unknown}; valid: {list(ASSET_TYPES)}")
        check(
            bool(self.mix)
            and all(0 <= w < math.inf for w in self.mix.values())
            and sum(self.mix.values()) > 0,
            "mix",
            f"needs finite non-negative weights, not all zero, got {self.mix}",
        )
        for key in ("scale_horizontal", "scale_vertical"):
            low, high = getattr(self, key)
            check(0 < low <= high < math.inf, key, f"expected 0 < low ≤ high, got {(low, high)}")
        check(
            1 <= self.tree_library_size <= MAX_TREE_LIBRARY,
            "tree_library_size",
            f"must be from 1 to {MAX_TREE_LIBRARY}, got {self.tree_library_size}",
        )


@dataclass(frozen=True)
class WorldSpec:
    """Everything a world is generated from; ``ground_size_m`` is the side of the square ground
    plane centred on the origin."""

    name: str
    placement: PlacementConfig
    assets: AssetConfig
    description: str = ""
    ground_size_m: float = 64.0

    def __post_init__(self) -> None:
        check_name(self.name, "name")
        size = self.ground_size_m
        check(0 < size < math.inf, "ground_size_m", f"must be > 0 and finite, got {size:g}")
        x0, y0, x1, y1 = self.placement.window_m
        check(
            max(-x0, -y0, x1, y1) <= size / 2,
            "ground_size_m",
            f"the ground (±{size / 2:g} m around the origin) must cover placement.window_m "
            f"{self.placement.window_m}, so that every asset stands on it",
        )

    @property
    def window_m(self) -> tuple[float, float, float, float]:
        """Where the assets stand (``placement.window_m``)."""
        return self.placement.window_m

    def check_inside(self, low_xy: tuple[float, float], high_xy: tuple[float, float], what: str):
        """Raise :class:`ConfigError` naming ``placement.window_m`` unless the window lies in
        the box ``low_xy``–``high_xy`` (metres) of ``what`` (e.g. the map of a simulator)."""
        x0, y0, x1, y1 = self.placement.window_m
        inside = low_xy[0] <= x0 and low_xy[1] <= y0 and x1 <= high_xy[0] and y1 <= high_xy[1]
        check(
            inside,
            "placement.window_m",
            f"world {self.name!r} places assets in {self.placement.window_m}, outside {what} "
            f"(x from {low_xy[0]:g} to {high_xy[0]:g} m, y from {low_xy[1]:g} to "
            f"{high_xy[1]:g} m), where they are never mapped; keep the window inside it",
        )

    def digest(self) -> str:
        """A short hash of the spec's content (the name and description excluded)."""
        content = to_dict(self)
        content.pop("name"), content.pop("description")
        return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def parse_spec(text: str, source: str, base: Path | None = None) -> AnySpec:
    """The spec of TOML ``text``: a :class:`WorldSpec`, or a
    :class:`~nbv_gym.worlds.scenes.spec.SceneSpec` when it has a ``[scene]`` table (whose file
    is taken relative to ``base``); errors name ``source`` and the offending key."""
    data = parse_toml(text, source)
    if "scene" in data:
        return parse_scene_spec(data, source, base)
    for key in ("name", "placement", "assets"):
        if key not in data:
            raise ConfigError(f"{source}: missing required key {key!r}")
    try:
        return from_dict(WorldSpec, data)
    except ConfigError as error:
        raise ConfigError(f"{source}: {error}") from None


def benchmark_names() -> list[str]:
    """Names of the benchmark worlds shipped with the package, sorted."""
    return sorted(path.name.removesuffix(".toml") for path in _spec_files())


def load_spec(name_or_path: str | Path) -> AnySpec:
    """The spec of a benchmark world name (e.g. ``"pp1-trees"``), of a training pool's world
    (``"random:wide/heldout-3"``, :mod:`nbv_gym.worlds.pools`) or of a ``.toml`` file path
    (procedural, or a scene: :mod:`nbv_gym.worlds.scenes`)."""
    if not str(name_or_path).strip():
        raise ConfigError(
            "The world name is empty; give a benchmark world (see `nbv-gym worlds list`) or "
            "the path of a world spec file (.toml)."
        )
    if (member := pools.parse_member(str(name_or_path))) is not None:
        return member_spec(*member)
    if (
        pools.is_distribution(str(name_or_path))
        and str(name_or_path)[len(pools.PREFIX) :] in pools.KINDS
    ):
        raise ConfigError(
            f"world: {name_or_path!r} is a distribution, not one world; give one of its worlds "
            f"({name_or_path}/<k> or {name_or_path}/heldout-<k>) or a world name"
        )
    if pools.is_member_like(str(name_or_path)):
        raise ConfigError(
            f"world: {name_or_path!r} is no pool world; a pool's world is "
            f"random:<kind>/<k> or random:<kind>/heldout-<k>, k a whole number from 0 to "
            f"{pools.MAX_POOL_SIZE - 1:,} (e.g. random:wide/heldout-3)"
        )
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise ConfigError(f"World spec file {str(path)!r} {missing_file(path)}.")
        return parse_spec(read_text(path, "World spec file"), str(path), path.parent)
    files = {p.name.removesuffix(".toml"): p for p in _spec_files()}
    if str(name_or_path) not in files:
        raise UnknownNameError("world", str(name_or_path), files)
    spec = parse_spec(files[str(name_or_path)].read_text(encoding="utf-8"), str(name_or_path))
    assert isinstance(spec, WorldSpec)  # the shipped specs are procedural
    return spec


def member_spec(kind: str, index: int, heldout: bool = False) -> WorldSpec:
    """The spec of world ``index`` of the training pool ``random:<kind>`` (or of its held-out
    set): :func:`~nbv_gym.worlds.pools.member_data`; :class:`UnknownNameError` for an unknown
    kind, :class:`ConfigError` for an index out of range."""
    if kind not in pools.KINDS:
        names = [pools.PREFIX + k for k in pools.KINDS]
        raise UnknownNameError("world distribution", pools.PREFIX + kind, names)
    check(
        0 <= index < pools.MAX_POOL_SIZE,
        "world",
        f"{pools.member_name(kind, index, heldout)}: the index must be below {pools.MAX_POOL_SIZE}",
    )
    return from_dict(WorldSpec, pools.member_data(kind, index, heldout))


def asset_type(spec) -> str:
    """The asset type of a world spec, ``"mixed"`` when it mixes several, ``"scene"`` for a
    scene world."""
    if not isinstance(spec, WorldSpec):
        return "scene"
    kinds = [kind for kind, weight in spec.assets.mix.items() if weight > 0]
    return kinds[0] if len(kinds) == 1 else "mixed"


#: Any world spec: procedural assets or a scene file.
AnySpec = WorldSpec | SceneSpec


def _spec_files() -> list[Any]:
    folder = importlib.resources.files("nbv_gym.worlds") / "benchmark"
    return [p for p in folder.iterdir() if p.name.endswith(".toml")]
