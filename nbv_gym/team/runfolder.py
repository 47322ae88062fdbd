"""The run folder of a team episode (``nbv-gym run --robots N``, docs/team.md): ``scans.csv``
(a row per scan), ``summary.json`` (the run's settings and config, the team's ``figures``,
``per_robot``: a row per robot, the map quality, wall time and versions), the final map and
statistics (``map.npz``, ``statistics.npz``), ``paths.png`` (every robot's path in its own
colour) and ``exploration.gif``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from nbv_gym.episode import write_run_files
from nbv_gym.team.env import TeamEnv
from nbv_gym.team.episode import TeamEpisodeResult

#: The columns of ``scans.csv``: the robot, the team's clock (s), the team's summed path (m),
#: Q, Q_paper and the discovered fraction after the scan.
SCAN_COLUMNS = ("robot", "time_s", "path_length_m", "q", "q_paper", "discovered")
#: The files a team run writes into its run folder.
TEAM_RUN_FILES = ("scans.csv", "summary.json", "map.npz", "statistics.npz", "paths.png",
                  "exploration.gif")  # fmt: skip


def write_team_run_folder(
    out: Path, env: TeamEnv, result: TeamEpisodeResult, meta: dict[str, Any]
) -> dict[str, Any]:
    """Write the scan table, the summary, the final map and statistics and the picture of the
    robots' paths to ``out``; the summary (what ``summary.json`` holds)."""
    from PIL import Image

    from nbv_gym.team.render import render_team_rgb

    figures = {"figures": result.figures, "per_robot": result.robots,
               "n_scans": len(result.scans), "wall_time_s": result.wall_time_s}  # fmt: skip
    table = ("scans.csv", SCAN_COLUMNS, result.scans)
    summary = write_run_files(out, table, meta, env.config, figures, env.sim.shared.summary)
    env.sim.shared.save(out)
    Image.fromarray(render_team_rgb(env.sim)).save(out / "paths.png")
    return summary
