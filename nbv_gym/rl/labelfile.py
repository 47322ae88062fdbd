"""The label shards of imitation learning: one episode's visited states, each with the agent's
observation and a teacher's values of its candidate goals, in one compressed ``.npz`` file.

A shard holds, for the ``n`` states of an episode (decision states: the reset's and every step's
but the last):

- ``layers``: (n, C, G) uint8, the observation's C map layers quantised to 255 levels on the
  network's own input scale — ``x`` for a layer in [0, 1], ``log1p(x) / log1p(high)`` for a
  layer whose upper bound ``high`` exceeds 1 (the gain layers, the time task's ``cost``), as
  :class:`~nbv_gym.rl.extractor.MapExtractor` scales them — so a decoded layer is within half a
  level (0.2 % of the scale) of the observed one; ``keys`` (C,) names them and ``highs`` (C,)
  holds their upper bounds;
- ``state``: (n, 6) float32, the robot state, exact;
- ``mask``: (n, ⌈G / 8⌉) uint8, the action mask as bits (``np.packbits``);
- ``candidates`` (m,) int32 and ``values`` (m,) float64: the teacher's candidate goals and their
  values, state ``t``'s at ``offsets[t]:offsets[t + 1]`` (``offsets``: (n + 1,) int64), in the
  teacher's order (its tie-break: the first); a value is a finite number or −inf (a candidate the
  teacher rules out), and a state with candidates has at least one finite value;
- ``action`` (n,) int32, the goal taken; ``teacher_acted`` (n,) bool, whether the teacher chose
  it; ``reward`` (n,) float64, the environment's reward of the step (unscaled);
- ``world``, ``iteration``, ``episode``, ``seed``: where the episode ran and its reset seed.

Measured on ``random:mixed`` under the time task with the 19 layers of ``imitation-time``: about
12 kB a state (docs/rl.md#imitation).
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np
from gymnasium import spaces

from nbv_gym.core.errors import NbvGymError
from nbv_gym.env.observation import BASE_LAYERS, observation_space

#: Quantisation levels of a layer (uint8).
LEVELS = 255
STATE_KEY = "state"


class LabelFileError(NbvGymError):
    """A label shard is unreadable or not one of this format."""


def _log_scaled(highs: np.ndarray) -> np.ndarray:
    """(C,) bool: the layers that are quantised on a log scale (upper bound above 1)."""
    return np.asarray(highs, np.float64) > 1


def encode_layers(layers: np.ndarray, highs: np.ndarray) -> np.ndarray:
    """(C, G) float layers → (C, G) uint8 on the network's input scale (module docstring)."""
    x = np.clip(np.asarray(layers, np.float64), 0, None)
    log = _log_scaled(highs)
    scale = np.where(log, np.log1p(np.maximum(highs, 1)), 1.0)[:, None]
    unit = np.where(log[:, None], np.log1p(x) / scale, x)
    return np.rint(np.clip(unit, 0, 1) * LEVELS).astype(np.uint8)


def decoding_table(highs: np.ndarray) -> np.ndarray:
    """(C, 256) float32: the layer value of each level of each layer (the inverse of
    :func:`encode_layers` up to the rounding)."""
    levels = np.arange(LEVELS + 1, dtype=np.float64) / LEVELS
    log = _log_scaled(highs)[:, None]
    scale = np.log1p(np.maximum(np.asarray(highs, np.float64), 1))[:, None]
    return np.where(log, np.expm1(levels * scale), levels).astype(np.float32)


@dataclass
class EpisodeLabels:
    """One episode's labelled states (the module docstring names the arrays)."""

    keys: tuple[str, ...]
    highs: np.ndarray
    layers: np.ndarray
    state: np.ndarray
    mask: np.ndarray
    offsets: np.ndarray
    candidates: np.ndarray
    values: np.ndarray
    action: np.ndarray
    teacher_acted: np.ndarray
    reward: np.ndarray
    world: str = ""
    iteration: int = 0
    episode: int = 0
    seed: int = 0

    def __len__(self) -> int:
        return len(self.layers)

    @property
    def n_goals(self) -> int:
        """G: the goals of a layer."""
        return self.layers.shape[2]

    def masks(self) -> np.ndarray:
        """(n, G) bool: the action masks."""
        return np.unpackbits(self.mask, axis=1, count=self.n_goals).astype(bool)

    def teacher_values(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """State ``t``'s candidate goals and the teacher's values of them."""
        span = slice(self.offsets[t], self.offsets[t + 1])
        return self.candidates[span], self.values[span]

    def observations(self) -> dict[str, np.ndarray]:
        """The decoded observations: key → (n, G) float32 layers, and ``state`` (n, 6)."""
        table = decoding_table(self.highs)
        out = {k: table[c][self.layers[:, c]] for c, k in enumerate(self.keys)}
        return {**out, STATE_KEY: self.state}

    def to_bytes(self) -> bytes:
        """The shard as compressed ``.npz`` bytes."""
        buffer = io.BytesIO()
        arrays = {name: getattr(self, name) for name in _ARRAYS}
        np.savez_compressed(
            buffer, **arrays, keys=np.array(self.keys), world=np.array(self.world),
            meta=np.array([self.iteration, self.episode, self.seed], np.int64),
        )  # fmt: skip
        return buffer.getvalue()

    @classmethod
    def from_file(cls, path: str | Path) -> EpisodeLabels:
        """The shard at ``path``; :class:`LabelFileError` if it is not one."""
        try:
            with np.load(path, allow_pickle=False) as data:
                iteration, episode, seed = (int(v) for v in data["meta"])
                labels = cls(
                    keys=tuple(str(k) for k in data["keys"]),
                    **{name: data[name] for name in _ARRAYS},
                    world=str(data["world"]), iteration=iteration, episode=episode, seed=seed,
                )  # fmt: skip
        except (OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError) as error:
            raise LabelFileError(
                f"{str(path)!r} is not a label shard ({type(error).__name__}: {error}); delete "
                "it and rerun the same command (its episode is collected again)."
            ) from None
        if (problem := labels.value_problem()) is not None:
            raise LabelFileError(
                f"{str(path)!r} {problem}: a teacher rates each candidate a finite number, or "
                "−inf to rule it out; delete the shard and rerun the same command (its episode "
                "is collected again)."
            )
        return labels

    def value_problem(self) -> str | None:
        """What makes the teacher's values unusable (NaN or +inf values, or a state whose
        candidates are all −inf), or None."""
        values = np.asarray(self.values, np.float64)
        bad = int((np.isnan(values) | np.isposinf(values)).sum())
        if bad:
            return f"holds {bad} NaN or +inf teacher value(s)"
        sizes = np.diff(self.offsets)
        starts = self.offsets[:-1][sizes > 0]
        best = np.maximum.reduceat(values, starts) if len(starts) else values[:0]
        if np.isneginf(best).any():
            return f"holds {int(np.isneginf(best).sum())} state(s) whose candidates are all −inf"
        return None


_ARRAYS = ("highs", "layers", "state", "mask", "offsets", "candidates", "values", "action",
           "teacher_acted", "reward")  # fmt: skip


@dataclass
class EpisodeRecorder:
    """Builds an :class:`EpisodeLabels` state by state: :meth:`add` a decision (before its step),
    then :meth:`rewarded` its step's reward; :meth:`labels` at the end."""

    keys: tuple[str, ...]
    highs: np.ndarray
    rows: list[tuple] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)

    @classmethod
    def of_space(cls, space: spaces.Dict) -> EpisodeRecorder:
        """A recorder of the map layers of the observation ``space`` (every key but ``state``)."""
        keys = tuple(k for k in space.spaces if k != STATE_KEY)
        highs = np.array([float(np.max(cast(spaces.Box, space[k]).high)) for k in keys])
        return cls(keys, highs)

    def add(self, observation, mask, candidates, values, action: int, teacher: bool) -> None:
        """Record a decision: the ``observation``, the (G,) action ``mask``, the teacher's
        (m,) ``candidates`` and their (m,) ``values``, the goal taken and who chose it."""
        layers = np.stack([np.asarray(observation[k], np.float32) for k in self.keys])
        self.rows.append((
            encode_layers(layers, self.highs), np.asarray(observation[STATE_KEY], np.float32),
            np.packbits(np.asarray(mask, bool)), np.asarray(candidates, np.int32),
            np.asarray(values, np.float64), int(action), bool(teacher),
        ))  # fmt: skip

    def rewarded(self, reward: float) -> None:
        """The reward of the last decision's step."""
        self.rewards.append(float(reward))

    def labels(self, world: str, iteration: int, episode: int, seed: int) -> EpisodeLabels:
        """The recorded episode."""
        if not self.rows or len(self.rewards) != len(self.rows):
            raise ValueError(f"{len(self.rows)} decisions and {len(self.rewards)} rewards")
        layers, state, mask, candidates, values, action, teacher = zip(*self.rows, strict=True)
        sizes = [len(c) for c in candidates]
        return EpisodeLabels(
            keys=self.keys, highs=self.highs,
            layers=np.array(layers, np.uint8), state=np.array(state, np.float32),
            mask=np.array(mask, np.uint8),
            offsets=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
            candidates=np.concatenate([np.zeros(0, np.int32), *candidates]),
            values=np.concatenate([np.zeros(0), *values]),
            action=np.array(action, np.int32), teacher_acted=np.array(teacher, bool),
            reward=np.array(self.rewards), world=world, iteration=iteration, episode=episode,
            seed=seed,
        )  # fmt: skip


def labels_space(labels: EpisodeLabels) -> spaces.Dict:
    """The observation space the labels were recorded under (the environment's: the base
    layers, the optional layers with their bounds, ``state``), rebuilt from the shard."""
    highs = dict(zip(labels.keys, (float(h) for h in labels.highs), strict=True))
    missing = [k for k in BASE_LAYERS if k not in highs]
    if missing:
        raise LabelFileError(f"label shard without the base layers {missing}")
    optional = {k: h for k, h in highs.items() if k not in BASE_LAYERS}
    return observation_space(labels.n_goals, optional, highs["cost"])
