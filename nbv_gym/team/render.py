"""A top-down picture of a team's exploration (``nbv-gym run --robots N``): the shared map and
its n_obs per 1 m column, every robot's path in its own colour, where it started, where it
stands and where it drives to (docs/team.md)."""

from __future__ import annotations

import numpy as np

from nbv_gym.env.render import render_exploration
from nbv_gym.team.simulator import TeamSimulator

#: A colour per robot (cycled past nine): none is the frontiers' orange or a cell class's grey.
ROBOT_COLOURS = ("tab:blue", "tab:red", "tab:purple", "tab:cyan", "magenta", "tab:olive",
                 "tab:brown", "navy", "lime")  # fmt: skip


def render_team_rgb(sim: TeamSimulator, size_px: int = 520) -> np.ndarray:
    """(size_px, 2 size_px, 3) uint8 picture of ``sim``'s team (module docstring): a robot's
    scans joined by its path (circles), its start (square), where it stands (star) and, while
    it drives, a dotted line to its goal (cross); titles: the team's scans, clock, discovered
    fraction, Q, Q_paper and summed path."""
    shared, summary = sim.shared, sim.shared.summary
    path_m = sum(robot.path_length_m for robot in sim.robots)
    titles = (
        f"{len(sim.robots)} robots · {len(sim.scans)} scans · t {sim.time_s:.0f} s · "
        f"discovered {shared.navigation.discovered_fraction:.0%}",
        f"Q {summary.q:.3f} · Q_paper {summary.q_paper:.3f} · paths {path_m:.0f} m",
    )
    return render_exploration(shared, titles, lambda axes: _draw_robots(axes, sim), size_px)


def _draw_robots(axes, sim: TeamSimulator) -> None:
    for index, robot in enumerate(sim.robots):
        colour = ROBOT_COLOURS[index % len(ROBOT_COLOURS)]
        xy = np.array([[p.x, p.y] for p in robot.trajectory])
        axes.plot(xy[:, 0], xy[:, 1], "-o", color=colour, markersize=3, linewidth=1.4,
                  label=f"robot {index}")  # fmt: skip
        axes.plot(*xy[0], "s", color=colour, markersize=6, markeredgecolor="black")
        axes.plot(*xy[-1], "*", color=colour, markersize=13, markeredgecolor="black")
        pending = sim.pending[index]
        if pending is not None:
            goal = pending[0]
            axes.plot([xy[-1, 0], goal.x], [xy[-1, 1], goal.y], ":", color=colour, linewidth=1.4)
            axes.plot(goal.x, goal.y, "X", color=colour, markersize=8, markeredgecolor="black")
