"""Policies: the registry and the interface (:mod:`~nbv_gym.policies.registry`), the paper's
frontier baselines (:mod:`~nbv_gym.policies.frontier`), its statistic-based NBV policies
(:mod:`~nbv_gym.policies.nbv`), the field's references (volumetric information gain
:mod:`~nbv_gym.policies.information_gain`, a frontier tour :mod:`~nbv_gym.policies.frontier_tour`,
the one-step ground-truth oracle :mod:`~nbv_gym.policies.oracle`), the time task's teacher
:mod:`~nbv_gym.policies.teacher` and the shipped trained agents (``models/``)."""

from nbv_gym.policies.registry import (
    MODELS,
    PAPER_POLICIES,
    POLICIES,
    PREFIXES,
    REFERENCE_POLICIES,
    SB3_PREFIX,
    TEACHER_POLICIES,
    Policy,
    PolicyError,
    episode_task,
    is_oracle,
    load_policy,
    model_path,
    policy_name,
    required_layers,
    trained_settings,
    trained_task,
    training_config_path,
)

__all__ = [
    "MODELS",
    "PAPER_POLICIES",
    "POLICIES",
    "PREFIXES",
    "REFERENCE_POLICIES",
    "SB3_PREFIX",
    "TEACHER_POLICIES",
    "Policy",
    "PolicyError",
    "episode_task",
    "is_oracle",
    "load_policy",
    "model_path",
    "policy_name",
    "required_layers",
    "trained_settings",
    "trained_task",
    "training_config_path",
]
