"""The package's import graph: every ``import`` of an ``nbv_gym`` module, at module level or
inside a function, is an edge. The graph has no cycle, every edge between subpackages points
down the layer table (:data:`LAYERS`), so the tree reads in the order data flows, and inside a
package no subpackage imports back a module that imports it (0 imports run back up, inside
subpackages too)."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("nbv_gym",)


def modules() -> dict[str, Path]:
    """Dotted module name → file, for every module of the packages."""
    found = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            found[name] = path
    return found


def imported(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package modules that module ``name`` (file ``path``) imports anywhere in its body."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    edges = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
            targets = [t for t in targets if t in known][:1] or [base]
        else:
            continue
        edges.update(t for t in targets if t in known and t != name)
    return edges


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a path [a, b, …, a], or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def import_graph() -> dict[str, set[str]]:
    known = modules()
    return {name: imported(name, path, known) for name, path in known.items()}


#: The layers, lowest first. A module may import its own subpackage and any subpackage of a lower
#: layer; subpackages that share a layer do not import each other.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("core",),
    ("worlds", "configs"),
    ("sensor",),
    ("mapping",),
    ("nbv", "metrics"),
    ("simulator",),
    ("env",),
    ("policies",),
    ("episode",),
    ("team",),
    ("reporting",),
    ("sweep", "studies", "rl"),
    ("benchmark",),
    ("perf",),
    ("cli",),
    ("__main__",),
)
RANK = {part: rank for rank, parts in enumerate(LAYERS) for part in parts}
#: The package's own ``__init__`` (it registers the environments) sits just above core.
RANK["nbv_gym"] = 0.5


def part(module: str) -> str:
    """The layer part of a module: ``nbv_gym.mapping.occupancy`` → ``mapping``."""
    pieces = module.split(".")
    return pieces[1] if len(pieces) > 1 else pieces[0]


def back_imports(graph: dict[str, set[str]]) -> list[str]:
    """Every edge ``a → b`` whose target is not in a lower layer than ``a``'s subpackage."""
    wrong = []
    for module, targets in sorted(graph.items()):
        for target in sorted(targets):
            here, there = part(module), part(target)
            if here != there and RANK[there] >= RANK[here]:
                wrong.append(f"{module} → {target}")
    return wrong


def child(module: str, package: str) -> str | None:
    """What of ``package`` holds ``module``: the package itself (its ``__init__``), one of its
    modules, or the subpackage the module lies in (``nbv_gym.worlds.scenes.files`` in
    ``nbv_gym.worlds`` → ``nbv_gym.worlds.scenes``); None outside the package."""
    if module == package:
        return package
    if not module.startswith(package + "."):
        return None
    return f"{package}.{module[len(package) + 1 :].split('.')[0]}"


def inner_back_imports(graph: dict[str, set[str]]) -> list[str]:
    """Inside every package, with each of its subpackages drawn as one node: every edge
    ``a → b`` from a subpackage's module ``a`` to a node that (directly or through others)
    imports that subpackage — an import that runs back up from a subpackage into its parent."""
    known = set(graph)
    subpackages = {m for m in known if any(other.startswith(m + ".") for other in known)}
    wrong = []
    for package in sorted(subpackages):
        inner: dict[str, set[str]] = {}
        for module, targets in graph.items():
            here = child(module, package)
            if here is not None:
                there = {child(t, package) for t in targets} - {None, here}
                inner.setdefault(here, set()).update(t for t in there if t is not None)
        for module, targets in sorted(graph.items()):
            here = child(module, package)
            if here == module or here not in subpackages:
                continue  # a module or the __init__ of ``package``: its imports point down
            for target in sorted(targets):
                there = child(target, package)
                if there not in (None, here) and here in reachable(inner, there):
                    wrong.append(f"{module} → {target}")
    return sorted(set(wrong))


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    """Every node ``start`` reaches in ``graph`` (itself included)."""
    seen, todo = {start}, [start]
    while todo:
        for nxt in graph.get(todo.pop(), set()) - seen:
            seen.add(nxt)
            todo.append(nxt)
    return seen


def test_every_module_belongs_to_a_layer():
    assert {part(m) for m in import_graph()} <= set(RANK)


def test_imports_point_down_the_layer_table():
    wrong = back_imports(import_graph())
    assert not wrong, "imports against the layer table:\n" + "\n".join(wrong)


def test_a_planted_back_import_is_found():
    graph = import_graph()
    graph["nbv_gym.mapping.occupancy"] = graph["nbv_gym.mapping.occupancy"] | {
        "nbv_gym.env.explore"
    }
    graph["nbv_gym.sweep.config"] = graph["nbv_gym.sweep.config"] | {"nbv_gym.rl.config"}
    assert back_imports(graph) == [
        "nbv_gym.mapping.occupancy → nbv_gym.env.explore",
        "nbv_gym.sweep.config → nbv_gym.rl.config",
    ]


def test_no_subpackage_imports_back_its_parent():
    wrong = inner_back_imports(import_graph())
    assert not wrong, "imports that run back up from a subpackage:\n" + "\n".join(wrong)


def test_a_planted_back_import_inside_a_package_is_found():
    graph = import_graph()
    # a subpackage may use a module of its parent that does not import it back
    assert "nbv_gym.worlds.shapes" in graph["nbv_gym.worlds.scenes.build"]
    graph["nbv_gym.worlds.scenes.files"] = graph["nbv_gym.worlds.scenes.files"] | {
        "nbv_gym.worlds.spec"  # spec imports scenes.spec
    }
    assert inner_back_imports(graph) == ["nbv_gym.worlds.scenes.files → nbv_gym.worlds.spec"]


def test_the_package_imports_have_no_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " → ".join(cycle)


def test_the_walker_sees_imports_inside_functions_and_finds_a_cycle():
    graph = import_graph()
    # nbv_gym.env.explore imports its renderer inside a method only
    assert "nbv_gym.env.render" in graph["nbv_gym.env.explore"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_every_test_folder_names_a_subpackage():
    """The tests are laid out like the package: a folder of tests is named after the subpackage
    it tests (data folders hold no test modules)."""
    subpackages = {p.name for p in (ROOT / "nbv_gym").iterdir() if (p / "__init__.py").is_file()}
    folders = {p.parent.name for p in (ROOT / "tests").glob("*/**/test_*.py")}
    assert folders <= subpackages, f"test folders without a subpackage: {folders - subpackages}"


#: The longest a module may grow (lines): past it, split the concept it holds.
MAX_MODULE_LINES = 600


def test_no_module_is_longer_than_the_limit():
    lines = {name: len(path.read_text().splitlines()) for name, path in modules().items()}
    long = {name: n for name, n in lines.items() if n > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines (split them): {long}"


def documented_layers() -> list[tuple[str, ...]]:
    """The layer table of docs/api/index.md: the subpackages of each row, lowest first."""
    rows = []
    for line in (ROOT / "docs" / "api" / "index.md").read_text().splitlines():
        cells = line.split("|")
        if len(cells) > 3 and cells[1].strip().isdigit():
            rows.append(tuple(part.removeprefix("nbv_gym.") for part in _code_spans(cells[2])))
    return rows


def _code_spans(text: str) -> list[str]:
    return text.split("`")[1::2]


def test_the_documented_layer_table_is_the_tested_one():
    assert documented_layers() == [layer for layer in LAYERS if layer != ("__main__",)]
