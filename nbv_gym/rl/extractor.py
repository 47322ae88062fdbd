"""Networks for the ``Explore-v0`` observation: a small CNN over the 2D layers plus the robot state.

:class:`MapExtractor` stacks the flat (3600,) layers of the observation into a (C, 60, 60) image
(``layer.reshape(60, 60)`` is the picture, goal ``g = i · 60 + j``), runs a small CNN and an MLP
on ``state``, and concatenates. With ``goal_scores=True`` it also returns one score per goal from
a fully convolutional head (local features modulated by the global ones, plus a linear
read-out of the layers themselves, which lets a policy learn "near frontier" early); the goal-map
policies below use those scores directly as the action logits, so the policy's output lives on
the same grid as its input, and their critic reads the global features only.

The network is lean on purpose (≈ 0.1 M parameters, ≈ 4 M multiply-adds per observation): the
full-resolution part is two 3 × 3 convolutions with 8 channels, on a channels-last image (oneDNN's
fast layout on CPU), so a PPO update costs no more than the environment steps it learns from.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from functools import partial
from typing import Any, Protocol, cast

import numpy as np
import torch as th
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableMultiInputActorCriticPolicy
from stable_baselines3.common.policies import MultiInputActorCriticPolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from nbv_gym.core import libm
from nbv_gym.rl.config import STATE_FEATURES

STATE_KEY = "state"
#: Channels of the full-resolution features (the goal scores' input).
LOCAL_CHANNELS = 8
#: Channels of the coarse (s/4, s/8) map features.
GLOBAL_CHANNELS = 16


class MapExtractor(BaseFeaturesExtractor):
    """Features of a Dict observation of flat square layers and a ``state`` vector.

    Output: (batch, n_goals + features_dim) float with ``goal_scores`` (the goal scores first),
    else (batch, features_dim). Layers whose upper bound exceeds 1 (the NBV gain layers) enter as
    ``log1p(x) / log1p(high)``.
    """

    log_high: th.Tensor  # a registered buffer: (C,) float32 log1p(upper bound) or 0

    def __init__(
        self, observation_space: spaces.Dict, features_dim: int = 128, goal_scores: bool = True
    ):
        self.layer_keys = map_layer_keys(observation_space)
        n_goals = _length(observation_space[self.layer_keys[0]])
        super().__init__(observation_space, features_dim + (n_goals if goal_scores else 0))
        self.side = math.isqrt(n_goals)
        self.goal_scores = goal_scores
        self.global_dim = features_dim
        self.register_buffer("log_high", _log_highs(observation_space, self.layer_keys))
        self.log_scaled = bool(self.log_high.any())
        self.local = _local_cnn(len(self.layer_keys))
        self.map_features = _global_cnn(self.side, features_dim - STATE_FEATURES)
        state_size = _length(observation_space[STATE_KEY])
        self.state_features = nn.Sequential(nn.Linear(state_size, STATE_FEATURES), nn.ReLU())
        if goal_scores:
            self.modulation = nn.Linear(features_dim, LOCAL_CHANNELS)
            self.score = nn.Conv2d(LOCAL_CHANNELS, 1, kernel_size=1)
            self.skip = nn.Conv2d(len(self.layer_keys), 1, kernel_size=1)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        """(batch, n_goals + features_dim) goal scores and features, or (batch, features_dim)
        features without goal scores."""
        image = self._image(observations)
        local = self.local(image)
        features = th.cat(
            [self.map_features(local), self.state_features(observations[STATE_KEY])], dim=1
        )
        if not self.goal_scores:
            return features
        modulated = th.relu(local + self.modulation(features)[:, :, None, None])
        scores = self.score(modulated) + self.skip(image)
        return th.cat([scores.flatten(1), features], dim=1)

    def _image(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        """(batch, C, side, side) float in channels-last memory: the layers, the unbounded ones
        log-scaled."""
        layers = th.stack([observations[k] for k in self.layer_keys], dim=1)  # (B, C, n_goals)
        if self.log_scaled:
            high = self.log_high[:, None]
            layers = th.where(high > 0, th.log1p(layers.clamp(min=0)) / high, layers)
        image = layers.reshape(len(layers), -1, self.side, self.side)
        return image.contiguous(memory_format=th.channels_last)


def map_layer_keys(observation_space: spaces.Dict) -> list[str]:
    """The keys of the 2D layers (every entry but ``state``), in the space's order."""
    keys = [k for k in observation_space.spaces if k != STATE_KEY]
    shapes = {tuple(observation_space[k].shape or ()) for k in keys}
    if len(shapes) != 1 or len(next(iter(shapes))) != 1:
        raise ValueError(f"expected flat layers of one size, got shapes {sorted(shapes)}")
    if math.isqrt(next(iter(shapes))[0]) ** 2 != next(iter(shapes))[0]:
        raise ValueError(f"expected square layers (n = side²), got {next(iter(shapes))[0]}")
    return keys


def _length(space: spaces.Space) -> int:
    """The length of a flat (n,) space; ValueError for any other."""
    if space.shape is None or len(space.shape) != 1:
        raise ValueError(f"expected a flat (n,) space, got shape {space.shape}")
    return space.shape[0]


def _log_highs(observation_space: spaces.Dict, keys: list[str]) -> th.Tensor:
    """Per layer: log1p(upper bound) where the bound exceeds 1, else 0 (the layer is in [0, 1])."""
    highs = np.array([float(np.max(cast(spaces.Box, observation_space[k]).high)) for k in keys])
    return th.as_tensor(np.where(highs > 1, libm.log1p(highs), 0.0), dtype=th.float32)


def _local_cnn(channels: int) -> nn.Module:
    """Full-resolution features: (B, C, s, s) → (B, 8, s, s), a 5 × 5 cell receptive field."""
    return nn.Sequential(
        nn.Conv2d(channels, LOCAL_CHANNELS, kernel_size=3, padding=1),
        nn.ReLU(),
        nn.Conv2d(LOCAL_CHANNELS, LOCAL_CHANNELS, kernel_size=3, padding=1),
        nn.ReLU(),
    )


def _global_cnn(side: int, out: int) -> nn.Module:
    """Coarse map features: (B, 8, s, s) → (B, out), via s/4 and s/8 resolutions."""
    coarse = math.ceil(side / 4)
    coarser = math.ceil(coarse / 2)
    return nn.Sequential(
        nn.Conv2d(
            LOCAL_CHANNELS,
            GLOBAL_CHANNELS,
            kernel_size=4,
            stride=4,
            padding=(4 * coarse - side) // 2,
        ),
        nn.ReLU(),
        nn.Conv2d(GLOBAL_CHANNELS, GLOBAL_CHANNELS, kernel_size=3, stride=2, padding=1),
        nn.ReLU(),
        nn.Flatten(),
        nn.Linear(GLOBAL_CHANNELS * coarser * coarser, out),
        nn.ReLU(),
    )


class GoalLogits(nn.Module):
    """The action head of the goal-map policies: the first ``n_goals`` latent entries (the
    extractor's goal scores) are the logits; an action space with ``n_actions`` > ``n_goals``
    (the team task's "carry on", :mod:`nbv_gym.rl.teamvec`) gets logits 0 for the extra
    actions, which only a mask allowing nothing else lets a robot take."""

    def __init__(self, n_goals: int, n_actions: int | None = None):
        super().__init__()
        self.n_goals = n_goals
        self.n_extra = (n_actions or n_goals) - n_goals

    def forward(self, latent: th.Tensor) -> th.Tensor:
        """(batch, n_actions) logits: the latent's first ``n_goals`` entries, then zeros."""
        logits = latent[:, : self.n_goals]
        if not self.n_extra:
            return logits
        return th.cat([logits, logits.new_zeros(len(logits), self.n_extra)], dim=1)


class GoalMapHeads(nn.Module):
    """The goal-map policies' ``mlp_extractor``: the actor's latent is the extractor's output
    unchanged (goal scores first, read by :class:`GoalLogits`); the critic is an MLP on the
    global features alone (the 3600 goal scores are no value feature).

    ``features_dim``: the extractor's global feature size; ``value_layers``: hidden sizes.
    """

    def __init__(self, n_goals: int, features_dim: int, value_layers: list[int]):
        super().__init__()
        self.n_goals = n_goals
        layers: list[nn.Module] = []
        size = features_dim
        for width in value_layers:
            layers += [nn.Linear(size, width), nn.ReLU()]
            size = width
        self.value_net = nn.Sequential(*layers)
        self.latent_dim_pi = n_goals + features_dim
        self.latent_dim_vf = size

    def forward(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """The actor's and the critic's latents of (batch, n_goals + features_dim) ``features``."""
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features: th.Tensor) -> th.Tensor:
        """The actor's latent: ``features`` unchanged (the goal scores first)."""
        return features

    def forward_critic(self, features: th.Tensor) -> th.Tensor:
        """The critic's (batch, latent_dim_vf) latent, from the global features alone."""
        return self.value_net(features[:, self.n_goals :])


class _ActorCritic(Protocol):
    """The parts of SB3's actor-critic policies (``ActorCriticPolicy`` and sb3-contrib's
    ``MaskableActorCriticPolicy``, which share them but no base class) that
    :class:`_GoalMapMixin` reads and replaces."""

    action_space: Any
    net_arch: Any
    ortho_init: bool
    share_features_extractor: bool
    features_extractor: Any
    pi_features_extractor: Any
    vf_features_extractor: Any
    mlp_extractor: Any
    action_net: Any
    value_net: Any
    optimizer: Any
    optimizer_class: Any
    optimizer_kwargs: dict[str, Any]

    def init_weights(self, module: nn.Module, gain: float = 1) -> None: ...

    def parameters(self, recurse: bool = True) -> Iterator[nn.Parameter]: ...

    def _build_mlp_extractor(self) -> None: ...


class _GoalMapMixin:
    """Builds the goal-map heads instead of SB3's dense ones: :class:`GoalMapHeads` and
    :class:`GoalLogits` (``net_arch``: ``{"pi": [], "vf": [hidden sizes]}``), with SB3's
    orthogonal initialisation (small initial goal scores, as SB3 does for its action head)."""

    # SB3 types them MlpExtractor and nn.Module; the goal-map heads take their place
    mlp_extractor: Any
    action_net: Any

    def _build_mlp_extractor(self: _ActorCritic) -> None:
        extractor = self.features_extractor
        self.mlp_extractor = GoalMapHeads(
            extractor.side**2, extractor.global_dim, list(self.net_arch["vf"])
        )

    def _build(self: _ActorCritic, lr_schedule: Callable[[float], float]) -> None:
        self._build_mlp_extractor()
        self.action_net = GoalLogits(self.features_extractor.side**2, int(self.action_space.n))
        self.value_net = nn.Linear(self.mlp_extractor.latent_dim_vf, 1)
        if self.ortho_init:
            extractors = (
                [self.features_extractor]
                if self.share_features_extractor
                else [self.pi_features_extractor, self.vf_features_extractor]
            )
            gains = [(m, np.sqrt(2)) for m in (*extractors, self.mlp_extractor)]
            for module, gain in [*gains, (self.value_net, 1.0)]:
                module.apply(partial(self.init_weights, gain=gain))
            for extractor in extractors:
                extractor.score.apply(partial(self.init_weights, gain=0.01))
        self.optimizer = self.optimizer_class(
            self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs
        )


class MaskableGoalMapPolicy(_GoalMapMixin, MaskableMultiInputActorCriticPolicy):
    """MaskablePPO policy whose logits are the per-goal scores of :class:`MapExtractor`."""


class GoalMapPolicy(_GoalMapMixin, MultiInputActorCriticPolicy):
    """PPO/A2C policy whose logits are the per-goal scores of :class:`MapExtractor`."""
