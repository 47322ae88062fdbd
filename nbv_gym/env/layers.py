"""Optional observation layers: computed only when a policy or user asks for them."""

from __future__ import annotations

import numpy as np

from nbv_gym.simulator import Simulator, StepOutcome

#: Names of the optional layers and what they hold.
OPTIONAL_LAYERS: dict[str, str] = {}


class OptionalLayers:
    """Computes the requested optional layers after each scan."""

    def __init__(self, sim: Simulator, names: tuple[str, ...]):
        self.sim = sim
        self.names = tuple(dict.fromkeys(names))

    def reset(self) -> None:
        """Forget per-episode state."""

    def compute(self, outcome: StepOutcome | None) -> dict[str, np.ndarray]:
        """The requested layers for the simulator's current state."""
        return {}
