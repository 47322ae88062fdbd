"""The documentation's shell examples name things that exist, and its install facts match pyproject.

Every command line of a ``bash`` block in README.md, CONTRIBUTING.md and docs/*.md (and the
README's indented ``nbv-gym`` lines) is read as a user would type it: an ``nbv-gym`` command must
be a command of the CLI with options it has; the configs, worlds, policies and suites it names
must be shipped; a path into the repository (``experiments/…``, ``docs/…``) or a file given to
``python`` or to rl-zoo3's ``-conf`` must exist, or be written by an earlier example of the same
page (``nbv-gym configs copy NAME FILE``). Files of the reader's own — the ones the docs ask the
reader to write — are named ``my…`` (``my_policy.py``, ``my-sweep.toml``) and are not looked up.
"""

from __future__ import annotations

import re
import shlex
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium
import pytest
import typer

from nbv_gym.benchmark.suites import SUITES
from nbv_gym.cli.main import app
from nbv_gym.configs import shipped_configs
from nbv_gym.core.errors import CPU_TORCH
from nbv_gym.policies.registry import MODELS, POLICIES
from nbv_gym.team.policies import TEAM_POLICIES
from nbv_gym.worlds.distribution import distribution_names
from nbv_gym.worlds.spec import benchmark_names

ROOT = Path(__file__).parents[1]
PAGES = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]
#: The repository's folders a docs path may point into.
REPO_FOLDERS = ("experiments/", "docs/", "nbv_gym/", "tests/", ".ci/")
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def commands(text: str) -> Iterator[str]:
    """The shell command lines of a Markdown page: ``bash`` fences (continuation lines joined)
    and indented ``nbv-gym …`` lines; each line split at ``&&``, ``;`` and pipes."""
    blocks = [
        m.group(2)
        for m in re.finditer(r"^( *)```(?:bash|sh|shell)\n(.*?)^\1```", text, re.M | re.S)
    ]
    blocks += re.findall(r"^ {4,}(nbv-gym .*)$", text, re.M)
    for block in blocks:
        for line in block.replace("\\\n", " ").splitlines():
            for part in re.split(r"&&|;|\|(?!\|)", line.split(" #")[0]):
                if part.strip() and not part.strip().startswith("#"):
                    yield part.strip()


def reader_file(value: str) -> bool:
    """A file the docs ask the reader to write (``my_policy.py``, ``my-sweep.toml``)."""
    return Path(value.partition(":")[0]).name.startswith("my")


def resolve(tokens: list[str]) -> tuple[Any, list[str]]:
    """The CLI command (a click command of typer's) that ``nbv-gym`` tokens name, and the tokens
    after its name."""
    command = typer.main.get_command(app)
    while hasattr(command, "commands") and tokens and not tokens[0].startswith("-"):
        name = tokens.pop(0)
        assert name in command.commands, f"nbv-gym has no command {name!r}"
        command = command.commands[name]
    return command, tokens


def options(command: Any) -> dict[str, Any]:
    return {
        flag: p
        for p in command.params
        for flag in (*p.opts, *p.secondary_opts)
        if flag.startswith("-")
    }


def check_policy(value: str) -> None:
    name = value.partition("@")[0]
    if ":" in name:  # module:Class, sb3:PATH — a file of the reader's or a training output
        assert name.startswith("sb3:") or reader_file(name), (
            f"policy {value!r}: not a reader's file"
        )
        return
    assert name in POLICIES or name in MODELS or name in TEAM_POLICIES, (
        f"policy {value!r} is not shipped"
    )


def check_world(value: str) -> None:
    if value in distribution_names() or reader_file(value):
        return
    assert value in benchmark_names(), f"world {value!r} is not a benchmark world"


def check_config(value: str, kind: str, written: set[str]) -> None:
    if value.endswith((".toml", ".yml")) or "/" in value:
        assert value in written or reader_file(value) or (ROOT / value).is_file(), (
            f"config file {value} does not exist"
        )
        return
    assert value in shipped_configs(kind), f"no shipped {kind} config {value!r}"


def check_nbv_gym(tokens: list[str], written: set[str]) -> None:  # noqa: C901 (a small parser)
    command, rest = resolve(tokens)
    known = options(command)
    arguments = []
    while rest:
        token = rest.pop(0)
        if token.startswith("-"):
            flag, _, inline = token.partition("=")
            assert flag in known, f"nbv-gym {command.name} has no option {flag}"
            parameter = known[flag]
            if getattr(parameter, "is_flag", False) or getattr(parameter, "count", False):
                continue
            value = inline or rest.pop(0)
            if flag == "--world" and value not in written:
                check_world(value)
            elif flag == "--policy":
                check_policy(value)
            elif flag == "--config" and command.name == "train":
                check_config(value, "train", written)
            elif flag == "--suite" and command.name == "score":
                assert value in SUITES, f"no suite {value!r}"
        else:
            arguments.append(token)
    name = command.name
    if name == "sweep" and arguments:
        check_config(arguments[0], "sweep", written)
    elif name in ("show", "copy"):
        assert arguments[0] in shipped_configs(), f"no shipped config {arguments[0]!r}"
    elif name == "score":
        check_policy(arguments[0])
    elif name == "build":
        for world in arguments:
            check_world(world.rstrip("…"))


def check_line(line: str, written: set[str]) -> None:
    tokens = [t for t in shlex.split(line) if t not in (">", "2>&1")]
    for token in tokens:
        if token.startswith(REPO_FOLDERS) and (token.endswith("/") or Path(token).suffix):
            assert (ROOT / token).exists(), f"{token} does not exist in the repository"
    if tokens[0] == "nbv-gym":
        check_nbv_gym(tokens[1:], written)
    elif tokens[0] == "python" and len(tokens) > 1 and tokens[1].endswith(".py"):
        assert (ROOT / tokens[1]).is_file(), f"{tokens[1]} does not exist"
    elif tokens[:2] == ["python", "-m"] and tokens[2].startswith("nbv_gym"):
        assert (ROOT / (tokens[2].replace(".", "/") + ".py")).is_file(), f"no module {tokens[2]}"
    if "-conf" in tokens:
        conf = tokens[tokens.index("-conf") + 1]
        assert conf in written or (ROOT / conf).is_file(), f"rl-zoo3 config {conf} does not exist"


def written_files(text: str) -> set[str]:
    """Files an example of the page writes: ``nbv-gym configs copy NAME DEST`` (DEST a file, or
    a folder that receives NAME's file) and ``nbv-gym worlds import FILE --out WORLD.toml``."""
    written = set(re.findall(r"nbv-gym worlds import \S+ --out (\S+)", text))
    for name, dest in re.findall(r"nbv-gym configs copy (\S+) (\S+)", text):
        suffix = (
            ".yml"
            if shipped_configs().get(name) and shipped_configs()[name].kind == "rl-zoo3"
            else ".toml"
        )
        written.add(dest if Path(dest).suffix else f"{name}{suffix}")
    return written


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_shell_examples_name_commands_options_configs_and_files_that_exist(page):
    text = page.read_text()
    written = written_files(text)
    failures = []
    for line in commands(text):
        try:
            check_line(line, written)
        except AssertionError as error:
            failures.append(f"{line}\n    {str(error).splitlines()[0]}")
    assert not failures, "\n".join(failures)


def test_the_checker_catches_a_stale_path_a_stale_flag_and_an_unknown_config():
    """The checks fail on what the docs once said (experiments/rl-zoo3-ppo.yml, moved into the
    package) and on names that do not exist."""
    stale = [
        "python -m rl_zoo3.train --algo ppo -conf experiments/rl-zoo3-ppo.yml -f logs/",
        "nbv-gym run --world pp1-trees --policy closest-frontier --speed 2",
        "nbv-gym sweep quik --out results/quick",
        "nbv-gym run --world pp9-trees",
        "nbv-gym score my_policy:Nearest --suite tiny",
        "nbv-gym configs copy rl-zoo3 .",
    ]
    for line in stale:
        with pytest.raises(AssertionError):
            check_line(line, set())
    check_line("nbv-gym sweep my-sweep.toml --out results/mine", set())
    check_line("python -m rl_zoo3.train -conf rl-zoo3-ppo.yml", {"rl-zoo3-ppo.yml"})


def stated_versions(text: str) -> list[str]:
    return re.findall(r"Python ≥ (3\.\d+)", text)


def test_the_environment_page_and_the_notebook_name_every_registered_id_and_its_count():
    ids = sorted(i for i in gymnasium.registry if i.startswith("nbv_gym/"))
    words = {2: "two", 3: "three", 4: "four", 5: "five"}
    for page in (ROOT / "docs/environment.md", ROOT / "docs/tutorials/getting-started.ipynb"):
        text = page.read_text()
        assert f"registers {words[len(ids)]} " in text, page
        assert all(f"`{i}`" in text for i in ids), page


def test_docs_state_the_python_version_that_pyproject_requires():
    required = re.fullmatch(r">=(3\.\d+)", PYPROJECT["project"]["requires-python"]).group(1)
    stated = {str(page.relative_to(ROOT)): stated_versions(page.read_text()) for page in PAGES}
    assert any(stated.values())
    wrong = {page: versions for page, versions in stated.items() if set(versions) - {required}}
    assert not wrong, f"pyproject requires Python >= {required}; the docs say {wrong}"


def test_docs_name_only_extras_that_pyproject_defines_and_the_home_page_names_them_all():
    extras = set(PYPROJECT["project"]["optional-dependencies"])
    for page in PAGES:
        for group in re.findall(r"(?:\.|nbv-gym)\[([a-z0-9_,-]+)\]", page.read_text()):
            unknown = set(group.split(",")) - extras
            assert not unknown, (
                f"{page.name} installs extras {unknown} that pyproject does not define"
            )
    home = (ROOT / "docs" / "index.md").read_text()
    install = home[home.index("## Install") : home.index("## Where to go")]
    named = {word for word in re.findall(r"`([a-z0-9-]+)` \(", install)}
    assert named | {"rl"} == extras, (
        f"docs/index.md names extras {sorted(named)}; pyproject {sorted(extras)}"
    )


def test_every_torch_install_line_uses_the_cpu_wheel_index_as_the_missing_torch_message_does():
    """A plain ``pip install torch`` gives most Linux users the multi-GB CUDA build."""
    lines = [
        line
        for page in PAGES
        for line in page.read_text().splitlines()
        if "pip install torch" in line
    ]
    assert lines
    for line in lines:
        assert CPU_TORCH in line, line


def test_no_table_cell_shows_an_escaped_pipe_inside_code():
    """Python-Markdown (mkdocs) keeps the backslash of ``\\|`` inside a code span of a table, so
    the page would show it; a cell lists alternatives in words instead."""
    rows = [(page.name, line) for page in PAGES for line in page.read_text().splitlines()
            if line.startswith("|") and re.search(r"`[^`]*\\\|[^`]*`", line)]  # fmt: skip
    assert not rows, rows


#: A citation of a section of a document by its short capitalised name ("NAME §1"): the
#: project's internal documents, which users do not have, are cited that way; papers by title.
INTERNAL_CITATION = re.compile(r"\b[A-Z]{3,}\s*§\s*\d")


def test_shipped_files_and_docs_cite_papers_not_internal_documents():
    """Users have the papers (cited by title), not the project's internal documents."""
    shipped = [
        p for p in (ROOT / "nbv_gym").rglob("*") if p.suffix in (".py", ".toml", ".yml", ".md")
    ]
    pages = [*shipped, *PAGES]
    citing = [str(p.relative_to(ROOT)) for p in pages if INTERNAL_CITATION.search(p.read_text())]
    assert not citing, citing


#: The longest the README may grow (lines): a first page, the rest lives in docs/.
MAX_README_LINES = 200


def test_the_readme_stays_a_first_page():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines: move a part to docs/"


def test_the_papers_bibtex_lives_in_the_docs_and_the_readme_points_to_it():
    bibtex = (ROOT / "docs" / "citing.md").read_text()
    for key in ("aravecchia2023nbv", "aravecchia2023wdocc", "turkar2023empir3d", "nbv_gym"):
        assert f"{{{key}," in bibtex, key
    assert "(docs/citing.md)" in (ROOT / "README.md").read_text()
