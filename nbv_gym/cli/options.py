"""Options shared by several commands: the task of ``run`` and ``record``."""

from __future__ import annotations

from typing import Annotated

import typer

from nbv_gym.cli.params import POSITIVE_COUNT
from nbv_gym.core.protocol import BUDGET_SCANS, EXPLORE_MAX_STEPS

TASK_HELP = (
    "explore (stop at 70 % discovered) or budget (a fixed number of scans) [default: the "
    "task a trained agent was trained under, else explore]."
)
BUDGET_HELP = f"Scans of the budget task [default: the agent's own budget, else {BUDGET_SCANS}]."
MAX_STEPS_HELP = f"Truncate the explore task after this many steps [default: {EXPLORE_MAX_STEPS}]."

#: The task options of ``run`` and ``record``, declared once (``task_of`` reads them).
TaskOption = Annotated[str | None, typer.Option(help=TASK_HELP)]
BudgetScansOption = Annotated[int | None, typer.Option(help=BUDGET_HELP, parser=POSITIVE_COUNT)]
MaxStepsOption = Annotated[int | None, typer.Option(help=MAX_STEPS_HELP, parser=POSITIVE_COUNT)]


def task_of(
    policy: str, task: str | None, budget_scans: int | None, max_steps: int | None
) -> tuple[str, int | None]:
    """The task and budget of ``run``/``record`` (see :func:`nbv_gym.policies.episode_task`);
    a --max-steps or --budget-scans that the task does not read is refused."""
    from nbv_gym.core.errors import ConfigError
    from nbv_gym.policies import episode_task

    task, budget = episode_task(policy, task, budget_scans)
    if task == "budget" and max_steps is not None:
        raise ConfigError("--max-steps truncates the explore task; give --budget-scans instead.")
    if task == "explore" and budget_scans is not None:
        raise ConfigError(
            "--budget-scans is the budget task's; give --task budget, or --max-steps."
        )
    return task, budget
