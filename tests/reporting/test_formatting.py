"""Markdown tables: a ``|`` inside a cell stays inside it when the table is rendered."""

from __future__ import annotations

import re

import numpy as np
from markdown_it import MarkdownIt

from nbv_gym.reporting.formatting import markdown_table


def cells(html: str) -> list[list[str]]:
    rows = re.findall(r"<tr>(.*?)</tr>", html, re.S)
    return [re.findall(r"<t[hd]>(.*?)</t[hd]>", row, re.S) for row in rows]


def test_a_pipe_in_a_cell_splits_no_cell_in_plain_text_or_code():
    """Rendered as the HTML report renders Markdown (markdown-it, tables on): three columns in
    every row, and the pipes shown as written."""
    table = markdown_table(
        ["policy", "note", "|ΔQ|"],
        [["`my_policy:A|B`", "left | right", 0.5], ["plain", "multi\nline", 1]],
    )
    html = MarkdownIt("commonmark", {"html": False}).enable("table").render(table)
    assert cells(html) == [
        ["policy", "note", "|ΔQ|"],
        ["<code>my_policy:A|B</code>", "left | right", "0.5"],
        ["plain", "multi line", "1"],
    ]


def test_every_shipped_policy_and_one_of_yours_get_their_own_colours_in_a_fixed_order():
    from matplotlib.colors import to_rgb

    from nbv_gym.policies import MODELS, PAPER_POLICIES, REFERENCE_POLICIES, TEACHER_POLICIES
    from nbv_gym.reporting.formatting import oracle_label, policy_colours

    shipped = [*PAPER_POLICIES, *REFERENCE_POLICIES, *MODELS, *TEACHER_POLICIES]
    oracle = shipped.index("oracle-greedy")
    labels = [*reversed(shipped[:oracle]), oracle_label(shipped[oracle]), *shipped[oracle + 1 :]]
    colours = policy_colours([*labels, "mine:A"])
    assert len(colours) == len(shipped) + 1 == len(set(colours.values()))
    rgb = [np.array(to_rgb(c)) for c in colours.values()]
    assert min(np.abs(a - b).sum() for i, a in enumerate(rgb) for b in rgb[i + 1 :]) > 0.3
    assert (
        colours[PAPER_POLICIES[0]]
        == policy_colours([PAPER_POLICIES[0], "mine:A"])[PAPER_POLICIES[0]]
    )
    assert policy_colours(["mine:B", "mine:A"]) == {"mine:B": "#1f77b4", "mine:A": "#ff7f0e"}
