"""Train an RL exploration agent with stable-baselines3 (``nbv-gym train``).

The run folder ``out`` receives ``config.toml`` (the resolved :class:`TrainConfig`),
``system_info.txt``, ``logs/run-<k>/`` (``progress.csv`` and TensorBoard events, one folder per
start or resume), ``checkpoints/model_<steps>_steps.zip``, ``best_model.zip`` (best mean
evaluation return), ``eval/evaluations.npz``, ``final_model.zip``, ``episodes.csv`` (every
training episode) and ``learning_curve.png`` (:mod:`nbv_gym.rl.curve`).

With ``scheduler`` set, the environments run on a Dask cluster (:mod:`nbv_gym.rl.daskvec`) and
the learner here; a cluster that loses every worker stops training with a
:class:`~nbv_gym.core.errors.ClusterError` after the model is saved as a checkpoint.
"""

from __future__ import annotations

import os
import platform
import time
import warnings
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

if TYPE_CHECKING:
    from collections.abc import Callable

    import gymnasium
    from stable_baselines3.common.vec_env import VecEnv

from nbv_gym.core.config import to_dict
from nbv_gym.core.errors import ClusterError, ConfigError, NbvGymError
from nbv_gym.core.progress import say
from nbv_gym.rl.config import TrainConfig, algorithm_class, require_rl
from nbv_gym.rl.curve import CURVE_PNG, EPISODES_CSV, plot_learning_curve
from nbv_gym.rl.learner import prepare_learner

FINAL_MODEL = "final_model.zip"
BEST_MODEL = "best_model.zip"
#: What a training writes into its run folder (files and folders): an earlier training's.
RUN_FILES = ("config.toml", "system_info.txt", "logs", "checkpoints", "eval", BEST_MODEL,
             FINAL_MODEL, EPISODES_CSV, CURVE_PNG)  # fmt: skip


def earlier_training(out: Path) -> list[str]:
    """The names in ``out`` that show a training learned there: a model, the episode log or the
    learning curve, a file in ``checkpoints/`` or ``eval/``, a logged update (a row in a
    ``logs/*/progress.csv``). What a training writes before it learns (``config.toml``,
    ``system_info.txt``, empty logs) shows none: a folder whose start-up failed is no earlier
    training, and a training may start there again."""
    found = [name for name in (FINAL_MODEL, BEST_MODEL, EPISODES_CSV, CURVE_PNG)
             if (out / name).exists()]  # fmt: skip
    found += [name for name in ("checkpoints", "eval")
              if any(p.is_file() for p in (out / name).rglob("*"))]  # fmt: skip
    if any(p.stat().st_size for p in (out / "logs").glob("*/progress.csv")):
        found.append("logs")
    return found


class TrainingInterrupted(NbvGymError):
    """Training was stopped with Ctrl-C; the model so far is saved as a checkpoint, which the
    message names with the ``--resume`` that continues from it."""

    exit_code = 130


def train(
    config: TrainConfig,
    out: str | Path,
    resume: str | Path | None = None,
    progress_bar: bool = True,
    verbose: int = 0,
    time_limit_s: float | None = None,
    callbacks: tuple = (),
):
    """Train per ``config`` into the run folder ``out`` and return the model.

    With ``resume`` (a checkpoint or model zip) training continues from that model's step count
    until ``config.total_timesteps`` in all. With ``time_limit_s`` training stops after that
    much wall time, then saves as if finished. ``callbacks``: more SB3 callbacks.
    """
    require_rl()
    check_device(config.device)
    check_resume(config, resume)  # before anything is written
    threads = prepare_learner(config.torch_threads, local_envs(config))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    where = (
        f"on {config.scheduler}"
        if config.scheduler
        else "in worker processes"
        if config.n_envs > 1 and config.robots == 1
        else "here"
    )
    say(f"starting {config.n_envs} training environment(s) {where} (imports, the first worlds; "
        "on a new install the kernels compile first)…")  # fmt: skip
    envs = make_vec_env(config)
    if config.eval_every_steps:
        say(f"starting the evaluation environment ({len(config.eval_worlds)} worlds)…")
    eval_env = make_eval_env(config) if config.eval_every_steps else None
    try:
        say(f"{'loading' if resume else 'creating'} the {config.algorithm} model "
            f"({time.perf_counter() - started:.0f} s so far)…")  # fmt: skip
        model = _load_or_create(config, envs, resume, verbose)
        write_run_info(config, out)  # once the run has started: a start-up failure leaves none
        model.set_logger(_logger(out, verbose))
        say(f"training: the first update comes after "
            f"{config.learning.n_steps * config.n_envs * config.robots:,} steps (n_steps · "
            f"n_envs{' · robots' if config.robots > 1 else ''})")  # fmt: skip
        remaining = config.total_timesteps - model.num_timesteps
        if remaining <= 0:
            raise ConfigError(
                f"total_timesteps: the model has already trained {model.num_timesteps} steps "
                f"≥ {config.total_timesteps}; raise total_timesteps (--timesteps) to go on."
            )
        with warnings.catch_warnings():  # the evaluation env runs in-process on purpose
            warnings.filterwarnings("ignore", "Training and eval env are not of the same type")
            _learn(
                model,
                out,
                remaining,
                callback=[*_callbacks(config, out, eval_env, verbose, time_limit_s, threads),
                          *callbacks],
                reset_num_timesteps=resume is None,
                progress_bar=progress_bar,
            )  # fmt: skip
        model.save(out / FINAL_MODEL)
        plot_learning_curve(out)
    finally:
        envs.close()
        if eval_env is not None:
            eval_env.close()
    return model


def _learn(model, out: Path, steps: int, **kwargs) -> None:
    """``model.learn(steps, **kwargs)``, SIGTERM raising ``KeyboardInterrupt`` as Ctrl-C does (so
    a batch system's stop saves a checkpoint too); when the cluster has lost every worker, the
    model is saved as a checkpoint before the :class:`ClusterError` goes on, naming it."""
    from nbv_gym.core.outputs import terminate_as_interrupt

    try:
        with terminate_as_interrupt():
            model.learn(steps, **kwargs)
    except ClusterError as error:
        _close_logs(kwargs.get("callback", ()))
        path = _save_checkpoint(model, out)
        raise ClusterError(f"{error} The model so far is saved as {path}.") from None
    except KeyboardInterrupt:
        _close_logs(kwargs.get("callback", ()))
        path = _save_checkpoint(model, out)
        raise TrainingInterrupted(
            f"interrupted (Ctrl-C) after {model.num_timesteps:,} steps; the model so far is saved "
            f"as {path}. Continue with --resume {path} (same --config and --out)."
        ) from None


def _close_logs(callbacks) -> None:
    """Flush and close the episode log among ``callbacks``: SB3 ends callbacks only when
    training ends normally, and an open log's buffer would otherwise land in the file later,
    after the rows of a resumed training."""
    from nbv_gym.rl.callbacks import EpisodeLog

    for callback in callbacks:
        if isinstance(callback, EpisodeLog):
            callback.close()


def _save_checkpoint(model, out: Path) -> Path:
    """Save ``model`` as ``out/checkpoints/model_<steps>_steps.zip`` and return that path."""
    path = out / "checkpoints" / f"model_{model.num_timesteps}_steps.zip"
    path.parent.mkdir(exist_ok=True)
    model.save(path)
    return path


def local_envs(config: TrainConfig) -> int:
    """How many environment processes run on this machine: ``n_envs``, but none when a remote
    Dask cluster runs them."""
    if config.robots > 1:  # the team envs run in this process
        return 1
    return config.n_envs if config.scheduler in ("", "local") else 0


def check_device(device: str) -> None:
    """Raise :class:`ConfigError` for ``device = "cuda"`` when torch sees no CUDA device (SB3
    would train on the CPU without a word)."""
    import torch

    if device == "cuda" and not torch.cuda.is_available():
        raise ConfigError(
            f"device: cuda requested, but torch {torch.__version__} sees no CUDA device; "
            "install a CUDA build of torch, or train with --device cpu (or auto)."
        )


def make_vec_env(config: TrainConfig, seed_offset: int = 0):
    """The training ``VecEnv``: ``n_envs`` world-cycling environments, environment ``i`` cycling
    over ``train_worlds[i::n_envs]`` (all of them, shifted by ``i``, when there are fewer worlds
    than environments), in worker processes without torch when ``n_envs`` > 1, or on the Dask
    cluster of ``config.scheduler`` (``local``: one worker process per environment, at most
    one per core)."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    if config.robots > 1:
        return make_team_vec_env(config, seed_offset)
    from nbv_gym.core.processes import worker_environment
    from nbv_gym.rl.daskvec import DaskVecEnv
    from nbv_gym.rl.vecenv import LeanSubprocVecEnv

    factories: list[Callable[[], gymnasium.Env]] = [
        partial(_env_factory, config, _share(config.train_worlds, i, config.n_envs))
        for i in range(config.n_envs)
    ]
    masks = ("action_masks",) if config.algorithm == "MaskablePPO" else ()
    envs: VecEnv
    if config.scheduler:
        workers = min(config.n_envs, os.cpu_count() or 1)
        envs = DaskVecEnv(factories, config.scheduler, local_workers=workers, prefetch=masks)
    elif config.n_envs == 1:
        envs = DummyVecEnv(factories)
    else:
        with worker_environment():  # workers share few cores: no nested thread pools
            envs = LeanSubprocVecEnv(factories, start_method="forkserver", prefetch=masks)
    envs.seed(config.seed + seed_offset)
    return envs


def make_team_vec_env(config: TrainConfig, seed_offset: int = 0):
    """The training ``VecEnv`` of a team config (``robots`` ≥ 2): ``n_envs`` team envs of
    ``robots`` in this process, a slot per robot (:mod:`nbv_gym.rl.teamvec`)."""
    from nbv_gym.rl.teamvec import TeamVecEnv, make_team_envs

    kwargs = {key: config.env_kwargs()[key]
              for key in ("noise", "lidar", "time_budget_s", "speed_mps", "scan_time_s")}  # fmt: skip
    teams = make_team_envs(config.train_worlds, config.n_envs, config.robots, **kwargs)
    envs = TeamVecEnv(teams, config.reward_scale)
    envs.seed(config.seed + seed_offset)
    return envs


def make_eval_env(config: TrainConfig):
    """The evaluation ``VecEnv``: one environment in this process cycling over ``eval_worlds``
    (``train_worlds`` when there are none), wrapped in SB3's ``Monitor``, which SB3's evaluation
    looks for."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    worlds = config.eval_worlds or config.train_worlds
    envs = DummyVecEnv([partial(_env_factory, config, worlds, monitor="sb3")])
    envs.seed(config.seed + 10_000)
    return envs


def write_run_info(config: TrainConfig, out: Path) -> None:
    """Write ``config.toml`` and ``system_info.txt`` (platform and library versions)."""
    from nbv_gym.core.provenance import versions

    (out / "config.toml").write_text(dumps_toml(config.file_dict()), encoding="utf-8")
    found = versions()
    for package in ("torch", "stable-baselines3", "sb3-contrib", "tensorboard"):
        found.update(_version(package))
    lines = [f"platform: {platform.platform()}", *(f"{k}: {v}" for k, v in found.items())]
    (out / "system_info.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")


def dumps_toml(data: dict[str, Any]) -> str:
    """``data`` (scalars, lists of scalars and one level of tables) as TOML text; None values
    (TOML has no null: an unset table such as ``imitation``) are left out."""
    data = {k: v for k, v in data.items() if v is not None}
    scalars = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    tables = [
        f"\n[{k}]\n" + "\n".join(f"{kk} = {_toml_value(vv)}" for kk, vv in v.items())
        for k, v in data.items()
        if isinstance(v, dict)
    ]
    return "\n".join(scalars) + "\n" + "\n".join(tables) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def _env_factory(config: TrainConfig, worlds: tuple[str, ...], monitor: str = "lean"):
    from nbv_gym.rl.envs import make_world_cycle

    return make_world_cycle(
        monitor=monitor,
        worlds=worlds,
        reward_scale=config.reward_scale,
        invalid_action="raise" if config.algorithm == "MaskablePPO" else "snap",
        world_pool_size=config.world_pool_size,
        episodes_per_world=config.episodes_per_world,
        **config.env_kwargs(),
    )


def _share(worlds: tuple[str, ...], i: int, n: int) -> tuple[str, ...]:
    if len(worlds) >= n:
        return worlds[i::n]
    shift = i % len(worlds)
    return worlds[shift:] + worlds[:shift]


def policy_setup(config: TrainConfig) -> tuple[type | str, dict[str, Any]]:
    """The policy class and ``policy_kwargs`` of ``config.network``."""
    from nbv_gym.rl.extractor import GoalMapPolicy, MapExtractor, MaskableGoalMapPolicy

    goal_map = config.network == "goal-map"
    kwargs: dict[str, Any] = {
        "features_extractor_class": MapExtractor,
        "features_extractor_kwargs": {
            "features_dim": config.features_dim,
            "goal_scores": goal_map,
        },
    }
    if not goal_map:
        return "MultiInputPolicy", {**kwargs, "net_arch": {"pi": [64], "vf": [64]}}
    policy = MaskableGoalMapPolicy if config.algorithm == "MaskablePPO" else GoalMapPolicy
    return policy, {**kwargs, "net_arch": {"pi": [], "vf": [64]}}


def create_model(config: TrainConfig, envs, verbose: int = 0):
    """A new model of ``config`` (algorithm, network, learning settings, seed) on ``envs``."""
    policy, policy_kwargs = policy_setup(config)
    learning = to_dict(config.learning)
    if config.algorithm == "A2C":
        for key in ("batch_size", "n_epochs", "clip_range"):
            learning.pop(key)
    return algorithm_class(config.algorithm)(
        policy,
        envs,
        policy_kwargs=policy_kwargs,
        seed=config.seed,
        device=config.device,
        verbose=verbose,
        **learning,
    )


def _load_or_create(config: TrainConfig, envs, resume: str | Path | None, verbose: int):
    if resume is None:
        model = create_model(config, envs, verbose)
        if config.init_model:
            _start_from(model, config)
        return model
    cls = algorithm_class(config.algorithm)
    try:
        return cls.load(resume, env=envs, device=config.device, verbose=verbose)
    except (ValueError, KeyError) as error:
        raise ConfigError(
            f"Cannot resume {config.algorithm} from {str(resume)!r}: {error}. Resume with the "
            "config (algorithm, n_envs, observation_layers) the checkpoint was trained with."
        ) from None


#: What a resumed training must share with the training that saved its model: the algorithm,
#: the network and what the environment gives and rewards (another task, budget, lidar or clock
#: starts a new training from the model's weights: ``init_model``).
RESUME_KEYS = ("algorithm", "network", "features_dim", "observation_layers", "reward_scale",
               "task", "noise", "lidar", "budget_scans", "max_steps", "time_budget_s",
               "speed_mps", "scan_time_s", "robots")  # fmt: skip


def check_resume(config: TrainConfig, resume: str | Path | None) -> None:
    """:class:`ConfigError` (or the model file's own error) unless ``resume`` (None: nothing to
    check) is a model zip saved by ``config.algorithm`` and, when the training that saved it
    left its ``config.toml`` (beside the model or above its ``checkpoints/``), that training's
    :data:`RESUME_KEYS` equal ``config``'s. Reads only the zip's JSON and the TOML: called
    before anything is written."""
    if resume is None:
        return
    from nbv_gym.policies import SB3_PREFIX, training_config_path
    from nbv_gym.rl.config import load_train_config
    from nbv_gym.rl.modelfile import check_model_file, describe_model

    check_model_file(Path(resume))
    saved = describe_model(Path(resume)).algorithm  # read before SB3 unpickles the file
    if saved != config.algorithm:
        raise ConfigError(
            f"Cannot resume {config.algorithm} from {str(resume)!r}: {saved} saved it. Set "
            f'algorithm = "{saved}" in the config, or start a new run.'
        )
    path = training_config_path(f"{SB3_PREFIX}{resume}")
    if path is None or not path.is_file():
        return
    then, now = load_train_config(path).file_dict(), config.file_dict()
    for key in RESUME_KEYS:
        if config.task.shapes(key) and then.get(key) != now.get(key):
            raise ConfigError(
                f"--resume {resume}: the training that saved it ({path}) has {key} = "
                f"{then.get(key)!r}, this config {now.get(key)!r}; a training resumes under its own "
                f"settings. Resume with its config, or start a new training from its weights "
                f'(init_model = "{resume}").'
            )


def _start_from(model, config: TrainConfig) -> None:
    """Copy the network weights of ``config.init_model`` into the new ``model`` (its buffers —
    the input scaling of this run's observation bounds — stay); :class:`ConfigError` when the
    networks differ."""
    from nbv_gym.policies import MODELS, model_path
    from nbv_gym.rl.agent import load_model

    name = config.init_model
    path = model_path(name) if name in MODELS else Path(name)
    source = load_model(path, device=config.device)
    if type(source) is not type(model):
        raise ConfigError(
            f"init_model: {name!r} is a {type(source).__name__}, this run a {config.algorithm}"
        )
    buffers = {key for key, _ in model.policy.named_buffers(remove_duplicate=False)}
    weights = {k: v for k, v in source.policy.state_dict().items() if k not in buffers}
    try:
        keys = model.policy.load_state_dict(weights, strict=False)
        differ = [*keys.unexpected_keys, *(set(keys.missing_keys) - buffers)]
    except RuntimeError as error:
        differ = [str(error).splitlines()[0]]
    if differ:
        raise ConfigError(
            f"init_model: {name!r} has another network than this run's (network, "
            f"features_dim, observation_layers): {', '.join(map(str, differ[:3]))}"
        )


def _logger(out: Path, verbose: int):
    from stable_baselines3.common.logger import configure

    logs = out / "logs"
    k = 1 + sum(1 for p in logs.glob("run-*") if p.is_dir()) if logs.exists() else 1
    formats = ["csv", "tensorboard", *(["stdout"] if verbose else [])]
    try:
        import tensorboard  # noqa: F401
    except ImportError:
        formats.remove("tensorboard")
    return configure(str(logs / f"run-{k}"), formats)


def _callbacks(
    config: TrainConfig,
    out: Path,
    eval_env,
    verbose: int,
    time_limit_s: float | None = None,
    threads: tuple[int, int] = (1, 1),
) -> list:
    from stable_baselines3.common.callbacks import CheckpointCallback

    from nbv_gym.rl.callbacks import EpisodeLog, TimeLimit, TorchThreads

    callbacks = [EpisodeLog(out / EPISODES_CSV), TorchThreads(*threads)]
    if time_limit_s is not None:
        callbacks.append(TimeLimit(time_limit_s))
    if config.checkpoint_every_steps:
        callbacks.append(
            CheckpointCallback(
                _calls(config.checkpoint_every_steps, config.n_envs * config.robots),
                str(out / "checkpoints"),
                name_prefix="model",
            )
        )
    if config.eval_every_steps:
        callbacks.append(_eval_callback(config, out, eval_env, verbose))
    return callbacks


class _EvalKwargs(TypedDict):
    """The settings the evaluation callbacks (SB3's and sb3-contrib's) share."""

    n_eval_episodes: int
    eval_freq: int
    best_model_save_path: str
    log_path: str
    deterministic: bool
    verbose: int


def _eval_callback(config: TrainConfig, out: Path, eval_env, verbose: int):
    kwargs: _EvalKwargs = {
        "n_eval_episodes": config.n_eval_episodes,
        "eval_freq": _calls(config.eval_every_steps, config.n_envs),
        "best_model_save_path": str(out),
        "log_path": str(out / "eval"),
        "deterministic": True,
        "verbose": verbose,
    }
    if config.algorithm == "MaskablePPO":
        from sb3_contrib.common.maskable.callbacks import MaskableEvalCallback

        return MaskableEvalCallback(eval_env, use_masking=True, **kwargs)
    from stable_baselines3.common.callbacks import EvalCallback

    return EvalCallback(eval_env, **kwargs)


def _calls(every_steps: int, n_envs: int) -> int:
    """Callback frequency in ``VecEnv.step`` calls for one event every ``every_steps`` steps."""
    return max(every_steps // n_envs, 1)


def _version(package: str) -> dict[str, str]:
    from importlib import metadata

    try:
        return {package: metadata.version(package)}
    except metadata.PackageNotFoundError:
        return {package: "not installed"}
