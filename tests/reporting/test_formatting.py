"""Markdown tables: a ``|`` inside a cell stays inside it when the table is rendered."""

from __future__ import annotations

import re

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
