"""The Gymnasium environment ``nbv_gym/Explore-v0`` (registered on ``import nbv_gym``)."""

from nbv_gym.env.explore import EnvConfig, ExploreEnv, GoalSpace

__all__ = ["EnvConfig", "ExploreEnv", "GoalSpace"]
