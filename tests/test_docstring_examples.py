"""Every Example in the library's docstrings runs and shows what it claims."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import arap

MODULES = ["arap", *sorted(m.name for m in pkgutil.walk_packages(arap.__path__, "arap."))]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_hold(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} docstring examples of {name} failed"


def test_the_modules_with_examples_are_found() -> None:
    """A walk that found no module would pass every test above."""
    assert {"arap.solve.lbfgs", "arap.solve.start", "arap.solve.solver", "arap.server.protocol"} <= set(MODULES)
    assert sum(doctest.testmod(importlib.import_module(m)).attempted for m in ("arap", "arap.solve.start")) > 0
