"""DAgger label collection: episodes on the training worlds in which a privileged teacher labels
every visited state with its values of its candidate goals, while a mixture of the teacher and
the current learner acts.

Episode ``k`` of iteration ``i`` resets with :func:`episode_seed` ``(seed, i, k)`` (which also
draws its world from a distribution, and seeds the teacher's candidate draws); at each step the
teacher acts with probability β = :meth:`~nbv_gym.rl.config.ImitationConfig.teacher_share`
``(i)`` (a coin from a generator of the same seed), the learner of iteration ``i − 1`` otherwise
(its most probable valid goal, from the agent's view only). So an episode's labels depend on its
seed, the config and the learner alone: which worker ran it, and when, changes nothing.

Every episode is one shard (:mod:`nbv_gym.rl.labelfile`), written atomically by this process as
it arrives: a collection killed at any point goes on where it stopped when run again (the
finished shards are kept, the others collected anew, the same bits). Episodes run here (one
environment), in local worker processes (``n_envs``, which exit with this process even after
``kill -9``) or on a Dask cluster (``scheduler``: an address or ``"local"``; the workers return
the shards, so they need no shared disk).
"""

from __future__ import annotations

import hashlib
import multiprocessing
import tempfile
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from gymnasium import spaces

from nbv_gym.core.errors import ConfigError
from nbv_gym.core.outputs import atomic
from nbv_gym.core.processes import exit_with_parent, worker_environment
from nbv_gym.core.progress import progress_bar, say
from nbv_gym.env.explore import ExploreEnv
from nbv_gym.env.views import agent_view
from nbv_gym.rl.config import TrainConfig
from nbv_gym.rl.labelfile import EpisodeLabels, EpisodeRecorder, LabelFileError
from nbv_gym.rl.modelfile import describe_model
from nbv_gym.worlds import load_world
from nbv_gym.worlds.distribution import is_distribution


@dataclass(frozen=True)
class CollectionSetup:
    """What the episodes of a collection share: the training ``worlds`` (a distribution, or
    names cycled episode by episode), the environment's keywords (sorted items of
    :meth:`TrainConfig.env_kwargs <nbv_gym.rl.config.TrainConfig.env_kwargs>` and the pool
    size) and the ``teacher``'s policy name. A worker keeps one environment per setup."""

    worlds: tuple[str, ...]
    env_kwargs: tuple[tuple[str, Any], ...]
    teacher: str

    @classmethod
    def of(cls, config: TrainConfig) -> CollectionSetup:
        """The setup of a recipe's config (its ``imitation`` table set)."""
        assert config.imitation is not None
        kwargs = {**config.env_kwargs(), "world_pool_size": config.world_pool_size}
        return cls(config.train_worlds, tuple(sorted(kwargs.items())), config.imitation.teacher)


@dataclass(frozen=True)
class EpisodeJob:
    """One episode to label: episode ``episode`` of ``iteration``, reset with ``seed``, the
    teacher acting with probability ``teacher_share``."""

    setup: CollectionSetup
    iteration: int
    episode: int
    seed: int
    teacher_share: float


def episode_seed(seed: int, iteration: int, episode: int) -> int:
    """The reset seed of episode ``episode`` of ``iteration`` under the config's ``seed``."""
    return int(np.random.SeedSequence([seed, iteration, episode]).generate_state(1)[0])


def shard_path(folder: Path, episode: int) -> Path:
    """The shard of episode ``episode`` in an iteration's ``folder``."""
    return folder / f"episode-{episode:05d}.npz"


def check_teacher(config: TrainConfig) -> None:
    """:class:`ConfigError` unless the recipe's teacher is a privileged policy with ``values``
    whose observation layers the config's ``observation_layers`` hold (the labels store the
    agent's observation, which the teacher reads too)."""
    from nbv_gym.policies import is_oracle, load_policy

    assert config.imitation is not None
    name = config.imitation.teacher
    teacher = load_policy(name)
    if not (is_oracle(teacher) and callable(getattr(teacher, "values", None))):
        raise ConfigError(
            f"imitation.teacher: {name!r} gives no values of its candidates; a teacher is a "
            "privileged policy with values(observation, info), such as oracle-time"
        )
    missing = [k for k in teacher.observation_layers if k not in config.task.observation_layers]
    if missing:
        raise ConfigError(
            f"observation_layers: the teacher {name} reads {missing}; add them (the labels "
            "store the agent's observation, and the teacher reads that one)"
        )


def collect(
    config: TrainConfig, folder: Path, iteration: int, learner: Path | None, progress: bool = True
) -> list[Path]:
    """Label the episodes of ``iteration`` into ``folder`` (those without a shard yet) and
    return every shard's path; ``learner``: the model zip acting beside the teacher (needed
    when the teacher's share is below 1)."""
    imitation = config.imitation
    assert imitation is not None
    folder.mkdir(parents=True, exist_ok=True)
    for stale in folder.glob("*.npz.tmp*"):  # a write cut short by a kill
        stale.unlink()
    paths = [shard_path(folder, k) for k in range(imitation.episodes_per_iteration)]
    share = imitation.teacher_share(iteration)
    setup = CollectionSetup.of(config)
    for k, path in enumerate(paths):
        if path.exists():
            check_shard(path, config.seed, iteration, k)
    todo = [EpisodeJob(setup, iteration, k, episode_seed(config.seed, iteration, k), share)
            for k, path in enumerate(paths) if not path.exists()]  # fmt: skip
    if not todo:
        return paths
    if share < 1 and learner is None:
        raise ValueError(f"iteration {iteration} needs a learner (teacher share {share:g})")
    if share < 1 and learner is not None:
        describe_model(learner)  # a damaged model is named here, not as a worker's copy of it
    model = learner.read_bytes() if share < 1 and learner is not None else None
    say(f"labels of iteration {iteration}: {len(todo)} of {len(paths)} episodes to collect "
        f"(teacher share {share:g}) {_where(config)}…")  # fmt: skip
    started, states = time.monotonic(), 0
    with progress_bar(len(paths), f"labels {iteration}", "episode", initial=len(paths) - len(todo),
                      disable=not progress) as bar:  # fmt: skip
        for episode, n, data in _run(config, todo, model):
            with atomic(paths[episode], "wb") as file:
                file.write(data)
            states += n
            bar.set_postfix_str(f"{states / (time.monotonic() - started):.2f} labels/s")
            bar.update()
    return paths


def check_shard(path: Path, seed: int, iteration: int, episode: int) -> None:
    """:class:`LabelFileError` unless the shard at ``path`` is episode ``episode`` of
    ``iteration`` under the config's ``seed`` (a shard copied from another run, iteration or
    episode is never trained on)."""
    labels = EpisodeLabels.from_file(path)
    found = (labels.iteration, labels.episode, labels.seed)
    expected = (iteration, episode, episode_seed(seed, iteration, episode))
    if found != expected:
        raise LabelFileError(
            f"{str(path)!r} holds iteration {found[0]}, episode {found[1]} with reset seed "
            f"{found[2]}, not this recipe's iteration {expected[0]}, episode {expected[1]} "
            f"(seed {expected[2]}): a shard of another run; delete it and rerun the same "
            "command (its episode is collected again)."
        )


def _where(config: TrainConfig) -> str:
    if config.scheduler:
        return f"on {config.scheduler}"
    return f"in {config.n_envs} worker processes" if config.n_envs > 1 else "here"


def _run(
    config: TrainConfig, jobs: list[EpisodeJob], model: bytes | None
) -> Iterator[tuple[int, int, bytes]]:
    """``(episode, states, shard bytes)`` of each job as it finishes, run where ``config``
    says."""
    if config.scheduler:
        yield from _run_on_dask(config, jobs, model)
    elif config.n_envs > 1:
        yield from _run_in_pool(config.n_envs, jobs, model)
    else:
        for job in jobs:
            yield (job.episode, *collect_episode(job, model))


def _run_in_pool(
    workers: int, jobs: list[EpisodeJob], model: bytes | None
) -> Iterator[tuple[int, int, bytes]]:
    context = multiprocessing.get_context("forkserver")
    alive, keep = context.Pipe(duplex=False)  # the workers watch `alive`; only we hold `keep`
    try:
        pool = ProcessPoolExecutor(
            min(workers, len(jobs)), context, initializer=exit_with_parent, initargs=(alive,)
        )
        with pool:
            with worker_environment():  # the workers start at the first submissions
                futures = {pool.submit(collect_episode, job, model): job for job in jobs}
            try:
                for future in as_completed(futures):
                    yield (futures[future].episode, *future.result())
            finally:
                for future in futures:
                    future.cancel()
    finally:
        keep.close()
        alive.close()


def _run_on_dask(
    config: TrainConfig, jobs: list[EpisodeJob], model: bytes | None
) -> Iterator[tuple[int, int, bytes]]:
    from distributed import as_completed as dask_completed

    from nbv_gym.core.cluster import connect

    client, cluster = connect(config.scheduler, config.n_envs)
    try:
        shared = client.scatter(model, broadcast=True) if model is not None else None
        futures = {
            client.submit(collect_episode, job, shared, pure=False, retries=2): job for job in jobs
        }
        for future in dask_completed(futures):
            yield (futures[future].episode, *future.result())
            future.release()
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


# the worker side


def collect_episode(job: EpisodeJob, model: bytes | None) -> tuple[int, bytes]:
    """Run and label one episode (in any process): its number of states and its shard's
    bytes. ``model``: the learner's model zip (read when the teacher's share is below 1)."""
    worker = _worker(job.setup)
    learner = _learner(model) if model is not None and job.teacher_share < 1 else None
    labels = worker.run(job, learner)
    if (problem := labels.value_problem()) is not None:  # never written: a rerun would repeat it
        raise LabelFileError(
            f"teacher {job.setup.teacher!r}: episode {job.episode} {problem}; a teacher rates "
            "each candidate a finite number, or −inf to rule it out"
        )
    return len(labels), labels.to_bytes()


class _Worker:
    """A worker's environment and teacher for one :class:`CollectionSetup`."""

    def __init__(self, setup: CollectionSetup):
        from nbv_gym.policies import load_policy

        self.setup = setup
        self.teacher: Any = load_policy(setup.teacher)
        kwargs = {**dict(setup.env_kwargs), "episodes_per_world": 1}
        self.env = ExploreEnv(world=setup.worlds[0], **kwargs)
        self.world = setup.worlds[0]

    def run(self, job: EpisodeJob, learner) -> Any:
        """The labels of ``job``'s episode."""
        env, teacher = self.env, self.teacher
        self._switch(job.episode)
        observation, info = env.reset(seed=job.seed)
        teacher.reset(job.seed)
        teacher.attach(env)
        coin = np.random.default_rng([job.seed, 1])
        recorder = EpisodeRecorder.of_space(cast(spaces.Dict, env.observation_space))
        done = False
        while not done:
            values = teacher.values(observation, info)
            labelled = np.isfinite(values).any()
            goals = teacher.last_evaluation["goals"] if labelled else np.zeros(0, np.int64)
            teacher_acts = coin.random() < job.teacher_share
            if teacher_acts:
                goal = (
                    int(goals[np.argmax(values[goals])])
                    if labelled
                    else teacher.act(observation, info)
                )
            else:
                goal = learner.act(observation, agent_view(info))
            recorder.add(observation, info["action_mask"], goals, values[goals], goal, teacher_acts)
            observation, reward, terminated, truncated, info = env.step(goal)
            recorder.rewarded(reward)
            done = terminated or truncated
        return recorder.labels(info["world"], job.iteration, job.episode, job.seed)

    def _switch(self, episode: int) -> None:
        """Go to the episode's world of a list of worlds (a distribution draws at reset)."""
        worlds = self.setup.worlds
        if len(worlds) == 1 and is_distribution(worlds[0]):
            return
        world = worlds[episode % len(worlds)]
        if world != self.world:
            self.env.sim.set_world(load_world(world))
            self.world = world


#: Per thread (a Dask worker may run tasks on several threads): its worker and learner.
_CACHE = threading.local()


def _worker(setup: CollectionSetup) -> _Worker:
    """This thread's worker of ``setup`` (built on first use, then kept: one environment per
    thread)."""
    if getattr(_CACHE, "worker", None) is None or _CACHE.worker.setup != setup:
        _CACHE.worker = None  # the previous environment goes before the next is built
        _CACHE.worker = _Worker(setup)
    return _CACHE.worker


def _learner(model: bytes):
    """The learner of a model zip's bytes as a policy (loaded once per thread and model)."""
    from nbv_gym.rl.agent import SB3Policy

    key = hashlib.sha256(model).hexdigest()
    if getattr(_CACHE, "learner_key", None) != key:
        _CACHE.learner = None
        with tempfile.TemporaryDirectory(prefix="nbv-gym-learner-") as folder:
            path = Path(folder) / "learner.zip"
            path.write_bytes(model)
            _CACHE.learner = SB3Policy(path)  # loaded into memory: the file may go
        _CACHE.learner_key = key
    return _CACHE.learner
