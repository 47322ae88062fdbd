"""A trained stable-baselines3 model as a policy: ``load_policy("sb3:runs/ppo/best_model.zip")``.

:class:`SB3Policy` declares the optional observation layers the model was trained with (read
from the saved observation space), so ``make_env`` computes them, and refuses models whose action
space or observation layers do not fit ``Explore-v0``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from nbv_gym.env.layers import OPTIONAL_LAYERS
from nbv_gym.env.observation import BASE_LAYERS, STATE_SIZE
from nbv_gym.mapping.statistics import StatisticsConfig
from nbv_gym.policies import PolicyError
from nbv_gym.rl.modelfile import check_model_file, model_file

#: The goals (actions) of the default grid G: its x, y cells (60 × 60).
N_GOALS = math.prod(StatisticsConfig().grid().shape[:2])
STATE_KEY = "state"


class SB3Policy:
    """A saved SB3 model (MaskablePPO, PPO or A2C) acting deterministically; ``path`` is its
    zip, or a folder holding one zip (``nbv-gym package-model``'s).

    MaskablePPO acts among ``info["action_mask"]``; the other algorithms' goal is replaced by the
    nearest valid goal when invalid, as during their training (``invalid_action="snap"``).
    """

    def __init__(self, path: str | Path, device: str = "cpu"):
        from nbv_gym.rl.config import require_rl

        require_rl()
        self.path = model_file(Path(path))
        self.model = load_model(self.path, device)
        self.observation_layers = check_spaces(self.model, self.path)
        self.masked = type(self.model).__name__ == "MaskablePPO"

    def reset(self, seed: int | None = None) -> None:
        """Nothing to reset: the policy is deterministic."""

    def act(self, observation: Mapping[str, np.ndarray], info: Mapping[str, Any]) -> int:
        """The model's most probable valid goal for ``observation``."""
        from nbv_gym.env.actions import nearest_valid_goal

        mask = np.asarray(info["action_mask"], bool)
        if mask.size != self.model.action_space.n:
            raise PolicyError(
                f"{str(self.path)!r} chooses among {self.model.action_space.n} goals; this world "
                f"has {mask.size} (its window is not the one the model was trained on). Train a "
                "model on worlds of this window, or explore a world of the model's window."
            )
        missing = [k for k in self.model.observation_space.spaces if k not in observation]
        if missing:
            raise PolicyError(
                f"{str(self.path)!r} needs the observation layers {missing}, which the "
                "environment does not give; build it with nbv_gym.episode.make_env."
            )
        obs = {k: np.asarray(observation[k]) for k in self.model.observation_space.spaces}
        if self.masked:
            action, _ = self.model.predict(obs, action_masks=mask, deterministic=True)
            return int(action)
        action, _ = self.model.predict(obs, deterministic=True)
        return nearest_valid_goal(int(action), mask)


def load_model(path: Path, device: str = "cpu"):
    """The SB3 model saved at ``path``, loaded once its data JSON declares a supported algorithm
    and Explore-v0's spaces (:func:`~nbv_gym.rl.modelfile.describe_model`). Loading unpickles
    the file: a model is code, load only models you trust."""
    from nbv_gym.rl.config import algorithm_class
    from nbv_gym.rl.modelfile import describe_model

    check_model_file(path)
    description = describe_model(path)
    check_spaces(description, path)
    try:
        return algorithm_class(description.algorithm).load(path, device=device)
    except (KeyboardInterrupt, SystemExit, MemoryError):
        raise
    except Exception as error:  # a broken file past the JSON check: torch, pickle or zip errors
        message = " ".join(str(error).split())[:200] or type(error).__name__
        raise PolicyError(
            f"{str(path)!r} is not a loadable model: its data JSON is an SB3 model's, but "
            f"stable-baselines3 could not load the rest ({type(error).__name__}: {message}). "
            "The file is damaged or was not written by SB3; train or download it again."
        ) from None


def check_spaces(model, path: Path) -> tuple[str, ...]:
    """The optional layers ``model`` observes; :class:`PolicyError` if its action space is not
    ``Discrete(3600)`` or its observation is not ``Explore-v0``'s for some set of layers."""
    from gymnasium import spaces

    action_space = model.action_space
    if not isinstance(action_space, spaces.Discrete) or int(action_space.n) != N_GOALS:
        raise PolicyError(
            f"{str(path)!r} was trained for the action space {action_space}; Explore-v0 needs "
            f"Discrete({N_GOALS}) (one action per goal). Retrain it with nbv-gym train."
        )
    space = model.observation_space
    if not isinstance(space, spaces.Dict):
        raise PolicyError(
            f"{str(path)!r} observes {space}; Explore-v0 gives a Dict of layers and 'state'."
        )
    return _check_keys(space, path)


def _check_keys(space, path: Path) -> tuple[str, ...]:
    keys = set(space.spaces)
    missing = [k for k in (*BASE_LAYERS, STATE_KEY) if k not in keys]
    unknown = sorted(keys - {*BASE_LAYERS, STATE_KEY, *OPTIONAL_LAYERS})
    if missing or unknown:
        raise PolicyError(
            f"{str(path)!r} was trained on other observation layers than Explore-v0 gives: "
            f"missing {missing}, unknown {unknown}. Expected the base layers "
            f"{list(BASE_LAYERS)}, 'state' and optional layers from {list(OPTIONAL_LAYERS)}."
        )
    wrong = {
        k: s.shape
        for k, s in space.spaces.items()
        if s.shape != ((STATE_SIZE,) if k == STATE_KEY else (N_GOALS,))
    }
    if wrong:
        raise PolicyError(
            f"{str(path)!r} expects other observation shapes than Explore-v0 gives: {wrong}; "
            f"layers are ({N_GOALS},) and 'state' ({STATE_SIZE},)."
        )
    return tuple(k for k in OPTIONAL_LAYERS if k in keys)
