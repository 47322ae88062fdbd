"""nbv-gym: a benchmark for autonomous lidar exploration and Next-Best-View research.

``import nbv_gym`` registers the Gymnasium environments ``nbv_gym/Explore-v0`` (the paper's
protocol), ``nbv_gym/ExploreBudget-v0`` (a fixed budget of scans, travel free) and
``nbv_gym/ExploreTime-v0`` (a budget of robot time, travel and scans charged), see
:mod:`nbv_gym.core.protocol`::

    import gymnasium, nbv_gym
    env = gymnasium.make("nbv_gym/Explore-v0", world="pp1-trees", noise=1)
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

import gymnasium

try:  # the version is stated once, in pyproject.toml
    __version__ = version("nbv-gym")
except PackageNotFoundError:  # a source tree on sys.path without an install
    __version__ = "0+unknown"

from nbv_gym.core.protocol import (
    BUDGET_ID,
    BUDGET_SCANS,
    EXPLORE_ID,
    EXPLORE_MAX_STEPS,
    TIME_BUDGET_S,
    TIME_ID,
    EffortModel,
)

ENV_ID = EXPLORE_ID

for _id, _kwargs, _limit in (
    (EXPLORE_ID, {}, EXPLORE_MAX_STEPS),
    (BUDGET_ID, {"task": "budget"}, BUDGET_SCANS),
    # the scan cap of the default budget, which never binds (a larger budget needs a larger
    # max_episode_steps through gymnasium.make)
    (TIME_ID, {"task": "time"}, EffortModel().scan_cap(TIME_BUDGET_S)),
):
    if _id not in gymnasium.registry:
        gymnasium.register(
            id=_id,
            entry_point="nbv_gym.env.explore:ExploreEnv",
            kwargs=_kwargs,
            max_episode_steps=_limit,
        )
