"""A trained agent packaged for a model hub (``nbv-gym package-model``): a folder in the
conventions of the stable-baselines3 ecosystem (the Hugging Face Hub's ``huggingface_sb3`` and
rl-zoo3 write the same files), evaluated with action masks, which the hub helpers' evaluation
does not apply.

The folder holds the model zip (``<algo>-<env>.zip`` as rl-zoo3 names it, e.g.
``ppo_mask-nbv_gym-ExploreBudget-v0.zip``), its training config (``config.toml``),
``results.json`` (the evaluation: ``mean_reward``, ``std_reward``, ``n_eval_episodes``, … and
every episode), a model card ``README.md`` whose YAML front matter is the hub's metadata block
(``library_name: stable-baselines3``, tags with the env id, ``model-index`` with the metrics),
``replay.gif`` (the first evaluation episode), ``learning_curve.png`` when the run has one, and
the files rl-zoo3's hub tooling reads (``config.yml``, ``env_kwargs.yml``, ``args.yml``,
``train_eval_metrics.zip``), so ``rl_zoo3.load_from_hub`` and ``rl_zoo3.enjoy`` load it too.
``sb3:FOLDER`` loads it back as a policy.

The evaluation runs the model deterministically on the held-out worlds of its config
(``eval_worlds``), ``episodes`` episodes each, under the task, noise level and budget it was
trained for; MaskablePPO acts among the valid goals only. Intervals are 95 % bootstrap
intervals of the mean over the episodes: resampled within each world when every world has two
episodes or more, across the worlds otherwise.
"""

from __future__ import annotations

import datetime
import json
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.core.config import to_dict
from nbv_gym.core.errors import missing_file
from nbv_gym.core.outputs import writable_folder
from nbv_gym.core.protocol import TASK_IDS
from nbv_gym.policies import PolicyError
from nbv_gym.policies.registry import MODELS, model_path
from nbv_gym.rl.config import TrainConfig, load_train_config
from nbv_gym.rl.curve import CURVE_PNG

MODEL_CARD = "README.md"
RESULTS = "results.json"
REPLAY = "replay.gif"
CONFIG = "config.toml"
#: The files rl-zoo3's hub tooling (``rl_zoo3.load_from_hub``) reads beside the model zip: the
#: hyper-parameters, the environment's keyword arguments, the run's arguments and its metrics.
ZOO_CONFIG, ZOO_ENV_KWARGS, ZOO_ARGS, ZOO_METRICS = (
    "config.yml", "env_kwargs.yml", "args.yml", "train_eval_metrics.zip"
)  # fmt: skip
#: nbv-gym's algorithm names → rl-zoo3's (``--algo``), which name the model zip.
ZOO_ALGOS = {"MaskablePPO": "ppo_mask", "PPO": "ppo", "A2C": "a2c"}
#: The model file a run folder is packaged from by default, then the next one.
RUN_MODELS = ("final_model.zip", "best_model.zip")
#: The model card's tags after the env id: the SB3 hub's, then the project's.
TAGS = ("deep-reinforcement-learning", "reinforcement-learning", "stable-baselines3", "nbv-gym",
        "next-best-view", "lidar-exploration")  # fmt: skip
#: Per-episode figures of the evaluation: name → what it is (units).
FIGURES = {
    "return": "return (reward_scale · Σ ΔQ, as in training)",
    "q": "Q after the episode, in [0, 1]",
    "discovered": "discovered fraction after the episode",
    "path_length_m": "path length, m",
}


@dataclass(frozen=True)
class Source:
    """A model zip, its training config and its learning curve (None when there is none)."""

    model: Path
    config: Path
    curve: Path | None


def find_source(path: str | Path, model: str | None = None) -> Source:
    """The model to package at ``path``: a run folder of ``nbv-gym train`` (``config.toml`` and
    ``model``, by default the first of :data:`RUN_MODELS` there), a model zip with its config
    beside it (``NAME.zip`` and ``NAME.toml``, a ``NAME.png`` curve if any, as the shipped
    models lie), or a shipped model's name (``ppo-budget``)."""
    path = model_path(str(path)) if str(path) in MODELS else Path(path)
    if path.is_dir():
        names = [model] if model else [n for n in RUN_MODELS if (path / n).exists()]
        if not names or not (path / names[0]).is_file():
            wanted = model or " or ".join(RUN_MODELS)
            raise PolicyError(
                f"{str(path)!r} holds no model {wanted}: expected a run folder of nbv-gym "
                "train, or a model zip with its .toml beside it."
            )
        curve = path / CURVE_PNG
        return Source(
            path / names[0], _config_file(path / CONFIG), curve if curve.exists() else None
        )
    if path.suffix != ".zip" or not path.is_file():
        raise PolicyError(
            f"No model at {str(path)!r} (it {missing_file(path)}): expected a run folder of "
            "nbv-gym train, a model .zip with its .toml beside it, or a shipped model's name "
            f"({', '.join(MODELS)})."
        )
    curve = path.with_suffix(".png")
    return Source(path, _config_file(path.with_suffix(".toml")), curve if curve.exists() else None)


def _config_file(path: Path) -> Path:
    if not path.is_file():
        raise PolicyError(
            f"The training config {str(path)!r} is missing: packaging needs the config the "
            "model was trained with (worlds, task, budget)."
        )
    return path


def package(
    source: Source,
    out: str | Path,
    episodes: int = 3,
    seed: int = 0,
    progress: Callable[[str], None] = lambda _: None,
) -> dict[str, Any]:
    """Write the hub folder of ``source`` into ``out`` (module docstring) with an evaluation of
    ``episodes`` episodes per held-out world from seeds ``seed``, ``seed + 1``, …; returns the
    evaluation (``results.json``'s content)."""
    from nbv_gym.rl.agent import SB3Policy

    out = writable_folder(out)
    config = load_train_config(source.config)
    policy = SB3Policy(source.model)
    env_id = TASK_IDS[config.task.name]
    model_name = zoo_model_name(config.algorithm, env_id)
    for stale in out.glob("*.zip"):  # one model per folder: sb3:FOLDER loads it
        stale.unlink()
    shutil.copyfile(source.model, out / model_name)
    shutil.copyfile(source.config, out / CONFIG)
    if source.curve is not None:
        shutil.copyfile(source.curve, out / CURVE_PNG)
    rows = evaluate(policy, config, episodes, seed, out / REPLAY, progress)
    results = summarise(rows, config, policy.masked, seed)
    (out / RESULTS).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    write_zoo_files(config, env_id, out)
    card = model_card(config, env_id, model_name, results, source.curve is not None)
    (out / MODEL_CARD).write_text(card, encoding="utf-8")
    return results


def zoo_model_name(algorithm: str, env_id: str) -> str:
    """The model zip's name as rl-zoo3's hub tooling looks it up: ``<algo>-<env>.zip`` with
    rl-zoo3's algorithm key and the env id's ``/`` as ``-`` (``ppo_mask-nbv_gym-ExploreBudget-v0.zip``)."""
    return f"{ZOO_ALGOS[algorithm]}-{env_id.replace('/', '-')}.zip"


def zoo_env_kwargs(config: TrainConfig) -> dict[str, Any]:
    """The environment's keyword arguments for rl-zoo3 (``env_kwargs.yml``): the first held-out
    world and the environment of training (:meth:`TrainConfig.env_kwargs`: task, noise, lidar,
    layers, effort model and budget); ``invalid_action: snap``, since rl-zoo3's ``enjoy`` passes
    no action masks. The task is the env id's, so it is left out."""
    kwargs = {key: value for key, value in config.env_kwargs().items() if key != "task"}
    return {
        "world": (config.eval_worlds or config.train_worlds)[0],
        **kwargs,
        "observation_layers": list(config.task.observation_layers),
        "invalid_action": "snap",
    }


def write_zoo_files(config: TrainConfig, env_id: str, out: Path) -> None:
    """The files rl-zoo3's hub tooling reads beside the model (:data:`ZOO_CONFIG`, …): its
    hyper-parameters as rl-zoo3 saves them (no ``VecNormalize``: nbv-gym scales the reward in
    the environment), the environment's keyword arguments, the run's arguments, and the
    evaluation zipped as the run's metrics."""
    import zipfile

    import yaml

    from nbv_gym.rl.train import policy_setup

    policy, _ = policy_setup(config)
    learning = to_dict(config.learning)
    if config.algorithm == "A2C":  # PPO's keys only, as nbv-gym train drops them
        for key in ("batch_size", "n_epochs", "clip_range"):
            learning.pop(key)
    hyperparameters = {
        "policy": policy if isinstance(policy, str) else f"{policy.__module__}.{policy.__name__}",
        "n_timesteps": config.total_timesteps,
        "n_envs": config.n_envs,
        "normalize": False,
        **learning,
    }
    env_kwargs = zoo_env_kwargs(config)
    arguments = {"algo": ZOO_ALGOS[config.algorithm], "env": env_id, "gym_packages": ["nbv_gym"],
                 "env_kwargs": env_kwargs, "seed": config.seed,
                 "n_timesteps": config.total_timesteps}  # fmt: skip
    for name, content in ((ZOO_CONFIG, hyperparameters), (ZOO_ENV_KWARGS, env_kwargs),
                          (ZOO_ARGS, arguments)):  # fmt: skip
        (out / name).write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    with zipfile.ZipFile(out / ZOO_METRICS, "w") as metrics:
        metrics.write(out / RESULTS, RESULTS)


def evaluate(
    policy,
    config: TrainConfig,
    episodes: int,
    seed: int,
    replay: Path | None = None,
    progress: Callable[[str], None] = lambda _: None,
) -> list[dict[str, Any]]:
    """One row per episode (``world``, ``seed`` and :data:`FIGURES`) of ``policy`` on each of
    ``config.eval_worlds`` (``train_worlds`` when there are none) from seeds ``seed`` … ``seed +
    episodes - 1``; the first episode is drawn into the GIF ``replay``."""
    from nbv_gym.env.explore import ExploreEnv
    from nbv_gym.env.render import save_animation
    from nbv_gym.episode import run_episode
    from nbv_gym.policies import required_layers

    rows: list[dict[str, Any]] = []
    frames: list[Any] = []
    for world in config.eval_worlds or config.train_worlds:
        env = ExploreEnv(
            "rgb_array" if replay is not None and not rows else None,
            world=world,
            **{**config.env_kwargs(), "observation_layers": required_layers(policy)},
        )
        for k in range(episodes):
            record = replay is not None and not rows
            on_step = (lambda row, env: frames.append(env.render())) if record else None
            result = run_episode(env, policy, seed + k, on_step)
            final = result.final
            rows.append(
                {
                    "world": world,
                    "seed": seed + k,
                    "return": config.reward_scale * sum(row["reward"] for row in result.steps),
                    **{key: final[key] for key in ("q", "discovered", "path_length_m")},
                }
            )
            progress(
                f"{world} seed {seed + k}: Q {final['q']:.4f}, return {rows[-1]['return']:.3f}"
            )
        env.close()
    if frames:
        save_animation(frames, replay, ExploreEnv.metadata["render_fps"])
    return rows


def summarise(rows: list[dict], config: TrainConfig, masked: bool, seed: int) -> dict[str, Any]:
    """``results.json``: the hub's ``mean_reward``, ``std_reward``, ``is_deterministic``,
    ``n_eval_episodes`` and ``eval_datetime``, then the mean and 95 % bootstrap interval of each
    of :data:`FIGURES` over all episodes and per world (``low``/``high`` None for a single
    episode), how the interval was drawn (``interval``: episodes resampled within each world
    when every world has two or more, else across the worlds), and the episodes."""
    from nbv_gym.reporting.inference import stratified_interval

    rng = np.random.default_rng(seed)
    returns = np.array([row["return"] for row in rows])
    worlds = list(dict.fromkeys(row["world"] for row in rows))
    per_world = min(sum(row["world"] == w for row in rows) for w in worlds)
    # Resampling within each world needs two episodes of it; with one, every resample is the
    # sample itself and the interval a point, so the episodes are resampled across the worlds.
    within = per_world >= 2

    def intervals(selected: list[dict]) -> dict[str, dict[str, float | None]]:
        found: dict[str, dict[str, float | None]] = {}
        strata = [row["world"] if within else "all" for row in selected]
        for key in FIGURES:
            values = np.array([row[key] for row in selected])
            interval = stratified_interval(values, strata, np.mean, rng)
            bounded = len(selected) >= 2  # no interval of a single episode
            found[key] = {
                "mean": interval.mean,
                "low": interval.low if bounded else None,
                "high": interval.high if bounded else None,
            }
        return found

    return {
        "mean_reward": float(returns.mean()),
        "std_reward": float(returns.std()),
        "is_deterministic": True,
        "masked": masked,
        "n_eval_episodes": len(rows),
        "eval_datetime": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "task": config.task.name,
        "noise": config.task.noise,
        "budget_scans": config.task.budget_scans if config.task.name == "budget" else None,
        "worlds": worlds,
        "interval": (
            "95 % bootstrap interval of the mean, episodes resampled within each world"
            if within
            else "95 % bootstrap interval of the mean, episodes resampled across the worlds "
            "(fewer than 2 episodes of a world; none for a single episode)"
        ),
        "overall": intervals(rows),
        "per_world": {w: intervals([r for r in rows if r["world"] == w]) for w in worlds},
        "episodes": rows,
    }


def metadata(config: TrainConfig, env_id: str, results: dict[str, Any]) -> dict[str, Any]:
    """The model card's metadata block, as the SB3 hub helpers write it (``library_name``,
    ``tags`` with the env id, ``model-index`` whose dataset ``name`` and ``type`` are the env id,
    with ``mean_reward`` as "mean +/- std"), with the final Q and the discovered fraction and
    their intervals besides; the held-out worlds are the dataset's ``split``."""
    overall = results["overall"]
    metrics = [
        {
            "type": "mean_reward",
            "name": "mean_reward",
            "verified": False,
            "value": f"{results['mean_reward']:.2f} +/- {results['std_reward']:.2f}",
        }
    ]
    for key in ("q", "discovered"):
        m = overall[key]
        interval = "" if m["low"] is None else f", 95% CI {m['low']:.4f} to {m['high']:.4f}"
        metrics.append(
            {
                "type": key,
                "value": round(m["mean"], 4),
                "verified": False,
                "name": f"{FIGURES[key]} (mean{interval})",
            }
        )
    masking = "masked" if results["masked"] else "invalid goals snapped"
    split = f"held-out worlds {', '.join(results['worlds'])} ({masking})"
    return {
        "library_name": "stable-baselines3",
        "tags": [env_id, *TAGS],
        "model-index": [
            {
                "name": config.algorithm,
                "results": [
                    {
                        "task": {
                            "type": "reinforcement-learning",
                            "name": "reinforcement-learning",
                        },
                        "dataset": {"name": env_id, "type": env_id, "split": split},
                        "metrics": metrics,
                    }
                ],
            }
        ],
    }


def model_card(
    config: TrainConfig, env_id: str, model_name: str, results: dict[str, Any], curve: bool
) -> str:
    """The model card: the metadata block as YAML front matter, then the evaluation per world,
    how to run the agent and the training config."""
    import yaml

    front = yaml.safe_dump(metadata(config, env_id, results), sort_keys=False, allow_unicode=True)
    trained_on = ", ".join(config.train_worlds)
    about = (
        f"A next-best-view exploration agent trained with nbv-gym: {config.algorithm}, "
        f"{config.total_timesteps:,} steps, `{config.network}` network, on `{trained_on}`."
    )
    return "\n".join(
        [
            "---",
            front.rstrip(),
            "---",
            "",
            f"# {config.algorithm} agent for {env_id}",
            "",
            about,
            "",
            *_evaluation_section(results),
            *_usage_section(),
            "## Training",
            "",
            f"The model is `{model_name}`; its training config `{CONFIG}` trains it again "
            f"(`nbv-gym train --config {CONFIG}`).",
            "",
            *([f"![learning curve]({CURVE_PNG})", ""] if curve else []),
        ]
    )


def _evaluation_section(results: dict[str, Any]) -> list[str]:
    acting = (
        "with action masks (valid goals only)"
        if results["masked"]
        else "invalid goals snapped to the nearest valid one"
    )
    per_world = results["n_eval_episodes"] // max(len(results["worlds"]), 1)
    scans = results.get("budget_scans")
    budget = f"{scans} scans per episode" if scans else "the task's own budget per episode"
    return [
        "## Evaluation",
        "",
        f"Deterministic, {acting}, on the held-out worlds {', '.join(results['worlds'])}: task "
        f"`{results['task']}`, noise level {results['noise']}, {budget}, "
        f"{per_world} episode(s) per world ({results['n_eval_episodes']} in all), "
        f"{results['eval_datetime']}. Means with their {results['interval']}.",
        "",
        "| world | return | Q after the episode | discovered | path (m) |",
        "|---|---|---|---|---|",
        *(_table_row(world, m) for world, m in results["per_world"].items()),
        _table_row("**all**", results["overall"]),
        "",
        f"mean_reward {results['mean_reward']:.3f} +/- {results['std_reward']:.3f} (mean +/- "
        "std of the episode returns, as the hub reports it). Every episode is in "
        f"`{RESULTS}`.",
        "",
        f"![replay of the first evaluation episode]({REPLAY})",
        "",
    ]


def _usage_section() -> list[str]:
    return [
        "## Usage",
        "",
        "```bash",
        'pip install "nbv-gym[rl]"',
        "nbv-gym run --policy sb3:THIS_FOLDER --world pp3-trees",
        "```",
        "",
        "```python",
        "from nbv_gym.policies import load_policy",
        "",
        "# a model zip is a pickle: load only models you trust",
        'policy = load_policy("sb3:THIS_FOLDER")',
        "```",
        "",
    ]


def _table_row(label: str, figures: dict[str, dict[str, Any]]) -> str:
    cells = [
        f"{m['mean']:.4g}" + ("" if m["low"] is None else f" [{m['low']:.4g}, {m['high']:.4g}]")
        for m in figures.values()
    ]
    return f"| {label} | " + " | ".join(cells) + " |"
