"""Every text file the package reads or writes is UTF-8, whatever the locale: under ``LC_ALL=C``
(Python's ASCII locale encoding) ``leaderboard --references`` was a UnicodeDecodeError reading
the scorecard schema (probe N05). The package's text ``open``, ``read_text`` and ``write_text``
calls each name their encoding."""

from __future__ import annotations

import ast
from pathlib import Path

import nbv_gym

#: Receivers whose ``open`` is not the built-in's or a path's (archives, images, point clouds).
OTHER_OPENS = {"laspy", "Image", "archive", "os", "zipfile", "tarfile", "gzip", "np", "io"}


def _binary(call: ast.Call) -> bool:
    modes = [a.value for a in call.args if isinstance(a, ast.Constant)]
    modes += [k.value.value for k in call.keywords
              if k.arg == "mode" and isinstance(k.value, ast.Constant)]  # fmt: skip
    return any(isinstance(m, str) and "b" in m for m in modes)


def _unnamed_encodings(path: Path) -> list[str]:
    source = path.read_text(encoding="utf-8")
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if isinstance(func, ast.Attribute):
            if func.attr not in ("open", "read_text", "write_text"):
                continue
            if isinstance(func.value, ast.Name) and func.value.id in OTHER_OPENS:
                continue
        elif not (isinstance(func, ast.Name) and func.id == "open"):
            continue
        if _binary(node) or any(k.arg == "encoding" for k in node.keywords):
            continue
        found.append(f"{path.name}:{node.lineno}: {ast.get_source_segment(source, node)}")
    return found


def test_every_text_file_the_package_opens_names_its_encoding():
    package = Path(nbv_gym.__file__).parent
    found = [line for path in sorted(package.rglob("*.py")) for line in _unnamed_encodings(path)]
    assert not found, "\n".join(found)
