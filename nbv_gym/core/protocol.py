"""The two tasks of nbv-gym (docs/protocol.md#tasks) and their Gymnasium ids (registered on ``import nbv_gym``).

- ``explore`` — ``nbv_gym/Explore-v0``, the paper's protocol: an episode terminates at 70 %
  of the ground discovered and is truncated at :data:`EXPLORE_MAX_STEPS` steps.
- ``budget`` — ``nbv_gym/ExploreBudget-v0``, equal effort: a fixed budget of scans
  (:data:`BUDGET_SCANS` by default), never terminated by the discovered fraction, truncated at the
  budget. The reward is ΔQ in both, so a budget episode's return is Q after the budget minus Q
  after the first scan; its score is Q after the budget (and the area under Q against scans).

This module imports nothing heavy: ``import nbv_gym`` reads it to register the ids.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from nbv_gym.core.errors import ConfigError

TASKS = ("explore", "budget")
EXPLORE_ID = "nbv_gym/Explore-v0"
BUDGET_ID = "nbv_gym/ExploreBudget-v0"
#: Gymnasium id of each task.
TASK_IDS = {"explore": EXPLORE_ID, "budget": BUDGET_ID}
#: Truncation of the explore task (``EpisodeConfig.max_steps``).
EXPLORE_MAX_STEPS = 100
#: Default budget of the budget task: scans after the first one. Measured at noise 1 (pp1-cuboids,
#: pp1-trees, pp2-crosses, pp2-helicoids × 2 seeds), the baseline fastest to 70 % discovered,
#: random-frontier, needs 5–11 scans (median 7), random-free a median of 11 (one episode never),
#: closest-frontier 9–23 (median 15): after 12 scans every random-frontier episode has passed 70 %
#: and Q still rises for every policy, so the budget rewards quality per scan, not discovery.
BUDGET_SCANS = 12


def task_episode(task: str, episode: Any, budget_scans: int | None = None) -> Any:
    """``episode`` (an :class:`~nbv_gym.simulator.EpisodeConfig`) for ``task``: unchanged for
    ``explore``; for ``budget`` without termination and with ``max_steps`` = ``budget_scans``
    (default :data:`BUDGET_SCANS`)."""
    check_task(task)
    if task == "explore":
        return episode
    return replace(episode, discovered_target=None, max_steps=budget_scans or BUDGET_SCANS)


def check_task(task: str) -> None:
    """Raise :class:`ConfigError` unless ``task`` is one of :data:`TASKS`."""
    if task not in TASKS:
        raise ConfigError(f"task: expected one of {', '.join(TASKS)}, got {task!r}")
