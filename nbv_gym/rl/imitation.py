"""Imitation of a teacher's labels by the goal-map policy of ``nbv-gym train`` (the network RL
then fine-tunes).

Loss, per labelled state (:mod:`nbv_gym.rl.labelfile`): the cross-entropy between the teacher's
target distribution over its candidates — ``softmax((value − best) / (T · max |value|))``, T the
``temperature``, zero off the candidates — and the policy's own distribution, the softmax of its
goal scores over the valid goals (the one MaskablePPO samples from and acts by). So the
imitated weights are the RL policy's weights unchanged, and the policy learns both which
candidate is best and to choose among candidates at all: a valid goal the teacher did not rate
gets no target mass. Plus ``value_coef`` times the squared error of the critic on each state's
discounted return in its episode (``learning.gamma``, ``reward_scale`` times the reward), so RL
starts from a fitted critic. Adam, gradients clipped at ``learning.max_grad_norm``.

Validation on the held-out episodes: the loss, the top-1 agreement with the teacher (the policy's
most probable valid goal is the teacher's best candidate), the agreement among the candidates
only, the regret in teacher value of the policy's best candidate (a share of the best
candidate's value) and the share of states whose most probable goal is no candidate.

Each epoch visits the training shards in an order drawn from ``(seed, iteration, epoch)``,
:data:`BUFFER_EPISODES` at a time (their states shuffled), so memory holds a few thousand states
whatever the label set's size. After each epoch a checkpoint (weights, optimiser, metrics) is
written atomically: a killed imitation goes on from its last epoch, and ends as it would have.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from nbv_gym.core.outputs import atomic
from nbv_gym.core.progress import progress_bar
from nbv_gym.rl.config import TrainConfig
from nbv_gym.rl.labelfile import (
    STATE_KEY,
    EpisodeLabels,
    LabelFileError,
    decoding_table,
    labels_space,
)

#: Shards (episodes) whose states are shuffled together.
BUFFER_EPISODES = 32
CHECKPOINT = "checkpoint.pt"
MODEL = "model.zip"
METRICS = "metrics.csv"
METRIC_COLUMNS = ("iteration", "epoch", "train_states", "train_loss", "validation_states",
                  "validation_loss", "top1", "top1_candidates", "regret", "outside")  # fmt: skip


def teacher_targets(values: np.ndarray, temperature: float) -> np.ndarray:
    """(m,) float64 target probabilities of (m,) candidate ``values`` (finite, or −inf for a
    candidate ruled out, at least one finite): a softmax at ``temperature`` relative to the
    largest finite |value| (uniform over the finite ones when they are all 0); 0 for −inf."""
    finite = np.isfinite(values)
    scale = float(np.max(np.abs(values[finite])))
    if not scale > 0:
        return finite / finite.sum()
    weights = np.exp((values - np.max(values)) / (temperature * scale))
    return weights / weights.sum()


def check_same_layout(path: Path, labels: EpisodeLabels, first: EpisodeLabels) -> None:
    """:class:`LabelFileError` unless the shard ``labels`` (at ``path``) has the layers,
    their bounds and the goal grid of ``first`` (states of one network's input)."""
    layout = (labels.keys, labels.highs.tolist(), labels.n_goals)
    expected = (first.keys, first.highs.tolist(), first.n_goals)
    if layout != expected:
        raise LabelFileError(
            f"{str(path)!r} holds the layers {list(layout[0])} on {layout[2]} goals, the other "
            f"shards {list(expected[0])} on {expected[2]} goals: a shard of another run; delete "
            "it and rerun the same command (its episode is collected again)."
        )


def discounted_returns(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """(n,) float64: the return from each step of an episode of (n,) ``rewards``."""
    out = np.zeros(len(rewards))
    running = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        running = rewards[t] + gamma * running
        out[t] = running
    return out


@dataclass
class States:
    """Labelled states in memory (those with candidates): the quantised ``layers`` (N, C, G)
    uint8, ``state`` (N, 6), ``mask`` (N, G) bool, each state's candidates, target
    probabilities and teacher values (lists of (m,) arrays) and discounted ``returns`` (N,)."""

    keys: tuple[str, ...]
    table: np.ndarray
    layers: np.ndarray
    state: np.ndarray
    mask: np.ndarray
    candidates: list[np.ndarray]
    targets: list[np.ndarray]
    values: list[np.ndarray]
    returns: np.ndarray

    @classmethod
    def load(cls, paths: list[Path], config: TrainConfig, like: Path | None = None) -> States:
        """The states of the shards ``paths`` with their targets under ``config``; each shard
        must have the layout of the shard ``like`` (default: the first of ``paths``)."""
        imitation = config.imitation
        assert imitation is not None
        parts: dict[str, list] = {k: [] for k in ("layers", "state", "mask", "returns")}
        candidates, targets, values = [], [], []
        labels = None
        first = EpisodeLabels.from_file(like) if like is not None else None
        for path in paths:
            labels = EpisodeLabels.from_file(path)
            first = first or labels
            check_same_layout(path, labels, first)
            returns = discounted_returns(config.reward_scale * labels.reward, config.learning.gamma)
            keep = np.diff(labels.offsets) > 0
            for t in np.flatnonzero(keep):
                goals, v = labels.teacher_values(int(t))
                candidates.append(goals.astype(np.int64))
                values.append(v)
                targets.append(teacher_targets(v, imitation.temperature))
            for key, array in (("layers", labels.layers), ("state", labels.state),
                               ("mask", labels.masks()), ("returns", returns)):  # fmt: skip
                parts[key].append(array[keep])
        if labels is None:
            raise ValueError("no label shards")
        layers, state, mask, returns = (np.concatenate(parts[k]) for k in parts)
        return cls(labels.keys, decoding_table(labels.highs), layers, state, mask, candidates,
                   targets, values, returns)  # fmt: skip

    def __len__(self) -> int:
        return len(self.layers)

    def batch(self, index: np.ndarray) -> dict[str, Any]:
        """The tensors of the states ``index``: ``observation`` (key → (B, G) float32 and
        ``state``), ``mask`` (B, G) bool, ``target`` (B, G) float32, ``candidate`` (B, G) bool,
        ``value`` (B, G) float64 (−inf off the candidates), ``best`` (B,) the teacher's best
        goal, ``returns`` (B,)."""
        import torch as th

        n_goals = self.layers.shape[2]
        observation = {k: th.from_numpy(self.table[c][self.layers[index, c]])
                       for c, k in enumerate(self.keys)}  # fmt: skip
        observation[STATE_KEY] = th.from_numpy(self.state[index])
        rows = np.repeat(np.arange(len(index)), [len(self.candidates[i]) for i in index])
        cols = np.concatenate([self.candidates[i] for i in index])
        target = np.zeros((len(index), n_goals), np.float32)
        target[rows, cols] = np.concatenate([self.targets[i] for i in index])
        value = np.full((len(index), n_goals), -np.inf)
        value[rows, cols] = np.concatenate([self.values[i] for i in index])
        best = [self.candidates[i][np.argmax(self.values[i])] for i in index]  # first on a tie
        return {
            "observation": observation,
            "mask": th.from_numpy(self.mask[index]),
            "target": th.from_numpy(target),
            "candidate": th.from_numpy(np.isfinite(value)),
            "value": th.from_numpy(value),
            "best": th.as_tensor(np.array(best, np.int64)),
            "returns": th.as_tensor(self.returns[index], dtype=th.float32),
        }


def policy_outputs(policy, observation) -> tuple[Any, Any]:
    """The (B, G) goal logits and (B,) values of an SB3 actor-critic ``policy``."""
    features = policy.extract_features(observation)
    if policy.share_features_extractor:
        latent_pi, latent_vf = policy.mlp_extractor(features)
    else:
        latent_pi = policy.mlp_extractor.forward_actor(features[0])
        latent_vf = policy.mlp_extractor.forward_critic(features[1])
    return policy.action_net(latent_pi), policy.value_net(latent_vf).flatten()


def losses(policy, batch: dict[str, Any]) -> tuple[Any, Any, Any]:
    """The imitation cross-entropy and the critic's squared error (each a mean over the batch),
    and the masked logits."""
    import torch as th

    logits, values = policy_outputs(policy, batch["observation"])
    masked = logits.masked_fill(~batch["mask"], -th.inf)
    log_p = th.log_softmax(masked, dim=1)
    target = batch["target"]
    cross_entropy = -th.where(target > 0, target * log_p, 0.0).sum(dim=1).mean()
    return cross_entropy, th.mean((values - batch["returns"]) ** 2), masked


def agreement(masked, batch: dict[str, Any]) -> dict[str, Any]:
    """Per state (tensors): whether the policy's most probable goal is the teacher's best
    (``top1``) and among the candidates only (``top1_candidates``), the regret in teacher
    value of its best candidate as a share of the best value, and whether its most probable
    goal is no candidate (``outside``)."""
    import torch as th

    choice = masked.argmax(dim=1)
    among = masked.masked_fill(~batch["candidate"], -th.inf).argmax(dim=1)
    value = batch["value"]
    best = value.max(dim=1).values
    chosen = value.gather(1, among[:, None])[:, 0]
    scale = th.where(best.abs() > 0, best.abs(), th.ones_like(best))
    return {
        "top1": (choice == batch["best"]).double(),
        "top1_candidates": (among == batch["best"]).double(),
        "regret": (best - chosen) / scale,
        "outside": (~batch["candidate"].gather(1, choice[:, None])[:, 0]).double(),
    }


def imitate(
    config: TrainConfig,
    iteration: int,
    train: list[Path],
    validation: list[Path],
    out: Path,
    start: Path | None = None,
    progress: bool = True,
) -> Path:
    """Train the policy of ``config`` on the shards ``train`` for ``imitation.epochs`` epochs
    into the folder ``out`` (from the weights of the model zip ``start``, else new ones), going
    on from ``out``'s checkpoint if there is one; the model zip it saves (``out/model.zip``)."""
    import torch as th

    from nbv_gym.rl.learner import prepare_learner

    imitation = config.imitation
    assert imitation is not None
    out.mkdir(parents=True, exist_ok=True)
    if (out / MODEL).exists():
        return out / MODEL
    prepare_learner(config.torch_threads, 0)
    first = EpisodeLabels.from_file(train[0])
    model = new_model(config, labels_space(first), first.n_goals)
    if start is not None:
        model.set_parameters(str(start), exact_match=True, device=config.device)
    policy = model.policy
    optimizer = th.optim.Adam(policy.parameters(), lr=imitation.learning_rate)
    state = _resume(out, policy, optimizer)
    held_out = States.load(validation, config, like=train[0]) if validation else None
    with progress_bar(imitation.epochs, f"imitation {iteration}", "epoch",
                      initial=state["epoch"], disable=not progress) as bar:  # fmt: skip
        for epoch in range(state["epoch"], imitation.epochs):
            rng = np.random.default_rng([config.seed, iteration, epoch])
            n, loss = _epoch(config, policy, optimizer, train, rng)
            row = {"iteration": iteration, "epoch": epoch + 1, "train_states": n,
                   "train_loss": loss, **evaluate(policy, held_out, imitation.batch_size)}  # fmt: skip
            state = {"epoch": epoch + 1, "rows": [*state["rows"], row]}
            _checkpoint(out, policy, optimizer, state)
            bar.set_postfix_str(f"loss {loss:.3f}, top-1 {row['top1']:.2f}")
            bar.update()
    with atomic(out / MODEL, "wb") as file:
        model.save(file)
    return out / MODEL


def new_model(config: TrainConfig, space: gymnasium.spaces.Dict, n_goals: int):
    """A new model of ``config`` (the one RL would create, same seed) on observations of
    ``space`` and ``n_goals`` goals, without an environment."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    from nbv_gym.rl.train import create_model

    return create_model(config, DummyVecEnv([lambda: _Spaces(space, n_goals)]))


class _Spaces(gymnasium.Env):
    """An environment of given spaces that is never stepped (a model's shapes only)."""

    def __init__(self, space: gymnasium.spaces.Dict, n_goals: int):
        self.observation_space = space
        self.action_space = gymnasium.spaces.Discrete(n_goals)

    def step(self, action):
        raise NotImplementedError("imitation steps no environment")

    def reset(self, *, seed=None, options=None):
        raise NotImplementedError("imitation resets no environment")


def _epoch(config: TrainConfig, policy, optimizer, paths: list[Path], rng) -> tuple[int, float]:
    """One pass over the shards ``paths``; the states seen and their mean loss."""
    import torch as th

    imitation = config.imitation
    assert imitation is not None
    policy.set_training_mode(True)
    total, seen = 0.0, 0
    for states in _buffers(paths, config, rng):
        order = rng.permutation(len(states))
        for start in range(0, len(order), imitation.batch_size):
            batch = states.batch(order[start : start + imitation.batch_size])
            cross_entropy, value_error, _ = losses(policy, batch)
            loss = cross_entropy + imitation.value_coef * value_error
            optimizer.zero_grad()
            loss.backward()
            th.nn.utils.clip_grad_norm_(policy.parameters(), config.learning.max_grad_norm)
            optimizer.step()
            size = len(batch["best"])
            total, seen = total + cross_entropy.item() * size, seen + size
    return seen, total / max(seen, 1)


def _buffers(paths: list[Path], config: TrainConfig, rng) -> Iterator[States]:
    order = [paths[i] for i in rng.permutation(len(paths))]
    for start in range(0, len(order), BUFFER_EPISODES):
        yield States.load(order[start : start + BUFFER_EPISODES], config, like=paths[0])


def evaluate(policy, states: States | None, batch_size: int) -> dict[str, float]:
    """The validation metrics (module docstring) of ``policy`` on ``states`` (NaN without)."""
    import torch as th

    names = ("validation_loss", "top1", "top1_candidates", "regret", "outside")
    if states is None or not len(states):
        return {"validation_states": 0, **dict.fromkeys(names, float("nan"))}
    policy.set_training_mode(False)
    sums = dict.fromkeys(names, 0.0)
    with th.no_grad():
        for start in range(0, len(states), batch_size):
            batch = states.batch(np.arange(start, min(start + batch_size, len(states))))
            cross_entropy, _, masked = losses(policy, batch)
            sums["validation_loss"] += float(cross_entropy) * len(batch["best"])
            for key, values in agreement(masked, batch).items():
                sums[key] += float(values.sum())
    return {"validation_states": len(states), **{k: v / len(states) for k, v in sums.items()}}


def _resume(out: Path, policy, optimizer) -> dict[str, Any]:
    """The training state of ``out``'s checkpoint (weights and optimiser loaded), or a new one."""
    import torch as th

    path = out / CHECKPOINT
    if not path.exists():
        return {"epoch": 0, "rows": []}
    try:
        saved = th.load(path, weights_only=True)
        policy.load_state_dict(saved["policy"])
        optimizer.load_state_dict(saved["optimizer"])
    except Exception as error:  # torch raises many kinds for a damaged or foreign file
        raise LabelFileError(
            f"{str(path)!r} is no imitation checkpoint of this recipe ({type(error).__name__}); "
            "delete it and rerun the same command (the imitation starts again from its first "
            "epoch)."
        ) from None
    return {"epoch": saved["epoch"], "rows": saved["rows"]}


def _checkpoint(out: Path, policy, optimizer, state: dict[str, Any]) -> None:
    """Write the checkpoint and the metrics table of the epochs so far, each atomically."""
    import torch as th

    buffer = io.BytesIO()
    th.save({**state, "policy": policy.state_dict(), "optimizer": optimizer.state_dict()}, buffer)
    with atomic(out / CHECKPOINT, "wb") as file:
        file.write(buffer.getvalue())
    with atomic(out / METRICS, "w") as file:
        writer = csv.DictWriter(file, METRIC_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(state["rows"])
