"""Each run of a scorecard checked against itself: figures that the same episode fixes must agree.

A run's figures are not independent. :func:`inconsistent_run` finds the first run where they
disagree, and what (the validation refuses the card in one line naming the run and the field):

- **the clock**: ``elapsed_s`` is exactly what the effort model gives for the run's path and
  scans (``path_length_m / speed + steps × scan time``, :class:`~nbv_gym.core.protocol.EffortModel`;
  every suite runs its defaults) — a team run's is its latest robot's clock, from that robot's
  own path and scans, and its path and scans are the sums of its robots' —, and a time-task run
  ends within its part's budget; a budget or explore run takes no more scans than its part
  allows;
- **the curves**: ``q_time`` and ``q_path`` both start at Q after the first scan, and every
  point at or past the run's end (its elapsed time, its path) holds its final Q, rounded as the
  curves are (:data:`~nbv_gym.benchmark.curves.CURVE_DECIMALS`);
- **the area**: a time-task run's ``q_time_auc`` lies between the left and right Riemann sums of
  its own Q(t) samples on the time grid (the bounds of the area of a step function that does not
  fall between samples), widened by :data:`AREA_SLACK` and by the largest fall between two of
  its samples (Q falls rarely and little: at most 2.4e-4 between two 30-s samples over the
  9,516 runs of the shipped references, all of which lie within the unwidened bounds); the
  other tasks carry no area;
- **70 % discovered**: ``q_paper_70`` is a number exactly when the run discovered 70 %.

This proves that a card's figures are those of *some* episodes, not that they are this
policy's: a forgery that edits a run and everything derived from it consistently passes. Only
a re-run shows that (``nbv-gym leaderboard --verify``, :mod:`nbv_gym.benchmark.rerun`).
"""

from __future__ import annotations

from itertools import pairwise

from nbv_gym.benchmark.cardtypes import PartEntry, RunEntry, Scorecard, value_of
from nbv_gym.benchmark.curves import CURVE_DECIMALS, PATH_GRID_M, TIME_GRID_S, time_grid
from nbv_gym.core.protocol import DISCOVERED_TARGET, EffortModel

#: The slack of the area check beyond the curve's own falls: the rounding of its samples.
AREA_SLACK = 1e-6


def inconsistent_run(card: Scorecard) -> tuple[int, str] | None:
    """The index of the first run of ``card`` (runs already matched to the suite's parts) that
    disagrees with itself and what disagrees (:func:`run_problem`); None if none does."""
    parts = {part["split"]: part for part in card["suite"]["parts"]}
    for index, run in enumerate(card["runs"]):
        problem = run_problem(run, parts[run["split"]])
        if problem is not None:
            return index, problem
    return None


def run_problem(run: RunEntry, part: PartEntry) -> str | None:
    """What is inconsistent in ``run`` (a scorecard run of ``part``), naming the field; None if
    nothing. Figures a run does not carry (protocol version 1) are not checked."""
    for check in (_measured, _clock, _budget, _curves, _area, _target):
        problem = check(run, part)
        if problem is not None:
            return problem
    return None


def _clock(run: RunEntry, part: PartEntry) -> str | None:
    if "elapsed_s" not in run:
        return None
    effort = EffortModel()  # the suites' (nbv-gym score has no effort options)
    if "per_robot" in run:
        return _team_clock(run, effort)
    expected = effort.elapsed_s(run["path_length_m"], run["steps"])
    if run["elapsed_s"] != expected:
        return (
            f"elapsed_s is {run['elapsed_s']:.12g} s but its path and scans take {expected:.12g} s "
            f"(path_length_m {run['path_length_m']:.12g} m / {effort.speed_mps:g} m/s + steps "
            f"{run['steps']} × {effort.scan_time_s:g} s)"
        )
    return None


def _team_clock(run: RunEntry, effort: EffortModel) -> str | None:
    """A team run's clock, path and scans against its robots' (:func:`_clock`)."""
    robots = run["per_robot"]
    path = float(sum(robot["path_length_m"] for robot in robots))
    steps = sum(robot["steps"] for robot in robots)
    latest = max(effort.elapsed_s(robot["path_length_m"], robot["steps"]) for robot in robots)
    for name, held, expected in (("path_length_m", run["path_length_m"], path),
                                 ("steps", run["steps"], steps),
                                 ("elapsed_s", run["elapsed_s"], latest)):  # fmt: skip
        if held != expected:
            return f"{name} is {held:.12g} but its robots' (per_robot) give {expected:.12g}"
    return None


def _measured(run: RunEntry, part: PartEntry) -> str | None:
    """Q and the discovered fraction are measured after every run's first scan: never null."""
    for name in ("q", "discovered"):
        if run.get(name) is None:
            return f"{name} is null, but every run measures it (its first scan included)"
    return None


def _budget(run: RunEntry, part: PartEntry) -> str | None:
    budget = part.get("time_budget_s")
    if run["task"] == "time" and budget is not None and run.get("elapsed_s", 0.0) > budget:
        return f"elapsed_s is {run['elapsed_s']:g} s, over its part's time budget of {budget:g} s"
    cap = part.get("budget_scans") if run["task"] == "budget" else part.get("max_steps")
    if run["task"] != "time" and cap is not None and run["steps"] > cap:
        return f"steps is {run['steps']}, more than its part allows ({cap})"
    return None


def _curves(run: RunEntry, part: PartEntry) -> str | None:
    if "q_time" not in run or "q_path" not in run:
        return None
    if run["q_time"][0] != run["q_path"][0]:
        return (
            f"q_time[0] is {run['q_time'][0]} but q_path[0] is {run['q_path'][0]} (both are Q "
            "after the first scan)"
        )
    final = round(value_of(run, "q"), CURVE_DECIMALS)
    for name, grid, end in (
        ("q_time", time_grid(part), run.get("elapsed_s")),
        ("q_path", PATH_GRID_M, run["path_length_m"]),
    ):
        for k, (at, value) in enumerate(zip(grid, value_of(run, name), strict=True)):
            if end is not None and at >= end and value != final:
                unit = "s" if name == "q_time" else "m"
                return (
                    f"{name}[{k}] (at {at:g} {unit}, past the run's end at {end:g} {unit}) is "
                    f"{value} but its final Q is {run['q']}"
                )
    return None


def _area(run: RunEntry, part: PartEntry) -> str | None:
    if "q_time_auc" not in run:
        return None
    area = run["q_time_auc"]
    if run["task"] != "time":
        return None if area is None else f"q_time_auc is {area} in a {run['task']}-task run"
    if area is None:
        return "q_time_auc is null in a time-task run"
    q_time, q = value_of(run, "q_time"), value_of(run, "q")
    low, high = area_bounds(q_time, q, value_of(part, "time_budget_s"), time_grid(part))
    if not low <= area <= high:
        return (
            f"q_time_auc is {area:.6g} but its own Q(t) samples bound it to [{low:.6g}, {high:.6g}]"
        )
    return None


def area_bounds(
    q_time: list[float], final_q: float, budget_s: float, grid: tuple[float, ...] = TIME_GRID_S
) -> tuple[float, float]:
    """The range the normalised area under Q(t) over [0, ``budget_s``] may take given Q on the
    time ``grid`` (:data:`~nbv_gym.benchmark.curves.TIME_GRID_S`, or a team run's) and the run's final Q: per
    interval of the grid within the budget, Q between the samples at its ends (past the grid's
    end, between its last sample and the final Q) — the left and right Riemann sums of a rising
    curve —, widened by the largest fall between two samples and :data:`AREA_SLACK`."""
    low = high = 0.0
    for k, start in enumerate(grid):
        last = k + 1 == len(grid)
        stop = budget_s if last else min(grid[k + 1], budget_s)
        if stop <= start:
            break
        after = final_q if last else q_time[k + 1]
        low += min(q_time[k], after) * (stop - start)
        high += max(q_time[k], after) * (stop - start)
    falls = [a - b for a, b in pairwise(q_time)]
    slack = max([0.0, *falls]) + AREA_SLACK
    return low / budget_s - slack, high / budget_s + slack


def _target(run: RunEntry, part: PartEntry) -> str | None:
    reached = value_of(run, "discovered") >= DISCOVERED_TARGET
    if reached == (run["q_paper_70"] is None):
        state = "reached" if reached else "never reached"
        return (
            f"q_paper_70 is {run['q_paper_70']} but the run {state} "
            f"{DISCOVERED_TARGET * 100:g} % discovered (discovered {run['discovered']:g})"
        )
    return None
