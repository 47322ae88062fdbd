"""The Gymnasium environment ``nbv_gym/Explore-v0`` (registered on ``import nbv_gym``) and
:class:`TaskConfig`, the one declaration of a task's settings."""

from nbv_gym.env.explore import EnvConfig, ExploreEnv, GoalSpace
from nbv_gym.env.task import TaskConfig

__all__ = ["EnvConfig", "ExploreEnv", "GoalSpace", "TaskConfig"]
