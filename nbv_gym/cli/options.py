"""Options shared by several commands: the task of ``run`` and ``record`` and the effort model."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from nbv_gym.cli.params import FINITE, POSITIVE, POSITIVE_COUNT
from nbv_gym.core.protocol import (
    BUDGET_SCANS,
    EXPLORE_MAX_STEPS,
    SCAN_TIME_S,
    SPEED_MPS,
    TIME_BUDGET_S,
)

TASK_HELP = (
    "explore (stop at 70 % discovered), budget (a fixed number of scans, travel free) or time "
    "(a budget of robot time: travel and scans charged) [default: the task a trained agent "
    "was trained under, else explore]."
)
BUDGET_HELP = f"Scans of the budget task [default: the agent's own budget, else {BUDGET_SCANS}]."
MAX_STEPS_HELP = f"Truncate the explore task after this many steps [default: {EXPLORE_MAX_STEPS}]."
TIME_BUDGET_HELP = f"Seconds of robot time of the time task [default: {TIME_BUDGET_S:g}]."
SPEED_HELP = (
    f"Driving speed of the effort model, m/s (every task's clock) [default: {SPEED_MPS:g}]."
)
SCAN_TIME_HELP = (
    f"Time of one stop-and-scan besides driving, s (every task's clock) [default: {SCAN_TIME_S:g}]."
)

#: The task options of ``run`` and ``record``, declared once (``task_of`` reads them).
TaskOption = Annotated[str | None, typer.Option(help=TASK_HELP)]
BudgetScansOption = Annotated[int | None, typer.Option(help=BUDGET_HELP, parser=POSITIVE_COUNT)]
MaxStepsOption = Annotated[int | None, typer.Option(help=MAX_STEPS_HELP, parser=POSITIVE_COUNT)]
TimeBudgetOption = Annotated[float | None, typer.Option(help=TIME_BUDGET_HELP, parser=POSITIVE)]
SpeedOption = Annotated[float | None, typer.Option(help=SPEED_HELP, parser=POSITIVE)]
ScanTimeOption = Annotated[float | None, typer.Option(help=SCAN_TIME_HELP, parser=FINITE)]


def task_of(
    policy: str,
    task: str | None,
    budget_scans: int | None,
    max_steps: int | None,
    time_budget_s: float | None = None,
) -> tuple[str, int | None]:
    """The task and budget of ``run``/``record`` (see :func:`nbv_gym.policies.episode_task`);
    a --max-steps, --budget-scans or --time-budget-s that the task does not read is refused."""
    from nbv_gym.core.errors import ConfigError
    from nbv_gym.policies import episode_task

    task, budget = episode_task(policy, task, budget_scans)
    if task != "explore" and max_steps is not None:
        budget_option = "--budget-scans" if task == "budget" else "--time-budget-s"
        raise ConfigError(f"--max-steps truncates the explore task; give {budget_option} instead.")
    if task != "budget" and budget_scans is not None:
        raise ConfigError(
            "--budget-scans is the budget task's; give --task budget, or --max-steps."
        )
    if task != "time" and time_budget_s is not None:
        raise ConfigError("--time-budget-s is the time task's; give --task time.")
    return task, budget


def task_episode_config(
    task: str,
    budget_scans: int | None,
    max_steps: int | None,
    time_budget_s: float | None,
    speed_mps: float | None,
    scan_time_s: float | None,
) -> Any:
    """The :class:`~nbv_gym.simulator.EpisodeConfig` of the options (after :func:`task_of`)."""
    from nbv_gym.core.config import from_dict
    from nbv_gym.core.protocol import EpisodeConfig, task_episode

    given = {"max_steps": max_steps, "speed_mps": speed_mps, "scan_time_s": scan_time_s}
    episode = from_dict(EpisodeConfig, {k: v for k, v in given.items() if v is not None})
    return task_episode(task, episode, budget_scans, time_budget_s)
