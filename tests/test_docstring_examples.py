"""Every Example in the library's docstrings runs and shows what it claims, and every public name has one.

The public names are those of ``arap.__all__`` and those the documentation pages render (their ``::: name``
lines; a module rendered whole brings the names of its ``__all__``). A function or class shows its example in its
own docstring; a constant or type alias, which has none, in the docstring of the module that defines it.
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil
import re
from pathlib import Path
from types import ModuleType

import pytest

import arap

MODULES = ["arap", *sorted(m.name for m in pkgutil.walk_packages(arap.__path__, "arap."))]
DOCS = Path(__file__).resolve().parents[1] / "docs"
RENDERED = re.compile(r"^::: ([\w.]+)", re.M)
FLAGS = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE


def _public_names() -> dict[str, tuple[object, ModuleType]]:
    """Each public name, dotted, with its object and the module that holds it."""
    found: dict[str, tuple[object, ModuleType]] = {}
    for name in arap.__all__:
        home = importlib.import_module(arap._LAZY.get(name, "arap.errors" if name.endswith("Error") else "arap"))
        found[f"arap.{name}"] = (getattr(arap, name), home)
    for page in sorted(DOCS.rglob("*.md")):
        for dotted in RENDERED.findall(page.read_text(encoding="utf-8")):
            try:
                module = importlib.import_module(dotted)
            except ImportError:
                module_name, _, attribute = dotted.rpartition(".")
                module = importlib.import_module(module_name)
                found[dotted] = (getattr(module, attribute), module)
            else:
                for name in getattr(module, "__all__", ()):
                    found[f"{dotted}.{name}"] = (getattr(module, name), module)
    return found


PUBLIC = _public_names()


def _examples_of(dotted: str) -> list[doctest.Example]:
    """The docstring examples that show ``dotted`` and run (not skipped): its own, or for a constant its module's
    that name it."""
    obj, module = PUBLIC[dotted]
    finder = doctest.DocTestFinder(recurse=False)
    if inspect.isclass(obj) or inspect.isroutine(obj):
        tests = finder.find(obj, dotted, module=False, globs={})
    else:
        short = re.compile(rf"\b{re.escape(dotted.rpartition('.')[2])}\b")
        tests = [t for t in finder.find(module, module.__name__, globs={})
                 if any(short.search(e.source) for e in t.examples)]
    return [e for t in tests for e in t.examples if not e.options.get(doctest.SKIP)]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_hold(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=FLAGS)
    assert result.failed == 0, f"{result.failed} of {result.attempted} docstring examples of {name} failed"


def test_the_modules_with_examples_are_found() -> None:
    """A walk that found no module would pass every test above."""
    assert {"arap.solve.lbfgs", "arap.solve.start", "arap.solve.solver", "arap.server.protocol"} <= set(MODULES)
    assert sum(doctest.testmod(importlib.import_module(m)).attempted for m in ("arap", "arap.solve.start")) > 0


def test_the_public_names_are_found() -> None:
    """Those of ``arap.__all__`` and those only the pages render."""
    assert {"arap.ArapSolver", "arap.__version__", "arap.solve.prepared.prepare", "arap.io.formats.get",
            "arap.server.runner.serve"} <= set(PUBLIC)


@pytest.mark.parametrize("dotted", sorted(PUBLIC))
def test_every_public_name_has_an_example(dotted: str) -> None:
    """Its examples run in :func:`test_docstring_examples_hold`, with those of its module."""
    assert _examples_of(dotted), f"{dotted} has no example (an Examples section with >>> lines) in its docstring"
