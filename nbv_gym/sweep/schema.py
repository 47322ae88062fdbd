"""The columns of a sweep's tables — ``runs.csv``, ``steps.csv``, ``cuboids.parquet`` — with their
unit and meaning, in one place: :func:`schema_markdown` prints them (docs/sweeps.md and
``nbv-gym report`` link to it) and :func:`with_column_docs` writes them into the parquet file's
metadata (key ``nbv_gym.columns``, a JSON list of ``{name, unit, meaning}``), so the file explains
itself. ``end_code`` sits beside ``end_reason``: a short code to group and filter by.

Units: ``m`` metres, ``s`` seconds, ``1`` a fraction or score in [0, 1], ``count``, ``index``,
``—`` a label.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

from nbv_gym.episode import STEP_COLUMNS
from nbv_gym.metrics.cuboids import COV_SETTINGS, CuboidConfig


@dataclass(frozen=True)
class Column:
    """One column: ``name``, ``unit`` and what it means."""

    name: str
    unit: str
    meaning: str


IDENTITY = (
    Column("key", "—", "run key world/noiseN/policy/repR"),
    Column("world", "—", "benchmark world name or spec file"),
    Column("asset", "—", "asset type of the world: cuboids, crosses, helicoids, trees or mixed"),
    Column("noise", "index", "localisation-noise level (0: none, 2: the most)"),
    Column("policy", "—", "policy name (or module:Class, sb3:PATH)"),
    Column("repeat", "index", "repeat number of this world, noise level and policy"),
)
#: Short codes of ``end_reason`` (the simulator's text starts with the given prefix).
END_CODES = {
    "target": "discovered ",  # the discovered fraction reached the target: terminated
    "max_steps": "reached max_steps",  # truncated at the step limit
    "no_goal": "no valid goal",  # truncated: no goal reachable
    "time": "time budget spent",  # truncated: the time task's budget buys no further goal
}
RUNS = (
    *IDENTITY,
    Column("seed", "—", "episode seed (from the sweep seed, world, noise and repeat)"),
    Column("oracle", "—", "true: the policy declares privileged = True (reads ground truth)"),
    Column("status", "—", "ok, or failed after every attempt"),
    Column("steps", "count", "scans after the first one"),
    Column("end_reason", "—", "why the episode ended, in words"),
    Column("end_code", "—", f"end_reason as a code: {', '.join(END_CODES)}; empty if failed"),
    Column("discovered", "1", "discovered fraction of the ground plane at the end"),
    Column("q", "1", "final map quality Q (fixed bounds; the reward's quantity)"),
    Column("q_paper", "1", "final Q_paper (paper eq. 3, min–max normalised)"),
    Column("path_length_m", "m", "length of the robot's path"),
    Column("elapsed_s", "s", "the robot's time: path / speed + scans × scan time (effort model)"),
    Column("wall_time_s", "s", "wall time of the episode (reset to end)"),
    Column("decision_time_s", "s", "mean time of the policy's act() per step (its decision)"),
    Column("total_time_s", "s", "wall time of the run, world loading included"),
    Column("attempts", "count", "attempts made (1 unless earlier ones failed)"),
    Column("host", "—", "machine that ran the last attempt"),
    Column("error", "—", "last error of a failed run"),
)
#: Unit and meaning of each step column; the columns and their order are the episode's
#: (:data:`nbv_gym.episode.STEP_COLUMNS`), so a column added there without a meaning here fails
#: at import.
_STEP_DOCS = {
    "step": ("index", "0 = the first scan at the start pose, then one per goal"),
    "goal": ("index", "goal cell i·60 + j of the 60 × 60 goal grid; −1 at step 0"),
    "discovered": ("1", "discovered fraction of the ground plane"),
    "q": ("1", "map quality Q after this step"),
    "q_paper": ("1", "Q_paper after this step"),
    "q_observed": ("1", "Q over the observed cuboids only"),
    "reward": ("1", "ΔQ of this step minus the path penalty (0 by default)"),
    "path_length_m": ("m", "path length so far"),
    "elapsed_s": ("s", "the robot's time so far: path / speed + scans × scan time"),
    "predicted_gain": ("—", "the nbv-* policy's predicted gain of the goal; NaN otherwise"),
    "realised_gain": ("—", "the same statistic's realised gain; NaN otherwise"),
    "time_s": ("s", "wall time since the reset"),
}
STEPS = (*IDENTITY, *(Column(name, *_STEP_DOCS[name]) for name in STEP_COLUMNS))
_Q_P, _Q_D = COV_SETTINGS[CuboidConfig.q_setting]
CUBOIDS = (
    *IDENTITY,
    Column("cuboid", "index", "flat index of the 1 m cuboid in G (row-major ix, iy, iz)"),
    Column("ix", "index", "cuboid index along x"),
    Column("iy", "index", "cuboid index along y"),
    Column("iz", "index", "cuboid index along z"),
    Column("u_occ", "—", "true: the ground truth holds an occupied voxel in it (U_occ)"),
    Column("observed", "—", "true: some reconstructed p lies outside (0.4, 0.6)"),
    Column("n_obs", "count", "observations of the cuboid (viewpoint statistic)"),
    Column("r_min", "m", "smallest viewing range; inf if never observed"),
    Column("n_omega", "count", "azimuth sectors (of 32) it was observed from"),
    Column("sigma_theta", "1", "spherical variance of the viewing directions"),
    *(
        Column(f"cov_p{p:g}_d{d:g}", "1", f"surface coverage: GT voxels with p > {p} within {d} m")
        for p, d in COV_SETTINGS
    ),
    Column("cov_q", "1", f"coverage at Q's setting (p {_Q_P}, d {_Q_D} m); U_occ cuboids"),
    Column("l1", "—", "Σ p over the cuboid's 1000 voxels; U_empty cuboids"),
    Column("quality", "1", "cuboid quality: cov on U_occ, (500 − L1) / 380 clipped on U_empty"),
)
TABLES = {"runs.csv": RUNS, "steps.csv": STEPS, "cuboids.parquet": CUBOIDS}
METADATA_KEY = b"nbv_gym.columns"


def names(columns: tuple[Column, ...]) -> tuple[str, ...]:
    """The names of ``columns``, in order."""
    return tuple(column.name for column in columns)


def end_reason_code(reason) -> str:
    """The :data:`END_CODES` code of an ``end_reason`` text; "" for none (a failed run),
    ``"other"`` for a text no code describes."""
    if not isinstance(reason, str) or not reason:
        return ""
    return next((code for code, prefix in END_CODES.items() if reason.startswith(prefix)), "other")


def with_column_docs(schema):
    """A pyarrow ``schema`` with the documentation of the :data:`CUBOIDS` columns it holds in its
    metadata under :data:`METADATA_KEY`."""
    docs = [asdict(c) for c in CUBOIDS if c.name in schema.names]
    return schema.with_metadata({**(schema.metadata or {}), METADATA_KEY: json.dumps(docs)})


def schema_markdown() -> str:
    """The three tables' columns as Markdown tables (name, unit, meaning)."""
    parts = []
    for table, columns in TABLES.items():
        rows = [f"| `{c.name}` | {c.unit} | {c.meaning} |" for c in columns]
        parts.append(
            f"### `{table}`\n\n| column | unit | meaning |\n|---|---|---|\n" + "\n".join(rows)
        )
    return "\n\n".join(parts)
