"""nbv-gym: a benchmark for autonomous lidar exploration and Next-Best-View research.

``import nbv_gym`` registers the Gymnasium environment ``nbv_gym/Explore-v0``::

    import gymnasium, nbv_gym
    env = gymnasium.make("nbv_gym/Explore-v0", world="pp1-trees", noise=1)
"""

from __future__ import annotations

import gymnasium

__version__ = "0.1.0"

ENV_ID = "nbv_gym/Explore-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="nbv_gym.env.explore:ExploreEnv")
