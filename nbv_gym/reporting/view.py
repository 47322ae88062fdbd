"""A 3D view of an exploration that a person can turn around: one self-contained HTML file.

``nbv-gym view RUN_DIR`` (or ``MAP.npz``) draws with plotly. The page loads plotly.js from its
CDN (a page of a few hundred kB to a few MB, the points alone) and, opened without a network,
says so and how to write one that needs none; ``offline=True`` inlines the 3.5 MB library so
that the file opens without a network:

- the map's occupied voxels (probability ≥ ``min_probability``, centre at least ``min_z_m``
  high: the default 0.2 m leaves out the ground, whose lidar rings would hide everything else,
  as the statistics do) coloured by their occupancy probability or by a viewpoint statistic of
  their 1 m cell of G (``n_obs``, ``r_min``, ``n_omega``, ``sigma_theta``; from the run's
  ``statistics.npz``);
- the world's ground truth, translucent slate grey (the run's world from ``summary.json``, or
  ``world``);
- the robot's path and scan poses (the run's ``trajectory.csv``), numbered by step.

Large clouds are thinned to ``max_points`` by a seeded random choice (said in the title), so the
page stays responsive.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nbv_gym.core.arrays import FloatArray
from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.trajectory import TRAJECTORY_NAME, read_trajectory
from nbv_gym.mapping.mapfile import load_map

COLOURINGS = ("probability", "n_obs", "r_min", "n_omega", "sigma_theta")
VIEW_NAME = "view.html"
PATH_HEIGHT_M = 0.3  # the path is drawn this high above the ground, visible over it
#: Colour of the ground-truth points: visible behind the map, not competing with it.
TRUTH_COLOUR = "rgba(95,105,125,0.45)"
#: Where the default camera looks from (plotly's scene units, the box's half-diagonal ~1):
#: far enough back that the whole world fits the page.
CAMERA_EYE = dict(x=-1.45, y=-1.85, z=1.2)


class ViewError(NbvGymError, ValueError):
    """What ``nbv-gym view`` was given cannot be drawn (missing files, unknown colouring)."""


@dataclass(frozen=True)
class Scene:
    """What the view draws: ``voxels`` (n, 3) occupied voxel centres (m) with ``values`` (n,)
    for their colour and its ``label``; ``truth`` (m, 3) ground-truth points or None;
    ``poses`` (k, 4) x, y, z (m), yaw (rad) per scan or None; ``title``."""

    voxels: FloatArray
    values: FloatArray
    label: str
    truth: FloatArray | None
    poses: FloatArray | None
    title: str


def load_scene(
    source: str | Path,
    colour_by: str = "probability",
    world: str | None = None,
    min_probability: float = 0.5,
    max_points: int = 150_000,
    seed: int = 0,
    min_z_m: float = 0.2,
) -> Scene:
    """The scene of a run folder (``map.npz``, and when present ``statistics.npz``,
    ``summary.json``, ``trajectory.csv``) or of a map file ``.npz``."""
    from nbv_gym.mapping.export import map_voxels

    if colour_by not in COLOURINGS:
        raise ViewError(f"unknown colouring {colour_by!r}; use one of {', '.join(COLOURINGS)}")
    source = Path(source)
    folder, map_path = (source, source / "map.npz") if source.is_dir() else (None, source)
    if not map_path.is_file():
        raise ViewError(f"{map_path}: no such map; give a run folder (nbv-gym run) or a map .npz")
    voxels, probability = map_voxels(load_map(map_path), min_probability)
    above = voxels[:, 2] >= min_z_m
    voxels, probability = voxels[above], probability[above]
    values, label = probability, "occupancy probability"
    if colour_by != "probability":
        values, label = _statistic(folder, colour_by, voxels), colour_by
    rng = np.random.default_rng(seed)
    keep = _thin(len(voxels), max_points, rng)
    summary = _summary(folder)
    world = world or summary.get("world")
    truth = _ground_truth(world, max_points, rng) if world else None
    trajectory = folder / TRAJECTORY_NAME if folder else None
    poses = read_trajectory(trajectory) if trajectory and trajectory.exists() else None
    title = _title(source, summary, len(voxels), keep.size)
    return Scene(voxels[keep], values[keep], label, truth, poses, title)


#: Shown in place of the figure when plotly.js did not load (the page opened without a network):
#: what happened and the command that writes a page that needs none.
NO_PLOTLY_MESSAGE = (
    "This 3D view draws with plotly.js, loaded from its CDN (cdn.plot.ly), and it did not load: "
    "no network? Write the page again with the library inside it (3.5 MB more), which opens "
    'anywhere: <code style="white-space: nowrap">nbv-gym view RUN_DIR --offline</code>.'
)
#: The message, first in the page (the figure's empty box would push it out of sight), and the
#: script, last, that hides it once the library has loaded.
_NO_PLOTLY_MESSAGE_BLOCK = f"""
<div id="nbv-gym-no-plotly" style="font: 16px sans-serif; margin: 2em; padding: 1em;
 border: 2px solid #b45309; background: #fffbeb; max-width: 50em">{NO_PLOTLY_MESSAGE}</div>
"""
_NO_PLOTLY_CHECK = """
<script>
if (typeof Plotly !== "undefined") {
  document.getElementById("nbv-gym-no-plotly").style.display = "none";
}
</script>
"""


def write_view(scene: Scene, path: str | Path, offline: bool = False) -> Path:
    """Write ``scene`` as one HTML page to ``path``: plotly.js from its CDN, or inlined when
    ``offline`` (the page then opens without a network, 3.5 MB larger). A page that loads the
    library from the CDN says so in place of the figure when it opens without a network."""
    path = Path(path)
    figure = scene_figure(scene)
    page = figure.to_html(include_plotlyjs=True if offline else "cdn", full_html=True,
                          config={"responsive": True})  # fmt: skip
    if not offline:
        page = page.replace("<body>", "<body>" + _NO_PLOTLY_MESSAGE_BLOCK, 1)
        page = page.replace("</body>", _NO_PLOTLY_CHECK + "</body>", 1)
    path.write_text(page, encoding="utf-8")
    return path


def scene_figure(scene: Scene):
    """The plotly Figure of ``scene``: voxels, faint ground truth, path and scan poses."""
    import plotly.graph_objects as go

    figure = go.Figure()
    if scene.truth is not None:
        figure.add_trace(_points(go, scene.truth, "ground truth", color=TRUTH_COLOUR))
    marker = dict(size=2.2, color=scene.values.astype(np.float32), colorscale="Viridis", showscale=True,
                  colorbar=dict(title=dict(text=scene.label, side="right"), thickness=14))  # fmt: skip
    figure.add_trace(_points(go, scene.voxels, "map (occupied voxels)", marker=marker))
    if scene.poses is not None and len(scene.poses):
        figure.add_traces(_path_traces(go, scene.poses))
    figure.update_layout(
        title=dict(text=scene.title, x=0.01, font=dict(size=15)),
        scene=dict(aspectmode="data", xaxis_title="x (m)", yaxis_title="y (m)",
                   zaxis_title="z (m)", camera=dict(eye=CAMERA_EYE)),
        legend=dict(x=0.01, y=0.94, bgcolor="rgba(255,255,255,0.7)"),
        margin=dict(l=0, r=0, t=40, b=0),
        template="plotly_white",
    )  # fmt: skip
    return figure


def _points(go, xyz: FloatArray, name: str, color=None, marker=None):
    marker = marker or dict(size=1.6, color=color)
    xyz = np.asarray(xyz, dtype=np.float32)  # float32 in the page: half the bytes, mm precision
    return go.Scatter3d(x=xyz[:, 0], y=xyz[:, 1], z=xyz[:, 2], mode="markers", name=name,
                        marker=marker, hoverinfo="skip" if color else None)  # fmt: skip


def _path_traces(go, poses: FloatArray) -> list:
    """The path through the scan poses, the scans numbered, the start and the last pose."""
    x, y = poses[:, 0], poses[:, 1]
    z = poses[:, 2] + PATH_HEIGHT_M
    steps = [str(i) for i in range(len(poses))]
    path = go.Scatter3d(x=x, y=y, z=z, mode="lines+markers+text", name="robot path and scans",
                        text=steps, textposition="top center", textfont=dict(size=10),
                        line=dict(color="crimson", width=5),
                        marker=dict(size=4, color="crimson"))  # fmt: skip
    ends = go.Scatter3d(x=x[[0, -1]], y=y[[0, -1]], z=z[[0, -1]], mode="markers",
                        name="start / last scan",
                        marker=dict(size=8, color=["limegreen", "black"],
                                    symbol=["diamond", "x"]))  # fmt: skip
    return [path, ends]


def _statistic(folder: Path | None, name: str, voxels: FloatArray) -> FloatArray:
    """(n,) the statistic ``name`` of the G cell holding each voxel (NaN outside G)."""
    from nbv_gym.mapping import ViewpointStatistics

    path = folder / "statistics.npz" if folder else None
    if path is None or not path.is_file():
        raise ViewError(f"colouring by {name} needs the run folder's statistics.npz")
    statistics = ViewpointStatistics.load(path)
    grid = statistics.grid
    index = grid.index(voxels)
    inside = grid.contains(index)
    values = np.full(len(voxels), np.nan)
    field = np.asarray(getattr(statistics, name), float)
    values[inside] = field[tuple(index[inside].T)]
    return values


def _ground_truth(world: str, max_points: int, rng) -> FloatArray:
    from nbv_gym.worlds import load_world

    points = load_world(world).ground_truth.points()
    return points[_thin(len(points), max_points, rng)]


def _thin(count: int, limit: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of at most ``limit`` of ``count`` items (all when they fit)."""
    if count <= limit:
        return np.arange(count)
    return np.sort(rng.choice(count, size=limit, replace=False))


def _summary(folder: Path | None) -> dict:
    path = folder / "summary.json" if folder else None
    from nbv_gym.core.inputs import read_json

    return read_json(path, "Run summary") if path and path.is_file() else {}


def _title(source: Path, summary: dict, total: int, shown: int) -> str:
    what = f"{summary['policy']} on {summary['world']}" if "policy" in summary else source.name
    final = summary.get("final", {})
    figures = f" · Q {final['q']:.3f} · discovered {final['discovered']:.0%}" if final else ""
    thinned = f" ({shown:,} of {total:,} voxels shown)" if shown < total else f" ({total:,} voxels)"
    return f"nbv-gym: {what}{figures}{thinned}"
