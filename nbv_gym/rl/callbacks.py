"""Training callbacks of ``nbv-gym train`` (the episode log behind the learning curve, a
wall-clock limit, torch's thread count per phase) and the timers of the RL perf suite
(:mod:`nbv_gym.perf.rl`)."""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import IO

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnvWrapper

from nbv_gym.rl.curve import COLUMNS


class EpisodeLog(BaseCallback):
    """Appends a row to ``path`` (``episodes.csv``) for every training episode that ends; the
    rows are flushed at the end of every rollout. A file written by an older version keeps its
    columns."""

    def __init__(self, path: Path):
        super().__init__()
        self.path = Path(path)
        self._file: IO[str]  # both opened when training starts
        self._writer: csv.DictWriter[str]

    def _on_training_start(self) -> None:
        header = _header(self.path)
        self._file = open(self.path, "a", newline="", encoding="utf-8")
        self._writer = csv.DictWriter(self._file, header or COLUMNS, extrasaction="ignore")
        if header is None:  # a new file, or one left empty by an interrupted training
            self._writer.writeheader()
            self._file.flush()

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            if "episode" in info:
                row = episode_row(self.num_timesteps, info)
                self._writer.writerow(dict(zip(COLUMNS, row, strict=True)))
        return True

    def _on_rollout_end(self) -> None:
        self._file.flush()

    def _on_training_end(self) -> None:
        self.close()

    def close(self) -> None:
        """Flush and close the file (again: nothing)."""
        if self._file is not None:
            self._file.close()


def episode_row(timesteps: int, info: dict) -> list:
    """The ``episodes.csv`` row of an episode that ended with ``info`` (SB3's ``Monitor``
    statistics in ``info["episode"]``, the environment's last info otherwise)."""
    episode = info["episode"]
    return [
        timesteps,
        info.get("world", ""),
        f"{float(episode['r']):.6g}",
        int(episode["l"]),
        f"{float(info['q']):.6g}",
        f"{float(info['discovered']):.6g}",
        f"{float(info['path_length_m']):.6g}",
        info.get("end_reason", ""),
    ]


def _header(path: Path) -> list[str] | None:
    """The columns of the CSV file at ``path``; None if there is none yet."""
    if not path.exists():
        return None
    with open(path, newline="", encoding="utf-8") as file:
        return next(csv.reader(file), None)


class TimeLimit(BaseCallback):
    """Stops training once ``limit_s`` seconds of wall time have passed since it started (the
    run then ends as if finished: final model and learning curve saved)."""

    def __init__(self, limit_s: float):
        super().__init__()
        self.limit_s = limit_s
        self._start = 0.0

    def _on_training_start(self) -> None:
        self._start = time.perf_counter()

    def _on_step(self) -> bool:
        return time.perf_counter() - self._start < self.limit_s


class TorchThreads(BaseCallback):
    """Gives torch ``rollout`` intra-op threads while the environment workers step and
    ``update`` threads while PPO updates (the workers idle meanwhile);
    :func:`~nbv_gym.rl.learner.torch_threads` chooses the counts."""

    def __init__(self, rollout: int, update: int):
        super().__init__()
        self.rollout, self.update = rollout, update

    def _on_rollout_start(self) -> None:
        import torch

        torch.set_num_threads(self.rollout)

    def _on_rollout_end(self) -> None:
        import torch

        torch.set_num_threads(self.update)

    def _on_step(self) -> bool:
        return True


class TimedVecEnv(VecEnvWrapper):
    """A ``VecEnv`` that adds the wall time of every call into its environments to
    ``seconds``."""

    def __init__(self, venv):
        super().__init__(venv)
        self.seconds = 0.0

    def _timed(self, call, *args, **kwargs):
        start = time.perf_counter()
        try:
            return call(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - start

    def reset(self):
        """Reset the wrapped environments, timing it."""
        return self._timed(self.venv.reset)

    def step_async(self, actions) -> None:
        """Send ``actions`` to the wrapped environments, timing it."""
        self._timed(self.venv.step_async, actions)

    def step_wait(self):
        """Wait for the wrapped environments' step, timing it."""
        return self._timed(self.venv.step_wait)

    def env_method(self, method_name: str, *args, indices=None, **kwargs):
        """Call ``method_name`` on the wrapped environments, timing it."""
        return self._timed(self.venv.env_method, method_name, *args, indices=indices, **kwargs)


class PhaseTimer(BaseCallback):
    """Wall seconds of the rollouts (``rollout_s``) and of the updates between and after them
    (``update_s``) of one ``learn`` call."""

    def __init__(self):
        super().__init__()
        self.rollout_s = self.update_s = 0.0
        self._mark: float | None = None

    def _on_rollout_start(self) -> None:
        now = time.perf_counter()
        if self._mark is not None:  # an update ran since the last rollout ended
            self.update_s += now - self._mark
        self._mark = now

    def _on_rollout_end(self) -> None:
        now = time.perf_counter()
        if self._mark is not None:  # the rollout started at the mark
            self.rollout_s += now - self._mark
        self._mark = now

    def _on_training_end(self) -> None:
        if self._mark is not None:
            self.update_s += time.perf_counter() - self._mark

    def _on_step(self) -> bool:
        return True
