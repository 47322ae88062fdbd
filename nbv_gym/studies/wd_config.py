"""The config of the WD_occ study (:mod:`nbv_gym.studies.wd_analysis`), light to import: the
command line reads its defaults for its help text."""

from __future__ import annotations

from dataclasses import dataclass

from nbv_gym.core.config import check
from nbv_gym.core.protocol import NOISE_LEVELS, check_noise_level

PP1_WORLDS = ("pp1-cuboids", "pp1-crosses", "pp1-helicoids", "pp1-trees")


@dataclass(frozen=True)
class WdStudyConfig:
    """What the WD study computes.

    ``worlds``: worlds of the ideal-vs-random part and Table II; ``share_worlds``: worlds explored
    for the informative share (when no runs folder is given), each at every level of
    ``noise_levels``, ``policy`` for ``max_steps`` scans after the first; ``resolutions_m``: map
    resolutions of the share (0.1 is the runs' own; others are replayed from the scans);
    ``cuboids``: U_occ cuboids drawn per world for part 1 and WD*_occ (the paper: 500);
    ``share_cuboids``: observed U_occ cuboids drawn per map for the share; ``seed``: the base seed.
    """

    worlds: tuple[str, ...] = PP1_WORLDS
    share_worlds: tuple[str, ...] = ("pp1-cuboids", "pp1-trees")
    noise_levels: tuple[int, ...] = tuple(NOISE_LEVELS)
    resolutions_m: tuple[float, ...] = (0.1, 0.05)
    cuboids: int = 200
    share_cuboids: int = 300
    policy: str = "closest-frontier"
    max_steps: int = 20
    seed: int = 0

    def __post_init__(self):
        check(len(self.worlds) >= 1, "worlds", "name at least one world")
        check(self.cuboids >= 1, "cuboids", f"must be >= 1, got {self.cuboids}")
        check(self.share_cuboids >= 1, "share_cuboids", f"must be >= 1, got {self.share_cuboids}")
        check(self.max_steps >= 1, "max_steps", f"must be >= 1, got {self.max_steps}")
        for i, level in enumerate(self.noise_levels):
            check_noise_level(level, f"noise_levels[{i}]")
        from nbv_gym.studies.wd_analysis import study_grid

        for res in self.resolutions_m:
            study_grid(res)  # raises ConfigError unless the box is whole cuboids at res
