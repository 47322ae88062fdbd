"""Episodes of any policy as a Minari dataset (``nbv-gym record``), to seed offline RL or imitation.

A dataset holds, per episode, the observations (the environment's ``Dict`` of flat layers and
state), the actions (goal indices), rewards, terminations and truncations, and from the infos the
``action_mask`` (int8, 3600) with ``discovered``, ``q``, ``q_paper`` and ``path_length_m``; each
episode's reset seed is in its metadata, so an episode replays exactly::

    MINARI_DATASETS_PATH=OUT python -c "import minari; minari.load_dataset('nbv-gym/...-v0')"

or :func:`load_recording` (``OUT``, id). The environment is made with ``gymnasium.make`` and the
recorded keyword arguments (``dataset.recover_environment()`` rebuilds it). Needs the optional
``minari`` (``pip install "nbv-gym[data]"``).
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from nbv_gym.core.errors import NbvGymError
from nbv_gym.core.names import check_path_of_names
from nbv_gym.core.outputs import writable_folder
from nbv_gym.core.protocol import TASK_IDS
from nbv_gym.env.task import TaskConfig

#: The info entries kept in a dataset (the rest is derived or not array-like).
INFO_KEYS = ("action_mask", "discovered", "q", "q_paper", "path_length_m")


class RecordError(NbvGymError, ValueError):
    """Episodes cannot be recorded as asked (missing minari, bad count, existing dataset)."""


def record_dataset(
    policy: str,
    world: str,
    out: str | Path,
    task: TaskConfig | None = None,
    episodes: int = 1,
    seed: int = 0,
    dataset_id: str | None = None,
    progress: Callable[[str], None] | None = None,
):
    """Run ``episodes`` episodes of ``policy`` on ``world`` (reset seeds ``seed``, ``seed + 1``,
    …) under ``task`` (a :class:`~nbv_gym.env.task.TaskConfig`, default: the explore task's
    defaults; the policy's own observation layers are added) and write them as a Minari dataset
    under the folder ``out``; the ``MinariDataset``. The environment is made with the task's
    keywords (:meth:`~nbv_gym.env.task.TaskConfig.env_kwargs`), which the dataset records."""
    task = task or TaskConfig()
    if episodes < 1:
        raise RecordError(f"--episodes must be ≥ 1, got {episodes}")
    dataset_id = check_path_of_names(dataset_id or default_id(world, policy), "--dataset-id", 3)
    if not re.search(r"-v\d+$", dataset_id):
        raise RecordError(
            f"--dataset-id {dataset_id!r} has no version; Minari ids end in -v<number>, e.g. "
            f"{dataset_id}-v0."
        )
    writable_folder(out)
    minari = _minari()
    import gymnasium

    from nbv_gym.core.provenance import code_permalink
    from nbv_gym.policies import load_policy, required_layers

    agent = load_policy(policy)
    layers = tuple(dict.fromkeys((*task.observation_layers, *required_layers(agent))))
    kwargs = {**task.env_kwargs(), "observation_layers": layers}
    env = gymnasium.make(TASK_IDS[kwargs.pop("task")], world=world, **kwargs)
    buffers = []
    for k in range(episodes):
        buffers.append(_episode(env, agent, seed + k, k))
        if progress:
            progress(f"episode {k + 1}/{episodes}: {len(buffers[-1].actions)} steps")
    with datasets_path(out), warnings.catch_warnings():
        warnings.filterwarnings("ignore", r"`(author_email|eval_env)` is set")
        if dataset_id in minari.list_local_datasets():
            raise RecordError(f"{Path(out) / dataset_id} exists; choose another --out or id")
        return minari.create_dataset_from_buffers(
            dataset_id, buffers, env=env, data_format="arrow", algorithm_name=policy,
            author="nbv-gym", code_permalink=code_permalink(), requirements=requirements(),
            description=f"{episodes} episodes of {policy} on {world} ({task.name} task, noise "
            f"{task.noise}, lidar {task.lidar}), reset seeds {seed}…{seed + episodes - 1}; nbv-gym record",
        )  # fmt: skip


def requirements() -> list[str]:
    """The pip requirements that rebuild a recorded environment: this nbv-gym version."""
    from importlib.metadata import version

    return [f"nbv-gym=={version('nbv-gym')}"]


def load_recording(out: str | Path, dataset_id: str):
    """The Minari dataset ``dataset_id`` written under the folder ``out``."""
    minari = _minari()
    with datasets_path(out):
        return minari.load_dataset(dataset_id)


def default_id(world: str, policy: str) -> str:
    """``nbv-gym/WORLD/POLICY-v0`` with characters Minari refuses replaced by ``-``."""

    def clean(text: str) -> str:
        text = re.sub(r"[^A-Za-z0-9_.]+", "-", Path(text).stem if "/" in text else text)
        return re.sub(r"\.{2,}", ".", text).strip(".-") or "x"

    return f"nbv-gym/{clean(world)}/{clean(policy)}-v0"


@contextmanager
def datasets_path(out: str | Path) -> Iterator[None]:
    """Point Minari's dataset root (``MINARI_DATASETS_PATH``) at ``out`` while inside."""
    previous = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(out).resolve())
    try:
        yield
    finally:
        if previous is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = previous


def _episode(env, agent, seed: int, index: int):
    """One episode of ``agent`` in ``env`` from ``reset(seed=seed)`` as a Minari episode buffer:
    observations and kept infos of the reset and of every step, actions, rewards, flags."""
    from minari.data_collector import EpisodeBuffer

    from nbv_gym.episode import policy_info, start_episode

    observation, info, oracle = start_episode(env, agent, seed)
    if info["end_reason"]:
        raise RecordError(
            f"episode {index} (seed {seed}) ended at its first scan ({info['end_reason']}): it "
            "has no step to record."
        )
    observations, infos, steps = [observation], [_kept(info)], []
    done = False
    while not done:
        action = int(agent.act(observation, policy_info(agent, info, oracle)))
        observation, reward, terminated, truncated, info = env.step(action)
        observations.append(observation)
        infos.append(_kept(info))
        steps.append((action, reward, terminated, truncated))
        done = terminated or truncated
    actions, rewards, terminations, truncations = (np.array(c) for c in zip(*steps, strict=True))
    return EpisodeBuffer(
        id=index, seed=seed, observations=_stack(observations), actions=actions,
        rewards=rewards.astype(np.float64), terminations=terminations, truncations=truncations,
        infos=_info_columns(infos),
    )  # fmt: skip


def _kept(info: dict) -> dict:
    """The :data:`INFO_KEYS` of an info dict as arrays (the mask as int8)."""
    return {
        k: np.asarray(info[k], np.int8 if k == "action_mask" else np.float64) for k in INFO_KEYS
    }


def _info_columns(infos: list[dict]) -> dict:
    """Per-step infos as columns: stacked arrays, but plain lists for scalars (Minari 0.5.4's
    Arrow storage cannot read back a column of 0-d arrays)."""
    return {k: v if v.ndim > 1 else v.tolist() for k, v in _stack(infos).items()}


def _stack(dicts: list[dict]) -> dict:
    """A list of dicts of arrays as one dict of stacked arrays (the first axis over the list)."""
    return {k: np.stack([d[k] for d in dicts]) for k in dicts[0]}


def _minari():
    try:
        import minari
    except ImportError:
        raise RecordError('recording datasets needs minari: pip install "nbv-gym[data]"') from None
    return minari
