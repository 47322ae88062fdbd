"""The training config of ``nbv-gym train`` (a TOML file such as the shipped ``ppo``,
``nbv_gym/configs/train/ppo.toml``).

Top-level keys are :class:`TrainConfig`'s fields and, flat beside them, the task's
(:class:`~nbv_gym.env.task.TaskConfig`: ``task``, ``noise``, ``lidar``, ``budget_scans``, …);
the learning hyper-parameters live in the ``[learning]`` table (:class:`LearningConfig`).
Unknown keys are rejected with their dotted path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from nbv_gym.core.config import check, from_dict, read_toml, to_dict
from nbv_gym.core.errors import ConfigError, MissingExtraError, UnknownNameError
from nbv_gym.env.task import TaskConfig
from nbv_gym.worlds.distribution import (
    MAX_POOL_SIZE,
    PREFIX,
    WIDE_POOL_SIZE,
    WorldDistribution,
    heldout_names,
    is_distribution,
)
from nbv_gym.worlds.spec import load_spec

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

#: Algorithms ``nbv-gym train`` supports. MaskablePPO reads the action mask; PPO and A2C do not,
#: so their environments snap an invalid goal to the nearest valid one (``invalid_action="snap"``,
#: :mod:`nbv_gym.env.actions`).
ALGORITHMS = ("MaskablePPO", "PPO", "A2C")
#: SB3 algorithm class names → ``module:Class`` (SB3's classes saving lean model files).
ALGORITHM_CLASSES = {name: f"nbv_gym.rl.algorithms:{name}" for name in ALGORITHMS}


def require_rl() -> None:
    """Raise :class:`MissingExtraError` unless torch, stable-baselines3 and sb3-contrib import."""
    for module, package in (
        ("torch", "torch"),
        ("stable_baselines3", "stable-baselines3"),
        ("sb3_contrib", "sb3-contrib"),
    ):
        try:
            __import__(module)
        except ImportError:
            raise MissingExtraError(package, "rl") from None


def algorithm_class(name: str) -> type[BaseAlgorithm]:
    """The SB3 class of an algorithm name in :data:`ALGORITHM_CLASSES`."""
    import importlib

    module, _, cls = ALGORITHM_CLASSES[name].partition(":")
    return getattr(importlib.import_module(module), cls)


#: Training draws worlds from ``random:wide``, whose recipe covers and exceeds the test split's
#: (its seeds and recipe are disjoint from every suite's worlds).
TRAIN_WORLDS = ("random:wide",)
#: Evaluation (during training, and of a packaged model) on held-out worlds of the same
#: distribution — never on worlds a suite scores.
EVAL_WORLDS = heldout_names("wide", 8)


@dataclass(frozen=True)
class LearningConfig:
    """Hyper-parameters of the on-policy learners (SB3's names and meanings).

    ``n_steps`` is per environment: one update sees ``n_steps · n_envs`` steps. ``batch_size``,
    ``n_epochs`` and ``clip_range`` are PPO's only. The defaults are lean: 4 epochs of batches
    of 256 cost about 3 times less per environment step than 10 epochs of 64 (same network),
    and the gradient steps per environment step (``n_epochs / batch_size``) do not depend on
    ``n_envs``.
    """

    n_steps: int = 128
    batch_size: int = 256
    n_epochs: int = 4
    learning_rate: float = 1e-3
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    vf_coef: float = 0.5
    max_grad_norm: float = 0.5

    def __post_init__(self) -> None:
        check(self.n_steps >= 2, "n_steps", f"must be ≥ 2, got {self.n_steps}")
        check(self.batch_size >= 2, "batch_size", f"must be ≥ 2, got {self.batch_size}")
        check(self.n_epochs >= 1, "n_epochs", f"must be ≥ 1, got {self.n_epochs}")
        check(
            0 < self.learning_rate < math.inf,
            "learning_rate",
            f"must be a finite number > 0, got {self.learning_rate}",
        )
        check(0 < self.gamma <= 1, "gamma", f"must be in (0, 1], got {self.gamma}")
        check(0 <= self.gae_lambda <= 1, "gae_lambda", f"must be in [0, 1], got {self.gae_lambda}")
        check(self.clip_range > 0, "clip_range", f"must be > 0, got {self.clip_range}")
        for key in ("clip_range", "ent_coef", "vf_coef", "max_grad_norm"):
            value = getattr(self, key)
            check(math.isfinite(value), key, f"must be a finite number, got {value}")
        check(self.vf_coef >= 0, "vf_coef", f"must be ≥ 0, got {self.vf_coef}")
        check(self.max_grad_norm > 0, "max_grad_norm", f"must be > 0, got {self.max_grad_norm}")


@dataclass(frozen=True)
class ImitationConfig:
    """The imitation stages of a training recipe (the ``[imitation]`` table): DAgger label
    collection and imitation of a privileged teacher, before the RL training of the rest of the
    config starts from the imitated weights (:mod:`nbv_gym.rl.recipe`).

    - ``teacher``: a privileged policy whose ``values(observation, info)`` give each candidate
      goal's value (``oracle-time``, or ``oracle-time@β``).
    - ``iterations``: DAgger iterations; iteration ``i`` labels ``episodes_per_iteration``
      episodes in which the teacher acts at each step with probability
      ``teacher_share_decay ** i`` (1 in iteration 0), the learner of iteration ``i − 1``
      otherwise, then imitates on the labels of iterations 0…i.
    - ``temperature``: the teacher's target distribution over its candidates is
      ``softmax((value − best) / (temperature · max |value|))``: a candidate worth half the best
      gets e^−5 of its weight at 0.1.
    - ``epochs``, ``batch_size`` (states), ``learning_rate``: the imitation of each iteration
      (Adam, gradients clipped at ``learning.max_grad_norm``).
    - ``value_coef``: weight of the critic's regression on the episodes' discounted returns
      (``learning.gamma``, ``reward_scale``), so that the RL stage starts with a fitted critic
      (0: the critic is left untrained).
    - ``validation_share``: the share of each iteration's episodes held out for validation.
    """

    teacher: str = "oracle-time"
    iterations: int = 4
    episodes_per_iteration: int = 100
    teacher_share_decay: float = 0.5
    temperature: float = 0.1
    epochs: int = 8
    batch_size: int = 64
    learning_rate: float = 1e-3
    value_coef: float = 0.5
    validation_share: float = 0.1

    def __post_init__(self) -> None:
        check(self.iterations >= 1, "iterations", f"must be ≥ 1, got {self.iterations}")
        check(
            0 <= self.validation_share < 1,
            "validation_share",
            f"must be in [0, 1), got {self.validation_share}",
        )
        check(
            self.episodes_per_iteration >= 1,
            "episodes_per_iteration",
            f"must be ≥ 1, got {self.episodes_per_iteration}",
        )
        check(
            0 <= self.teacher_share_decay <= 1,
            "teacher_share_decay",
            f"must be in [0, 1], got {self.teacher_share_decay}",
        )
        check(
            0 < self.temperature < math.inf,
            "temperature",
            f"must be a finite number > 0, got {self.temperature}",
        )
        check(self.epochs >= 1, "epochs", f"must be ≥ 1, got {self.epochs}")
        check(self.batch_size >= 1, "batch_size", f"must be ≥ 1, got {self.batch_size}")
        check(
            0 < self.learning_rate < math.inf,
            "learning_rate",
            f"must be a finite number > 0, got {self.learning_rate}",
        )
        check(
            0 <= self.value_coef < math.inf,
            "value_coef",
            f"must be a finite number ≥ 0, got {self.value_coef}",
        )

    def teacher_share(self, iteration: int) -> float:
        """The probability that the teacher acts at a step of ``iteration`` (DAgger's β)."""
        return self.teacher_share_decay**iteration

    def is_validation(self, episode: int) -> bool:
        """Whether episode ``episode`` of an iteration is held out: a ``validation_share`` of
        the episodes, spread evenly (episode k when ⌊(k + 1) · share⌋ > ⌊k · share⌋; episode 0
        never, so every iteration trains on one episode at least)."""
        share = self.validation_share
        return int((episode + 1) * share) > int(episode * share)


#: The task of a training config that names none: the budget task.
TRAIN_TASK = TaskConfig(name="budget")
#: A training file's flat keys that are its task's (:class:`~nbv_gym.env.task.TaskConfig`).
TASK_KEYS = ("task", *(name for name in TaskConfig.__dataclass_fields__ if name != "name"))

#: Features of the robot state in the network's global feature vector (``features_dim`` holds
#: them and the map's: :class:`~nbv_gym.rl.extractor.MapExtractor`).
STATE_FEATURES = 32


@dataclass(frozen=True)
class TrainConfig:
    """One training run of an RL exploration agent.

    - ``algorithm``: one of :data:`ALGORITHMS`.
    - ``total_timesteps``: environment steps over all parallel environments.
    - ``n_envs``: parallel environments (worker processes without torch when > 1,
      :mod:`~nbv_gym.rl.vecenv`); each cycles over its share of ``train_worlds``, one world per
      episode.
    - ``train_worlds`` / ``eval_worlds``: world names or spec files, or one world distribution
      (``random:wide``, ``random:mixed``, ``random:trees``, …: a world drawn from a pool of
      ``world_pool_size`` every ``episodes_per_world`` resets, 4 by default: a switch to a
      world with trees costs ~1.8 s CPU, and 4 cut budget training's CPU per step from 83 to
      52 ms); evaluation cycles over ``eval_worlds`` with ``eval_episodes`` episodes (default:
      one per world). Defaults: the 256-world pool of ``random:wide``, evaluated on its
      held-out worlds ``random:wide/heldout-0`` … ``-7`` (:mod:`nbv_gym.worlds.pools`).
    - ``task``: the episodes' settings (:class:`~nbv_gym.env.task.TaskConfig`, flat keys in
      the file): the task — ``"budget"`` (the default: ``budget_scans`` scans, no termination,
      travel free: the agent cannot profit from delaying discovery), ``"time"``
      (``time_budget_s`` seconds of robot time, travel and scans charged) or ``"explore"``
      (terminate at 70 % discovered, truncated at ``max_steps``) —, ``noise``, ``lidar``, the
      effort model (``speed_mps``, ``scan_time_s``) and ``observation_layers``: optional layers
      (e.g. ``gain_nobs``) the agent observes besides the base layers; they are stored in the
      model and checked when it is loaded as a policy.
    - ``reward_scale``: the learner sees ``reward_scale · ΔQ`` (ΔQ is ~1e-3 per step, too small
      for the default value-function scale); reported returns are scaled too.
    - ``network``: ``"goal-map"`` scores every goal with a fully convolutional head (the action
      is a cell of the map); ``"dense"`` is SB3's usual MLP head on the CNN features.
    - ``features_dim``: size of the global feature vector (CNN + robot state).
    - ``checkpoint_every_steps`` / ``eval_every_steps``: in environment steps (0 disables); an
      evaluation runs ``eval_episodes`` episodes in the training process, one at a time.
    - ``torch_threads``: the learner's torch threads (0: one per core no environment worker
      runs on, at least one).
    - ``seed``: seeds the learner and the environments (episode ``k`` of env ``i`` derives its
      seed from it).
    - ``scheduler``: where the environments run: ``""`` in worker processes of this machine,
      ``"local"`` on a new Dask LocalCluster of this machine, or the address of a Dask scheduler
      (``tcp://…``, ``tls://…`` with Dask's TLS settings): one actor per worker holds that
      worker's share of the ``n_envs`` environments (:mod:`nbv_gym.rl.daskvec`); the learner
      stays in the calling process.
    - ``init_model``: a trained model (a shipped name such as ``ppo-budget``, or a model zip)
      whose network weights a new training starts from — the same algorithm, network and
      observation layers, another task or budget allowed; the step count, the optimiser and the
      input scaling of the observation's bounds are the new run's. ``""``: random weights.
    - ``imitation``: a table of :class:`ImitationConfig` makes the config a staged recipe —
      labels of a privileged teacher, imitation, then this RL training from the imitated
      weights (:mod:`nbv_gym.rl.recipe`); MaskablePPO only.
    - ``robots``: 1, the single-robot task; N ≥ 2 trains one network shared by N robots on the
      team task (:mod:`nbv_gym.rl.teamvec`): ``n_envs`` team envs in this process, env ``i`` on
      ``train_worlds[i mod len]`` (world names), MaskablePPO, the time task, no evaluation
      during training; steps count robot slots (events · N · n_envs).
    """

    algorithm: str = "MaskablePPO"
    total_timesteps: int = 200_000
    n_envs: int = 2
    train_worlds: tuple[str, ...] = TRAIN_WORLDS
    eval_worlds: tuple[str, ...] = EVAL_WORLDS
    world_pool_size: int = WIDE_POOL_SIZE
    episodes_per_world: int = 4
    task: TaskConfig = TRAIN_TASK
    reward_scale: float = 100.0
    network: Literal["goal-map", "dense"] = "goal-map"
    features_dim: int = 128
    learning: LearningConfig = field(default_factory=LearningConfig)
    checkpoint_every_steps: int = 20_000
    eval_every_steps: int = 10_000
    eval_episodes: int = 0
    seed: int = 0
    device: str = "cpu"
    torch_threads: int = 0
    scheduler: str = ""
    init_model: str = ""
    imitation: ImitationConfig | None = None
    robots: int = 1

    def __post_init__(self) -> None:
        check(
            self.algorithm in ALGORITHMS,
            "algorithm",
            f"expected one of {', '.join(ALGORITHMS)}, got {self.algorithm!r}",
        )
        check(self.total_timesteps >= 1, "total_timesteps", "must be ≥ 1")
        check(self.n_envs >= 1, "n_envs", f"must be ≥ 1, got {self.n_envs}")
        robots = max(self.robots, 1)  # a team training's update sees every robot's slot
        rollout = self.learning.n_steps * self.n_envs * robots
        team = (" · robots", f" · {robots}") if robots > 1 else ("", "")
        check(
            "PPO" not in self.algorithm or self.learning.batch_size <= rollout,
            "learning.batch_size",
            f"must be ≤ n_steps · n_envs{team[0]} = {self.learning.n_steps} · {self.n_envs}"
            f"{team[1]} = {rollout} "
            f"(the steps of one update), got {self.learning.batch_size}; lower it (nbv-gym "
            f"train --batch-size {rollout}) or raise n_steps or n_envs",
        )
        check(len(self.train_worlds) >= 1, "train_worlds", "name at least one world")
        for key in ("train_worlds", "eval_worlds"):
            worlds = getattr(self, key)
            check(
                len(worlds) == 1 or not any(map(is_distribution, worlds)),
                key,
                f"a world distribution (random:…) must be the only entry, got {list(worlds)}",
            )
            check_pool_names(key, worlds)
        check(
            1 <= self.world_pool_size <= MAX_POOL_SIZE,
            "world_pool_size",
            f"must be from 1 to {MAX_POOL_SIZE}",
        )
        check(self.episodes_per_world >= 1, "episodes_per_world", "must be ≥ 1")
        task = self.task
        check(
            task.name != "time" or task.time_budget_s > task.scan_time_s,
            "time_budget_s",
            f"{task.time_budget_s:g} s leaves no goal: each costs a scan (scan_time_s = "
            f"{task.scan_time_s:g} s) and a drive, so every episode would end at its first scan "
            "with nothing to learn; give a larger time budget",
        )
        check(0 < self.reward_scale < math.inf, "reward_scale", "must be a finite number > 0")
        check(
            self.features_dim > STATE_FEATURES,
            "features_dim",
            f"must be > {STATE_FEATURES} (the robot state's features; the rest are the map's), "
            f"got {self.features_dim}",
        )
        check(self.checkpoint_every_steps >= 0, "checkpoint_every_steps", "must be ≥ 0")
        check(self.eval_every_steps >= 0, "eval_every_steps", "must be ≥ 0")
        check(self.eval_episodes >= 0, "eval_episodes", "must be ≥ 0")
        check(self.device in ("cpu", "cuda", "auto"), "device", "expected cpu, cuda or auto")
        check(self.torch_threads >= 0, "torch_threads", "must be ≥ 0 (0: one per free core)")
        check(
            self.scheduler in ("", "local") or "://" in self.scheduler,
            "scheduler",
            f'expected "", "local" or a scheduler address such as tcp://host:8786, got '
            f"{self.scheduler!r}",
        )
        check(
            self.imitation is None or self.algorithm == "MaskablePPO",
            "imitation",
            f'imitates with the action mask: set algorithm = "MaskablePPO", got {self.algorithm!r}',
        )
        check(self.robots >= 1, "robots", f"must be ≥ 1, got {self.robots}")
        if self.robots > 1:
            _check_team(self)

    def env_kwargs(self) -> dict[str, Any]:
        """The :class:`~nbv_gym.env.ExploreEnv` keywords this config trains, evaluates and
        packages under (:meth:`TaskConfig.env_kwargs <nbv_gym.env.task.TaskConfig.env_kwargs>`)."""
        return self.task.env_kwargs()

    def file_dict(self) -> dict[str, Any]:
        """The config as a file holds it (:func:`load_train_config` reads it back): the task's
        keys flat beside the others."""
        data = to_dict(self)
        del data["task"]
        return {**data, **self.task.flat()}

    @property
    def n_eval_episodes(self) -> int:
        """Episodes per evaluation: ``eval_episodes``, or one per evaluation world."""
        return self.eval_episodes or len(self.eval_worlds)


def _setting(config: TrainConfig, key: str) -> Any:
    """The value of the file key ``key`` of ``config`` (a task setting's too)."""
    return config.file_dict()[key]


def _check_team(config: TrainConfig) -> None:
    """ConfigError for what team training (``robots`` ≥ 2) does not run."""
    team = {"algorithm": config.algorithm == "MaskablePPO", "task": config.task.name == "time",
            "scheduler": not config.scheduler, "imitation": config.imitation is None,
            "eval_every_steps": not config.eval_every_steps,
            "observation_layers": not config.task.observation_layers,
            "train_worlds": not any(map(is_distribution, config.train_worlds))}  # fmt: skip
    for key in (key for key, ok in team.items() if not ok):
        check(
            False,
            key,
            f"robots = {config.robots} trains on the team task: MaskablePPO (busy robots' masks), "
            "the time task, world names, in this process, no imitation, no optional layers, no "
            f"evaluation during training; got {_setting(config, key)!r}",
        )


def check_pool_names(key: str, worlds: tuple[str, ...]) -> None:
    """:class:`ConfigError` naming ``key`` for a ``random:…`` name that is no distribution or
    pool world (an unknown kind, an index past the pool's bound): known from the name alone, so
    refused before any world is built, not when a stage first uses it."""
    for world in worlds:
        if not str(world).startswith(PREFIX):
            continue
        try:
            WorldDistribution.from_name(world) if is_distribution(world) else load_spec(world)
        except (ConfigError, UnknownNameError) as error:
            raise ConfigError(f"{key}: {error}") from None


def load_train_config(path: str | Path, overrides: dict[str, Any] | None = None) -> TrainConfig:
    """The :class:`TrainConfig` of a TOML file, with ``overrides`` (keys, e.g. from the command
    line; ``"learning.batch_size"`` sets a key of a table) applied; unknown keys raise
    :class:`ConfigError` naming them."""
    data = read_toml(path, "Training config")
    for key, value in (overrides or {}).items():
        if value is None:
            continue
        table, _, name = key.rpartition(".")
        target = data
        for part in filter(None, table.split(".")):
            target = target.setdefault(part, {})
        target[name] = value
    return train_config(data)


def train_config(data: dict[str, Any]) -> TrainConfig:
    """The :class:`TrainConfig` of a file's table (:meth:`TrainConfig.file_dict`'s shape: the
    task's keys flat, the task ``budget`` when it names none)."""
    rest = {key: value for key, value in data.items() if key not in TASK_KEYS}
    flat = {"task": TRAIN_TASK.name, **{k: data[k] for k in TASK_KEYS if k in data}}
    task = TaskConfig.from_flat(flat)
    return from_dict(TrainConfig, {**rest, "task": to_dict(task)})
