"""The package is a ladder of layers: a module imports only modules of its own layer or of the layers below it
(imports inside functions and under ``TYPE_CHECKING`` included), so each layer can be read, tested and reused
without the ones above it.

From the bottom: the compiled-kernel plumbing, errors and option names; the sparse solvers; meshes; the ARAP method
(cells, weights, the local step); the solver and the mesh diagnosis; files and constraints; the tools built on
solves (animation, batches, pictures, puppet warps); the front ends (server, command line, notebook, the kernel
warm-up). The package's lazy loader of public names, ``arap/__init__.py``, sits on top: below the front ends a
module may read only ``arap.__version__`` from it.
"""

from __future__ import annotations

from pathlib import Path

import pytest

import arap
from tests.imports import imported_modules, module_name, package_modules

SRC = Path(arap.__file__).resolve().parents[1]

LAYERS: list[set[str]] = [
    {"arap.kernels", "arap.errors", "arap.options", "arap._cstdout"},
    {"arap.sparse"},
    {"arap.meshes"},
    {"arap.method"},
    {"arap.solve", "arap.diagnose"},
    {"arap.io", "arap.constraints"},
    {"arap.animation", "arap.batching", "arap.render", "arap.puppet"},
    {"arap.server", "arap.cli", "arap.notebook", "arap.jupyter_widget", "arap.studio_handle", "arap.warmup"},
    {"arap"},
]
"""The layers, bottom first: the subpackages and top-level modules of each."""

ANY_LAYER_NAMES = {"__version__"}
"""Names every module may import from the package itself (``from arap import __version__``)."""


def layer_of(module: str) -> int:
    """The index in :data:`LAYERS` of a module of ``arap``."""
    parts = module.split(".")
    top = ".".join(parts[:2])
    for i, members in enumerate(LAYERS):
        if top in members:
            return i
    raise KeyError(f"{module} is in no layer: add {top} to LAYERS")


def upward_imports(src: Path) -> list[str]:
    """Every import of a module from a higher layer, as ``module:line imports other``."""
    paths = package_modules(src)
    found = []
    for module, path in sorted(paths.items()):
        for name, line in imported_modules(path, module, set(paths), free_names=ANY_LAYER_NAMES):
            if layer_of(name) > layer_of(module):
                found.append(f"{module}:{line} imports {name}")
    return found


def test_every_module_has_a_layer() -> None:
    for path in (SRC / "arap").rglob("*.py"):
        layer_of(module_name(path, SRC))


def test_no_module_imports_from_a_layer_above_it() -> None:
    assert upward_imports(SRC) == []


@pytest.mark.parametrize(("source", "upward"), [
    ("import arap.solve.solver\n", True),
    ("from arap.method import weights\n", True),
    ("def f():\n    from ..solve.solver import ArapSolver\n", True),
    ("import arap\n", True),
    ("from arap import __version__\n", False),
    ("from arap.sparse.linsolve import Factor\n", False),
    ("from arap.meshes import topology\n", False),
])
def test_an_upward_import_is_found(tmp_path: Path, source: str, upward: bool) -> None:
    package = tmp_path / "arap"
    for folder in ("sparse", "meshes", "method", "solve"):
        (package / folder).mkdir(parents=True)
        (package / folder / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "method" / "weights.py").write_text("")
    (package / "solve" / "solver.py").write_text("")
    (package / "sparse" / "linsolve.py").write_text("")
    (package / "meshes" / "topology.py").write_text(source)
    (package / "meshes" / "mesh.py").write_text("")
    found = upward_imports(tmp_path)
    assert bool(found) == upward, found
    assert all(f.startswith("arap.meshes.topology:") for f in found)
