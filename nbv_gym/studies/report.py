"""Verdict tables and figures for the study reports (Markdown + PNG)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from nbv_gym.reporting.formatting import markdown_table
from nbv_gym.reporting.verdicts import VERDICTS
from nbv_gym.studies import StudyError


@dataclass(frozen=True)
class Verdict:
    """One row of a verdict table: a claim of a paper, where and what the paper reports, what we
    measured, and the verdict (one of :data:`VERDICTS`)."""

    claim: str
    paper: str
    ours: str
    verdict: str

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise StudyError(f"verdict must be one of {VERDICTS}, got {self.verdict!r}")


def verdict_table(verdicts: Iterable[Verdict]) -> str:
    """The Markdown verdict table: claim | paper | ours | verdict."""
    rows = [[v.claim, v.paper, v.ours, f"**{v.verdict}**"] for v in verdicts]
    return markdown_table(["claim", "paper", "ours", "verdict"], rows)


def write_report(path: Path, title: str, sections: Sequence[str]) -> Path:
    """Write ``# title`` and the Markdown ``sections`` (separated by blank lines) to ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        f"# {title}\n\n" + "\n\n".join(s.strip() for s in sections) + "\n", encoding="utf-8"
    )
    return path


def figure(width_in: float, height_in: float):
    """A matplotlib Figure drawn off-screen (no pyplot state, any backend)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), layout="constrained")


def fmt(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` significant digits, or "—" when it is not finite."""
    return f"{value:.{digits}g}" if value == value and abs(value) != float("inf") else "—"
