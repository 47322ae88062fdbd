"""Run one policy for one episode and keep what a run folder needs (``nbv-gym run``)."""

from __future__ import annotations

import csv
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from nbv_gym.core.config import to_dict
from nbv_gym.core.jsonfiles import dumps_json
from nbv_gym.core.provenance import versions
from nbv_gym.env.explore import EnvConfig, ExploreEnv
from nbv_gym.env.views import agent_view
from nbv_gym.policies import Policy, PolicyError, is_oracle, policy_name, required_layers
from nbv_gym.simulator import InvalidActionError

STEP_COLUMNS = (
    "step", "goal", "discovered", "q", "q_paper", "q_observed", "reward", "path_length_m",
    "elapsed_s", "predicted_gain", "realised_gain", "time_s",
)  # fmt: skip
#: The files ``nbv-gym run`` writes into its run folder (besides the trajectory).
RUN_FILES = ("steps.csv", "summary.json", "map.npz", "statistics.npz", "map.ply", "exploration.gif")


@dataclass
class EpisodeResult:
    """The per-step table (one dict per row, :data:`STEP_COLUMNS`, step 0 = the first scan;
    ``elapsed_s`` is the robot's clock under the effort model in every task,
    :class:`~nbv_gym.core.protocol.EffortModel`; ``time_s`` the wall time) and the final figures
    of an episode."""

    steps: list[dict[str, float]] = field(default_factory=list)
    end_reason: str = ""
    wall_time_s: float = 0.0
    #: Whether the policy ran as an oracle (saw the full ``info``): its ``privileged`` flag as
    #: read once at the episode's start, which is what results record.
    oracle: bool = False

    @property
    def final(self) -> dict[str, float]:
        """The last row of the step table."""
        return self.steps[-1]


def make_env(config: EnvConfig, policy: Policy, render: bool = False) -> ExploreEnv:
    """An environment that computes the optional layers ``policy`` declares."""
    layers = tuple(dict.fromkeys((*config.observation_layers, *required_layers(policy))))
    visibility = getattr(policy, "visibility", None)
    nbv = config.nbv if visibility is None else replace(config.nbv, visibility=visibility)
    return ExploreEnv(
        "rgb_array" if render else None, replace(config, observation_layers=layers, nbv=nbv)
    )


def run_episode(
    env: ExploreEnv,
    policy: Policy,
    seed: int,
    on_step: Callable[[dict[str, float], ExploreEnv], None] | None = None,
) -> EpisodeResult:
    """Run ``policy`` in ``env`` from ``reset(seed=seed)`` until the episode ends; ``on_step`` is
    called with each new row (the first scan included). The policy sees :func:`policy_info`;
    a normal policy that reads a privileged key raises
    :class:`~nbv_gym.env.views.PrivilegedInfoError`. An episode that ends at its first scan (a
    time budget that leaves no goal) is a run of 0 steps: the policy is not asked."""
    start = time.perf_counter()
    observation, info, oracle = start_episode(env, policy, seed)
    result = EpisodeResult(oracle=oracle)
    clock = cast(ExploreEnv, env.unwrapped).sim  # the robot's clock, in every task
    row = _row(0, -1, info, 0.0, start, policy, clock.elapsed_s)
    done = bool(info["end_reason"])  # over at the first scan: nothing to decide
    while True:
        result.steps.append(row)
        if on_step:
            on_step(row, env)
        if done:
            break
        goal = policy.act(observation, policy_info(policy, info, oracle))
        try:
            observation, reward, terminated, truncated, info = env.step(goal)
        except InvalidActionError as error:
            where = f"Policy {policy_name(policy)} at step {len(result.steps)}"
            raise PolicyError(f"{where}: {error}") from None
        row = _row(len(result.steps), int(goal), info, reward, start, policy, clock.elapsed_s)
        done = terminated or truncated
    result.end_reason = info["end_reason"]
    result.wall_time_s = time.perf_counter() - start
    return result


def start_episode(env, policy: Policy, seed: int | None) -> tuple[dict, dict, bool]:
    """Reset ``env`` (an ``ExploreEnv``, wrapped or not) with ``seed`` and ``policy`` with the
    same seed, then read once whether the policy is an oracle this episode
    (:func:`~nbv_gym.policies.is_oracle`; a flag flipped later changes nothing until the next
    episode); an oracle with an ``attach`` method then gets the unwrapped environment
    (``policy.attach(env.unwrapped)``). The reset's observation, full info and that reading."""
    observation, info = env.reset(seed=seed)
    policy.reset(seed)
    oracle = is_oracle(policy)
    attach = getattr(policy, "attach", None)
    if oracle and callable(attach):
        attach(env.unwrapped)
    return observation, info, oracle


def policy_info(policy: Policy, info: dict[str, Any], oracle: bool) -> Mapping[str, Any]:
    """What ``policy`` may read of ``info``: all of it if it is an ``oracle`` this episode (as
    :func:`start_episode` read it), else its agent view (:func:`~nbv_gym.env.views.agent_view`)."""
    return info if oracle else agent_view(info, policy_name(policy))


def _row(
    step: int,
    goal: int,
    info: dict[str, Any],
    reward: float,
    start: float,
    policy: Policy,
    elapsed_s: float,
) -> dict:
    """One step's row; ``predicted_gain``/``realised_gain`` are those of the policy's gain layer
    (the ``nbv-*`` policies' ``gain_layer``), NaN for other policies and after a reset;
    ``elapsed_s`` the robot's clock (s)."""
    layer = getattr(policy, "gain_layer", None)
    return {
        "step": step,
        "goal": goal,
        "discovered": float(info["discovered"]),
        "q": float(info["q"]),
        "q_paper": float(info["q_paper"]),
        "q_observed": float(info["q_observed"]),
        "reward": float(reward),
        "path_length_m": float(info["path_length_m"]),
        "elapsed_s": float(elapsed_s),
        "predicted_gain": float(info.get("predicted_gain", {}).get(layer, np.nan)),
        "realised_gain": float(info.get("realised_gain", {}).get(layer, np.nan)),
        "time_s": time.perf_counter() - start,
    }


def write_run_folder(out: Path, env: ExploreEnv, result: EpisodeResult, meta: dict) -> dict:
    """Write the step table, the summary, the final map and statistics to ``out``; the summary
    (what ``summary.json`` holds)."""
    figures = {"final": result.final, "n_steps": len(result.steps) - 1,
               "end_reason": result.end_reason, "wall_time_s": result.wall_time_s}  # fmt: skip
    table = ("steps.csv", STEP_COLUMNS, result.steps)
    summary = write_run_files(out, table, meta, env.config, figures, env.sim.summary)
    env.sim.save(out)
    _write_exports(out, env)
    return summary


def write_run_files(
    out: Path,
    table: tuple[str, Sequence[str], Sequence[Mapping[str, Any]]],
    meta: Mapping[str, Any],
    config: Any,
    figures: Mapping[str, Any],
    quality: Any,
) -> dict:
    """Write a run folder's table and ``summary.json`` into ``out`` (made if missing): ``table``
    is (file name, columns, a row per scan or step) written as CSV; the summary holds ``meta``
    (the run's settings), the ``config`` (a dataclass), ``figures``, the map ``quality`` (a
    dataclass) and the library versions, in that order. The summary."""
    out.mkdir(parents=True, exist_ok=True)
    name, columns, rows = table
    with open(out / name, "w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(columns))
        writer.writeheader()
        writer.writerows(rows)
    summary = {**meta, "config": to_dict(config), **figures, "quality": asdict(quality),
               "versions": versions()}  # fmt: skip
    (out / "summary.json").write_text(dumps_json(summary) + "\n", encoding="utf-8")
    return summary


def _write_exports(out: Path, env: ExploreEnv) -> None:
    """The final map as PLY (occupied voxel centres, probability as a scalar) and the scan poses
    (``trajectory.csv``), for other tools and ``nbv-gym view``."""
    from nbv_gym.core.trajectory import TRAJECTORY_NAME, write_trajectory
    from nbv_gym.mapping.export import export_map

    export_map(env.sim.occupancy, out / "map.ply")
    write_trajectory(out / TRAJECTORY_NAME, env.sim.trajectory)
