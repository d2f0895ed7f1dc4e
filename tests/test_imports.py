"""Import hygiene: no import cycle between modules, no private name imported across modules.

The graph is read from the source with :mod:`ast` (nothing is imported). Its nodes are the
modules of :data:`PACKAGES` (``pkg/__init__.py`` is the module ``pkg``); an edge ``A -> B``
means that executing ``A`` can execute ``B``'s body. Every import statement counts, wherever
it is: at the top, inside a function or method (lazy imports run too, only later), under
``try``; only the bodies of ``if TYPE_CHECKING:`` are left out (they never run).

Edges of one import statement, in a module ``A``:

* ``import a.b.c`` and ``from a.b.c import name`` (``name`` not a submodule): ``A -> a.b.c``;
  ``from a.b import c`` with ``a.b.c`` a module: ``A -> a.b.c``. Relative imports are
  resolved against ``A``'s package first. These are the *explicit* edges.
* Importing ``a.b.c`` first executes ``a/__init__.py`` and ``a/b/__init__.py``: *implicit*
  edges ``A -> a`` and ``A -> a.b`` — except to the packages that contain ``A`` itself. Python
  imports a module's parent packages before the module, so when ``A``'s body runs they are
  already imported or being imported (the import that started it), and an import of a sibling
  runs nothing of them again. Counting those edges would make every package whose
  ``__init__`` re-exports a submodule that imports a sibling a cycle (``pkg -> pkg.sub ->
  pkg``): the classic false positive.
* An *explicit* import of a package that contains ``A`` (``from pkg import name`` or
  ``from . import name`` inside ``pkg.sub``, ``name`` not a submodule) is an edge
  ``pkg.sub -> pkg``: it reads the half-executed ``pkg/__init__``, the real hazard.

Dynamic imports (``importlib.import_module`` with a computed name, e.g. the builders of
:mod:`fem_runout.methods`) are not edges.

The private-name rule covers :data:`PACKAGES` and ``tests``: ``from m import _x`` where ``_x``
starts with one underscore (dunders are fine) and ``m`` is not the importing module.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Packages whose import graph must be acyclic.
PACKAGES = ("fem_runout", "mpm")
#: Packages checked for private-name imports.
PRIVATE_CHECKED = (*PACKAGES, "tests")


@dataclass(frozen=True)
class Edge:
    """One import edge ``source -> target`` from ``path:line``."""

    source: str
    target: str
    path: str
    line: int


def module_files(packages: tuple[str, ...]) -> dict[str, Path]:
    """Module name -> file, for every ``.py`` file of ``packages`` under the repository."""
    out: dict[str, Path] = {}
    for package in packages:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def is_package(path: Path) -> bool:
    """Whether ``path`` is a package's ``__init__.py``."""
    return path.name == "__init__.py"


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def import_nodes(tree: ast.AST) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement of ``tree``, at any depth, skipping ``if TYPE_CHECKING:`` bodies."""
    stack: list[ast.AST] = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node
            continue
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        stack.extend(ast.iter_child_nodes(node))


def from_base(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute module named by ``from <base> import ...`` inside ``module``."""
    if node.level == 0:
        return node.module or ""
    package = module.split(".") if is_package(path) else module.split(".")[:-1]
    anchor = package[: len(package) - (node.level - 1)]
    return ".".join([*anchor, *([node.module] if node.module else [])])


def ancestors(name: str) -> list[str]:
    """Proper parent packages of a dotted name, outermost first (``a.b.c`` -> a, a.b)."""
    parts = name.split(".")
    return [".".join(parts[:k]) for k in range(1, len(parts))]


def explicit_targets(module: str, path: Path, node: ast.Import | ast.ImportFrom,
                     known: set[str]) -> Iterator[tuple[str, str | None]]:
    """``(imported module, imported name or None)`` of one statement."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name, None
        return
    base = from_base(module, path, node)
    for alias in node.names:
        sub = f"{base}.{alias.name}"
        if sub in known:
            yield sub, None
        else:
            yield base, alias.name


def edges(packages: tuple[str, ...] = PACKAGES) -> list[Edge]:
    """Every import edge between modules of ``packages`` (see the module docstring)."""
    files = module_files(packages)
    known = set(files)
    out: list[Edge] = []
    for module, path in files.items():
        own = {*ancestors(module), module}  # packages already running when this body runs
        rel = path.relative_to(ROOT).as_posix()
        for node in import_nodes(ast.parse(path.read_text(), str(path))):
            for target, _ in explicit_targets(module, path, node, known):
                implicit = [a for a in ancestors(target) if a not in own]
                for t in (*implicit, target):
                    if t in known and t != module:
                        out.append(Edge(module, t, rel, node.lineno))
    return list(dict.fromkeys(out))  # one edge per statement and target


def cycles(graph_edges: list[Edge]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), sorted."""
    graph: dict[str, set[str]] = {}
    for e in graph_edges:
        graph.setdefault(e.source, set()).add(e.target)
        graph.setdefault(e.target, set())
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:  # the graph is small: recursion depth <= number of modules
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def shortest_cycle(start: str, graph_edges: list[Edge]) -> list[str]:
    """A shortest import chain from ``start`` back to itself (breadth first)."""
    graph: dict[str, list[str]] = {}
    for e in graph_edges:
        graph.setdefault(e.source, []).append(e.target)
    paths = {t: [start, t] for t in graph.get(start, [])}
    queue = list(paths)
    while queue:
        v = queue.pop(0)
        if v == start:
            return paths[v]
        for w in graph.get(v, []):
            if w not in paths:
                paths[w] = [*paths[v], w]
                queue.append(w)
    return [start]


def describe(component: list[str], graph_edges: list[Edge]) -> str:
    """One shortest cycle of a component, then every edge inside it with file and line."""
    inside = set(component)
    lines = [f"cycle between {', '.join(component)}, e.g. "
             + " -> ".join(shortest_cycle(component[0], graph_edges)) + ":"]
    lines += [f"  {e.source} -> {e.target}  ({e.path}:{e.line})" for e in graph_edges
              if e.source in inside and e.target in inside]
    return "\n".join(lines)


def private_imports(packages: tuple[str, ...] = PRIVATE_CHECKED) -> list[str]:
    """``path:line: from m import _x`` for every private name imported from another module."""
    files = module_files(packages)
    known = set(files)
    found = []
    for module, path in files.items():
        rel = path.relative_to(ROOT).as_posix()
        for node in import_nodes(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.ImportFrom):
                continue
            for target, name in explicit_targets(module, path, node, known):
                if target == module:
                    continue
                imported = name if name is not None else target.rsplit(".", 1)[-1]
                if imported.startswith("_") and not imported.startswith("__"):
                    found.append(f"{rel}:{node.lineno}: from {from_base(module, path, node)} "
                                 f"import {imported}")
    return found


def test_the_graph_sees_the_packages() -> None:
    graph_edges = edges()
    sources = {e.source for e in graph_edges}
    assert {"fem_runout.cli", "fem_runout.config", "mpm.build"} <= sources
    # a lazy import inside a function is an edge (fem_runout/__init__.py's __getattr__)
    assert any(e.source == "fem_runout" and e.target == "fem_runout.api" for e in graph_edges)


def test_no_import_cycles() -> None:
    graph_edges = edges()
    found = cycles(graph_edges)
    assert not found, "import cycles:\n" + "\n".join(describe(c, graph_edges) for c in found)


def test_no_private_names_imported_from_other_modules() -> None:
    found = private_imports()
    assert not found, "private names imported from another module:\n" + "\n".join(found)


def test_edge_rules_on_a_toy_package(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rules of the module docstring on a package written for the purpose."""
    pkg = tmp_path / "toy"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from toy.a import f\n")
    (pkg / "a.py").write_text("from toy.b import g\n\ndef f():\n    from toy.sub import x\n")
    (pkg / "b.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                              "    from toy.a import f\n\ndef g():\n    pass\n")
    (pkg / "sub" / "__init__.py").write_text("from . import x\n")
    (pkg / "sub" / "x.py").write_text("from ..b import _h, g\nfrom toy import f\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    got = {(e.source, e.target) for e in edges(("toy",))}
    assert got == {("toy", "toy.a"), ("toy.a", "toy.b"), ("toy.a", "toy.sub"),
                   ("toy.a", "toy.sub.x"), ("toy.sub", "toy.sub.x"), ("toy.sub.x", "toy.b"),
                   ("toy.sub.x", "toy")}
    # toy -> toy.a -> toy.sub.x -> toy: the explicit import of the half-executed toy/__init__
    assert cycles(edges(("toy",))) == [["toy", "toy.a", "toy.sub", "toy.sub.x"]]
    assert private_imports(("toy",)) == ["toy/sub/x.py:1: from toy.b import _h"]
