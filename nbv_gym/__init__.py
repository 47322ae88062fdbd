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

from nbv_gym.core.protocol import EXPLORE_ID, TASK_IDS

ENV_ID = EXPLORE_ID

# No id sets max_episode_steps: each task has one truncation, the environment's own (max_steps,
# the budget of scans, the time budget), and its info's end_reason says which ended an episode.
for _task, _id in TASK_IDS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(
            id=_id, entry_point="nbv_gym.env.explore:task_env", kwargs={"id_task": _task}
        )
