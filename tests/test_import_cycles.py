"""No import cycle among arap's modules, imports inside functions and under ``TYPE_CHECKING`` included (the
package's lazy loader of public names, ``arap/__init__.py``, is left out: every module may import ``arap``)."""

from __future__ import annotations

from pathlib import Path

import arap
from tests.imports import imported_modules, package_modules

SRC = Path(arap.__file__).resolve().parents[1]


def import_graph(src: Path = SRC) -> dict[str, set[str]]:
    """Each module of ``arap`` (in the source folder ``src``) and the modules of ``arap`` it imports anywhere in its
    source."""
    paths = package_modules(src)
    return {module: {name for name, _ in imported_modules(path, module, set(paths)) if name != "arap"}
            for module, path in paths.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
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
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_a_cycle_through_relative_imports_is_found(tmp_path: Path) -> None:
    package = tmp_path / "arap"
    (package / "solve").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "solve" / "__init__.py").write_text("")
    (package / "solve" / "solver.py").write_text("def f():\n    from ..method import cells\n")
    (package / "method").mkdir()
    (package / "method" / "__init__.py").write_text("from arap import solve\n")
    (package / "method" / "cells.py").write_text("from . import weights\n")
    (package / "method" / "weights.py").write_text("from ..solve.solver import f\n")
    assert cycles(import_graph(tmp_path)) == [["arap.method.cells", "arap.method.weights", "arap.solve.solver"]]


def test_no_import_cycle_in_the_package() -> None:
    graph = import_graph()
    assert {"arap.solve.solver", "arap.server.protocol", "arap.notebook"} <= set(graph)
    assert cycles(graph) == []
