"""The scripts of ``tools/`` and ``benchmarks/`` imported as modules, for their tests (they are programs, not part
of the package)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def load_tool(name: str, folder: str = "tools") -> ModuleType:
    """``<folder>/<name>.py`` (``tools/`` by default) as the module ``name``."""
    spec = importlib.util.spec_from_file_location(name, ROOT / folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def load_benchmark(name: str) -> ModuleType:
    """``benchmarks/<name>.py`` as the module ``name``, with ``benchmarks/`` on the import path while it loads (the
    benchmarks import their shared modules, such as ``benchjson``, as siblings)."""
    folder = str(ROOT / "benchmarks")
    sys.path.insert(0, folder)
    try:
        return load_tool(name, "benchmarks")
    finally:
        sys.path.remove(folder)
