"""Typed command-line numbers: each option declares its domain once (``parser=COUNT``), and a
value outside it (a negative count, ``inf`` or ``nan`` where a finite length is needed) is
refused before any work starts, with a message that names the option and the domain."""

from __future__ import annotations

import math
from collections.abc import Callable

from nbv_gym.core.protocol import NOISE_LEVELS


def number(kind: type, low: float | None = None, high: float | None = None, above: bool = False):
    """A parser of ``kind`` (``int`` or ``float``) values: finite, ≥ ``low`` (> ``low`` when
    ``above``) and ≤ ``high``; a bad value raises :class:`ValueError` saying why (the CLI reports it as a bad option)."""
    what = "an integer" if kind is int else "a finite number"
    show = "{:,}".format if kind is int else "{:g}".format
    bounds = [f"{'>' if above else '≥'} {show(low)}" if low is not None else "",
              f"≤ {show(high)}" if high is not None else ""]  # fmt: skip
    domain = " and ".join(b for b in bounds if b)

    def parse(text: str | float) -> float:
        try:
            value = kind(text)
        except (TypeError, ValueError):
            raise ValueError(f"expected {what}, got {text!r}") from None
        too_low = low is not None and (value <= low if above else value < low)
        if not math.isfinite(value) or too_low or (high is not None and value > high):
            raise ValueError(f"expected {what}{' ' + domain if domain else ''}, got {text}")
        return value

    parse.__name__ = kind.__name__  # Click shows it as the metavar's type
    return parse


#: A seed or a count that may be zero.
COUNT: Callable = number(int, 0)
#: A count of at least one (steps, episodes, points, workers).
POSITIVE_COUNT: Callable = number(int, 1)
#: Points sampled on a world's surfaces (memory grows with them: about 1 GB per 10 million).
SAMPLE_POINTS: Callable = number(int, 1, 20_000_000)
#: A localisation-noise level.
NOISE_LEVEL: Callable = number(int, min(NOISE_LEVELS), max(NOISE_LEVELS))
#: The help text of a noise-level option.
NOISE_HELP = f"Localisation-noise level: {', '.join(map(str, NOISE_LEVELS))}."
#: Any finite real number (a height, metres).
FINITE: Callable = number(float)
#: A length or duration > 0 (metres, minutes).
POSITIVE: Callable = number(float, 0, above=True)
#: A probability.
PROBABILITY: Callable = number(float, 0, 1)

#: The Empir3D cell size ε and region size r of ``evaluate`` and ``study empir3d`` (r ≥ ε is
#: checked by the metric's config).
