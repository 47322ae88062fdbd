"""Options shared by several commands: the task of ``run`` and ``record``, the effort model
and the lidar preset."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from nbv_gym.cli.params import POSITIVE_COUNT, number
from nbv_gym.core.protocol import (
    BUDGET_SCANS,
    EFFORT_RANGES,
    EXPLORE_MAX_STEPS,
    SCAN_TIME_S,
    SPEED_MPS,
    TIME_BUDGET_S,
)


def _effort(key: str) -> tuple[str, object]:
    """The range text and the parser of the effort value ``key`` (:data:`EFFORT_RANGES`)."""
    low, high, unit = EFFORT_RANGES[key]
    return f"{low:,g} to {high:,g} {unit}", number(float, low, high)


_BUDGET_RANGE, _BUDGET = _effort("time_budget_s")
_SPEED_RANGE, _SPEED = _effort("speed_mps")
_SCAN_RANGE, _SCAN = _effort("scan_time_s")

TASK_HELP = (
    "explore (stop at 70 % discovered), budget (a fixed number of scans, travel free) or time "
    "(a budget of robot time: travel and scans charged) [default: the task a trained agent "
    "was trained under, else explore]."
)
BUDGET_HELP = f"Scans of the budget task [default: the agent's own budget, else {BUDGET_SCANS}]."
MAX_STEPS_HELP = f"Truncate the explore task after this many steps [default: {EXPLORE_MAX_STEPS}]."
TIME_BUDGET_HELP = (
    f"Seconds of robot time of the time task, {_BUDGET_RANGE} [default: the agent's own, else "
    f"{TIME_BUDGET_S:g}]."
)
SPEED_HELP = (
    f"Driving speed of the effort model, {_SPEED_RANGE} (every task's clock) [default: the "
    f"agent's own, else {SPEED_MPS:g}]."
)
SCAN_TIME_HELP = (
    f"Time of one stop-and-scan besides driving, {_SCAN_RANGE} (every task's clock) [default: "
    f"the agent's own, else {SCAN_TIME_S:g}]."
)

#: The task options of ``run`` and ``record``, declared once (``task_of`` reads them).
TaskOption = Annotated[str | None, typer.Option(help=TASK_HELP)]
BudgetScansOption = Annotated[int | None, typer.Option(help=BUDGET_HELP, parser=POSITIVE_COUNT)]
MaxStepsOption = Annotated[int | None, typer.Option(help=MAX_STEPS_HELP, parser=POSITIVE_COUNT)]
TimeBudgetOption = Annotated[float | None, typer.Option(help=TIME_BUDGET_HELP, parser=_BUDGET)]
SpeedOption = Annotated[float | None, typer.Option(help=SPEED_HELP, parser=_SPEED)]
ScanTimeOption = Annotated[float | None, typer.Option(help=SCAN_TIME_HELP, parser=_SCAN)]


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


def task_config(
    policy: str,
    noise: int,
    task: str | None,
    budget_scans: int | None,
    max_steps: int | None,
    time_budget_s: float | None,
    speed_mps: float | None,
    scan_time_s: float | None,
    lidar: str | None,
) -> Any:
    """The :class:`~nbv_gym.env.task.TaskConfig` of the task options of ``run`` and ``record``
    (:func:`task_of`; a trained agent's own settings fill the options left out:
    :func:`agent_options`)."""
    from nbv_gym.env.task import TaskConfig

    task, budget_scans = task_of(policy, task, budget_scans, max_steps, time_budget_s)
    own = agent_options(policy, task, lidar=lidar, time_budget_s=time_budget_s,
                        speed_mps=speed_mps, scan_time_s=scan_time_s)  # fmt: skip
    given = {"budget_scans": budget_scans, "max_steps": max_steps, **own}
    return TaskConfig(name=task, noise=noise, **{k: v for k, v in given.items() if v is not None})


LIDAR_HELP = (
    "Lidar preset (beam pattern): os1-16 (the benchmark's), os1-64, os1-128, vlp-16, hdl-32e; "
    "nbv-gym configs lidars lists them."
)
#: ``--lidar NAME`` of ``run``, ``record``, ``sweep``, ``score`` and ``train``.
LidarOption = Annotated[str | None, typer.Option(help=LIDAR_HELP + " [default: os1-16]")]
#: ``--lidar NAME`` of ``run`` and ``record``, whose default is a trained agent's own.
AgentLidarOption = Annotated[
    str | None, typer.Option(help=LIDAR_HELP + " [default: the agent's own, else os1-16]")
]


#: The options of ``run`` and ``record`` that a trained agent's own settings fill in when left
#: out (its training config): its lidar; for an agent of the time task, its effort model and,
#: when it runs the time task, its time budget.
AGENT_OPTIONS = {
    "lidar": "--lidar",
    "time_budget_s": "--time-budget-s",
    "speed_mps": "--speed-mps",
    "scan_time_s": "--scan-time-s",
}


def agent_options(policy: str, task: str, **given: Any) -> dict[str, Any]:
    """The lidar and effort options (:data:`AGENT_OPTIONS`' keys) of ``run``/``record`` for
    ``policy`` under ``task``: each ``given`` one, else the trained agent's own
    (:func:`~nbv_gym.policies.trained_settings`), else None (the default). A given option that
    differs from the agent's own is refused: the agent would meet another sensor or clock than
    it learned from, while its run said nothing."""
    from nbv_gym.core.errors import ConfigError
    from nbv_gym.policies import trained_settings

    found = trained_settings(policy)
    if found is None:
        return given
    path, own = found
    applies = {"lidar"} | ({"speed_mps", "scan_time_s"} if own["task"] == "time" else set())
    if own["task"] == task == "time":
        applies.add("time_budget_s")
    out = dict(given)
    for key in applies:
        if given[key] is not None and given[key] != own[key]:
            raise ConfigError(
                f"{AGENT_OPTIONS[key]} {given[key]}: {policy} was trained with {key} = "
                f"{own[key]!r} ({path}); leave {AGENT_OPTIONS[key]} out to run it as it was "
                "trained, or train an agent for this setting."
            )
        out[key] = own[key]
    return out
