"""Formatting shared by the report's sections (tables, figures, the order and colours of assets
and policies), in a module of its own so that the sections import it, not the report."""

from __future__ import annotations

import math
import numbers
import re
from collections.abc import Callable
from typing import Any

from nbv_gym.policies import PAPER_POLICIES

#: What follows an oracle policy's name (``privileged = True``) in every table and legend.
ORACLE_MARK = " (oracle)"
#: The first cell of the row that separates oracles from the other policies in a table.
ORACLE_RULE = "*oracles: read privileged values, ranked apart*"


def markdown_table(header: list[str], rows: list[list[Any]]) -> str:
    """A GitHub-flavoured Markdown table; a ``|`` in a cell (a policy's name or a note) is
    escaped, as GFM and markdown-it read it (in code spans too), so that it splits no cell."""
    lines = ["| " + " | ".join(_cell(h) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def _cell(value: Any) -> str:
    """A table cell's text: ``|`` escaped, line breaks as spaces (a cell is one line)."""
    return str(value).replace("|", "\\|").replace("\n", " ")


#: What a table shows for an undefined number (None, NaN or ±inf).
UNDEFINED = "—"


def undefined(value: Any) -> bool:
    """Whether ``value`` is an undefined number: None (JSON's null), NaN or ±inf."""
    return value is None or (isinstance(value, numbers.Real) and not math.isfinite(value))


def number_text(value: Any, spec: str = ".4f", width: int = 0) -> str:
    """``value`` in the format ``spec`` (``".4f"``, ``".1%"``, ``".6g"``, …), right-aligned to
    ``width`` characters, or :data:`UNDEFINED` when it is undefined (:func:`undefined`): the
    one way a figure is written in the tables, summaries and terminal lines."""
    return format(UNDEFINED if undefined(value) else format(value, spec), f">{width}")


def estimate_text(value: Any, low: Any, high: Any, spec: str = ".4f") -> str:
    """``value [low, high]`` in the format ``spec`` (:func:`number_text`), or :data:`UNDEFINED`
    when ``value`` is undefined."""
    if undefined(value):
        return UNDEFINED
    return f"{number_text(value, spec)} [{number_text(low, spec)}, {number_text(high, spec)}]"


def markdown_code(text: object) -> str:
    """``text`` as a Markdown code span that stays one table cell on one line whatever it holds
    (a name from a file is data): control characters written as escapes (``\\n``), ``|``
    escaped for tables, and a backtick fence longer than any run of backticks inside."""
    shown = printable(text).replace("|", "\\|")
    longest = max((len(run) for run in re.findall("`+", shown)), default=0)
    fence = "`" * (longest + 1)
    pad = " " if shown.startswith("`") or shown.endswith("`") or not shown.strip() else ""
    return f"{fence}{pad}{shown}{pad}{fence}"


def markdown_text(text: object) -> str:
    """``text`` as plain Markdown on one line: control characters as escapes, and the
    characters Markdown reads as inline syntax (``|``, ``*``, ``_``, ``[``, ``!``, …) escaped."""
    return re.sub(r"([\\`*_\[\]!|<>])", r"\\\1", printable(text))


def printable(text: object) -> str:
    """``text`` on one line: each control or other non-printable character written as its
    escape (a newline as ``\\n``), as a name from a file is shown in tables and legends."""
    return "".join(
        ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii") for ch in str(text)
    )


def oracle_label(policy: str) -> str:
    """``policy`` marked as an oracle."""
    return policy + ORACLE_MARK


def is_oracle_label(label: str) -> bool:
    """Whether a policy label (or a row label such as ``A − B``) names an oracle."""
    return ORACLE_MARK in str(label)


def ranked_apart(
    rows: list[list[Any]], is_oracle_row: Callable[[list[Any]], bool] | None = None
) -> list[list[Any]]:
    """``rows`` of a table with the oracles' rows (by default: whose first cell names an oracle)
    after the others, below a rule row (:data:`ORACLE_RULE`); unchanged without oracles."""
    is_oracle_row = is_oracle_row or (lambda row: is_oracle_label(row[0]))
    oracles = [row for row in rows if is_oracle_row(row)]
    if not oracles:
        return rows
    others = [row for row in rows if not is_oracle_row(row)]
    return [*others, [ORACLE_RULE, *[""] * (len(rows[0]) - 1)], *oracles]


def policy_style(policy: str) -> str:
    """The line style of a policy in the figures: dotted for oracles, solid for the ``nbv-*``
    policies, dashed for the others."""
    if is_oracle_label(policy):
        return ":"
    return "-" if policy.startswith("nbv-") else "--"


def asset_order(assets) -> list[str]:
    """Asset types present, easiest first (cuboids, crosses, helicoids, trees), then others."""
    from nbv_gym.worlds import ASSET_TYPES

    present = list(dict.fromkeys(str(a) for a in assets))
    return [a for a in ASSET_TYPES if a in present] + sorted(
        a for a in present if a not in ASSET_TYPES
    )


#: Fifteen colours that stay apart on white, for the fourteen shipped policies and one of yours:
#: matplotlib's tab10, then black, a dark gold, maroon, navy and magenta (a dark teal read as
#: tab10's blue in thin lines).
PALETTE = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#000000", "#f5c200", "#800000", "#000080", "#ff00ff",
)  # fmt: skip


def policy_colours(policies: list[str]) -> dict[str, Any]:
    """A colour per policy label: the labels drawn take :data:`PALETTE`'s colours in turn, the
    shipped policies first in a fixed order (the paper's seven, the references, the trained
    models, the teachers), then the others in the order given — so up to fifteen labels (every shipped
    policy and one of yours) never share a colour, and a shipped policy keeps its colour from
    figure to figure of the same set."""
    from nbv_gym.policies import MODELS, REFERENCE_POLICIES, TEACHER_POLICIES

    shipped = [*PAPER_POLICIES, *REFERENCE_POLICIES, *MODELS, *TEACHER_POLICIES]

    def rank(label: str) -> tuple[int, int]:
        base = str(label).replace(ORACLE_MARK, "")
        return (
            (shipped.index(base), 0) if base in shipped else (len(shipped), policies.index(label))
        )

    ordered = sorted(dict.fromkeys(policies), key=rank)
    return {p: PALETTE[i % len(PALETTE)] for i, p in enumerate(ordered)}


def figure(width_in: float, height_in: float):
    """A matplotlib Figure drawn off-screen (no pyplot state, any backend)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in))
