"""The imports of ``arap``'s modules read from their source (imports inside functions and under ``TYPE_CHECKING``
included), relative ones resolved: what the layering and import-cycle tests check."""

from __future__ import annotations

import ast
from collections.abc import Collection
from pathlib import Path


def module_name(path: Path, src: Path) -> str:
    """The dotted name of the module at ``path`` in the source folder ``src``."""
    return ".".join(path.relative_to(src).with_suffix("").parts).removesuffix(".__init__")


def package_modules(src: Path, package: str = "arap") -> dict[str, Path]:
    """Each module of ``package`` in the source folder ``src``, by dotted name."""
    return {module_name(p, src): p for p in (src / package).rglob("*.py")}


def imported_modules(path: Path, module: str, modules: Collection[str],
                     free_names: Collection[str] = ()) -> list[tuple[str, int]]:
    """The modules among ``modules`` that the module ``module`` (source at ``path``) imports, with the line of each
    import, sorted by line and name; never the module itself.

    ``from a.b import c`` imports ``a.b`` and, when it is a module, ``a.b.c``; a name that is no module stands for
    the nearest module above it. ``free_names``: names that every module may import from the package itself
    (``from arap import __version__``); such an import is left out.
    """
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    root = module.partition(".")[0]
    found: list[tuple[str, int]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            if base == root and {a.name for a in node.names} <= set(free_names):
                continue
            names = [base, *(f"{base}.{a.name}" for a in node.names)]
        else:
            continue
        targets = set()
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                targets.add(name)
        found.extend((name, node.lineno) for name in sorted(targets))
    return sorted(found, key=lambda found_at: (found_at[1], found_at[0]))
