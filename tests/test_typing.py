"""The type-check ratchet: mypy's excuses for the package may only shrink.

``pyproject.toml`` has mypy check the bodies of unannotated functions too
(``check_untyped_defs``), and may excuse a module of ``nbv_gym`` from mypy (an override with
``disable_error_code`` or ``ignore_errors``) only as far as :data:`EXCUSED` lists, and no file may
silence mypy with a ``# type: ignore`` comment beyond :data:`IGNORE_COMMENTS`. Both lists are
empty: fix the types. Removing an excuse needs no change here; adding one fails until it is
written below, where a reviewer sees it.
"""

from __future__ import annotations

import io
import tokenize
import tomllib
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Module (or ``nbv_gym.*`` pattern) → the mypy error codes it may disable; "*" for
#: ``ignore_errors``. Each entry needs a comment saying why the module cannot be typed.
EXCUSED: dict[str, frozenset[str]] = {}
#: Package file (relative to the repository) → the number of ``# type: ignore`` comments it may hold.
IGNORE_COMMENTS: dict[str, int] = {}
#: Settings of ``[tool.mypy]`` that would hide errors in the whole package.
LOOSENING = (
    "disable_error_code",
    "ignore_errors",
    "follow_imports",
    "exclude",
    "ignore_missing_imports",
)


def mypy_config() -> dict[str, Any]:
    """The ``[tool.mypy]`` table of the repository's ``pyproject.toml``."""
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["mypy"]


def excuses(config: dict[str, Any]) -> dict[str, set[str]]:
    """Package module pattern → the error codes ``config``'s overrides disable for it ("*" for
    ``ignore_errors``)."""
    found: dict[str, set[str]] = {}
    for override in config.get("overrides", []):
        modules = override["module"]
        for module in [modules] if isinstance(modules, str) else modules:
            if module.split(".")[0] not in ("nbv_gym", "*"):
                continue  # a third-party library without type hints
            codes = set(override.get("disable_error_code", []))
            codes |= {"*"} if override.get("ignore_errors") else set()
            if codes:
                found.setdefault(module, set()).update(codes)
    return found


def grown(config: dict[str, Any]) -> list[str]:
    """The excuses of ``config`` that :data:`EXCUSED` does not list, as ``module: code``."""
    allowed = {module: set(codes) for module, codes in EXCUSED.items()}
    return sorted(
        f"{module}: {code}"
        for module, codes in excuses(config).items()
        for code in codes - allowed.get(module, set())
    )


def ignore_comments(source: str) -> int:
    """The number of ``# type: ignore`` comments in Python ``source``."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    return sum(
        t.type == tokenize.COMMENT and t.string.lstrip("# ").startswith("type: ignore")
        for t in tokens
    )


def test_no_module_gains_an_excuse():
    assert grown(mypy_config()) == [], "fix the types instead of excusing them"


def test_the_whole_package_is_checked():
    config = mypy_config()
    assert config["files"] == ["nbv_gym"]
    assert [key for key in LOOSENING if key in config] == []


def test_the_bodies_of_unannotated_functions_are_checked():
    assert mypy_config().get("check_untyped_defs") is True


def test_no_new_type_ignore_comments():
    counts = {}
    for path in sorted((ROOT / "nbv_gym").rglob("*.py")):
        name = str(path.relative_to(ROOT))
        counts[name] = ignore_comments(path.read_text())
    over = {n: c for n, c in counts.items() if c > IGNORE_COMMENTS.get(n, 0)}
    assert over == {}, "fix the types instead of ignoring them"


@pytest.mark.parametrize(
    "override, expected",
    [
        (
            {"module": "nbv_gym.simulator", "disable_error_code": ["arg-type"]},
            ["nbv_gym.simulator: arg-type"],
        ),
        ({"module": ["nbv_gym.rl.*"], "ignore_errors": True}, ["nbv_gym.rl.*: *"]),
        ({"module": "*", "disable_error_code": ["misc"]}, ["*: misc"]),
        ({"module": ["numba.*"], "ignore_missing_imports": True}, []),
    ],
    ids=["disabled-code", "ignore-errors", "every-module", "third-party"],
)
def test_a_planted_excuse_is_caught(override, expected):
    config = {**mypy_config()}
    config["overrides"] = [*config.get("overrides", []), override]
    assert grown(config) == expected


def test_a_planted_ignore_comment_is_counted():
    source = 'x = f()  # type: ignore[arg-type]\ny = "# type: ignore"  # a string, not a comment\n'
    assert ignore_comments(source) == 1
