"""The Python examples of the README and the documentation pages (the examples gallery and the example notebook
included) run as written, in an empty folder, and need no more than the install their page tells the reader to make.

A block runs when it is a whole program (its first line imports); blocks that continue an earlier one, or open a
studio page (a server and a browser), are shown as fragments and left to the tests of what they call.

A program needs the core install (``pip install arap``) unless the line just above its block says otherwise, e.g.
``<!-- needs: arap[notebook] -->`` (extras of arap, or other packages, separated by spaces); a notebook says so in
one of its Markdown cells. Whatever a program needs beyond the core, its page names in a ``pip install`` line, and
the program imports only the standard library, arap, and the modules of the distributions its install brings (the
dependencies of the core and of the extras named, read from pyproject.toml, with their own dependencies as installed
here).
"""

from __future__ import annotations

import ast
import json
import os
import re
import sys
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
         *sorted((ROOT / "docs" / "examples").glob("*.md"))]
NOTEBOOKS = sorted((ROOT / "docs" / "notebooks").glob("*.ipynb"))
BLOCK = re.compile(r"^(?:<!-- needs: (?P<needs>[^>]*?) -->\n)?```python\n(?P<code>.*?)^```", re.S | re.M)
NEEDS = re.compile(r"<!-- needs: (?P<needs>[^>]*?) -->")
PIP_INSTALL = re.compile(r"pip install ([^\n`#]+)")
CORE = "arap"
USES = {"arap.widget(": {"notebook"}, "arap.studio(": {"notebook", "studio"}}
"""What a program calls, and the extras of which it must name one."""


@dataclass(frozen=True)
class Program:
    name: str
    page: str
    code: str
    needs: tuple[str, ...]
    runs: bool


def _programs() -> list[Program]:
    found = []
    for page in PAGES:
        page_name = page.relative_to(ROOT).as_posix()
        for k, match in enumerate(BLOCK.finditer(page.read_text(encoding="utf-8"))):
            code = match["code"]
            first = code.lstrip().splitlines()[0] if code.strip() else ""
            if first.startswith(("import ", "from ")):
                needs = tuple(match["needs"].split()) if match["needs"] else (CORE,)
                found.append(Program(f"{page_name}#{k + 1}", page_name, code, needs, "arap.studio(" not in code))
    return found


def _notebook_text(path: Path, kind: str) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == kind)


def _notebook_programs() -> list[Program]:
    """Each example notebook's code cells as one program (the notebook runs in tests/notebook)."""
    found = []
    for path in NOTEBOOKS:
        needs = NEEDS.search(_notebook_text(path, "markdown"))
        found.append(Program(path.relative_to(ROOT).as_posix(), path.relative_to(ROOT).as_posix(),
                             _notebook_text(path, "code"), tuple(needs["needs"].split()) if needs else (CORE,), False))
    return found


PROGRAMS = _programs()
ALL_PROGRAMS = PROGRAMS + _notebook_programs()


def _page_text(page: str) -> str:
    path = ROOT / page
    return _notebook_text(path, "markdown") if path.suffix == ".ipynb" else path.read_text(encoding="utf-8")


@cache
def _pyproject() -> dict[str, object]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def _installed(needs: tuple[str, ...]) -> set[str]:
    """The distributions an install of ``needs`` brings (canonical names): arap's own dependencies from pyproject.toml
    for ``arap[...]``, then their dependencies as the installed distributions declare them."""
    project = _pyproject()
    wanted: list[Requirement] = []
    for need in needs:
        requirement = Requirement(need)
        if canonicalize_name(requirement.name) == CORE:
            extras = project["optional-dependencies"]  # type: ignore[index]
            unknown = requirement.extras - set(extras)
            assert not unknown, f"{need}: arap has no extra {sorted(unknown)}"
            wanted += [Requirement(r) for r in project["dependencies"]]  # type: ignore[index]
            wanted += [Requirement(r) for extra in sorted(requirement.extras) for r in extras[extra]]
        else:
            wanted.append(requirement)
    seen: set[str] = {CORE}
    while wanted:
        requirement = wanted.pop()
        name = canonicalize_name(requirement.name)
        if name in seen:
            continue
        seen.add(name)
        try:
            requires = metadata.requires(requirement.name) or []
        except metadata.PackageNotFoundError:
            continue  # not for this platform or Python (its marker), or not installed here: nothing more to follow
        for text in requires:
            dependency = Requirement(text)
            if dependency.marker is None or any(dependency.marker.evaluate({"extra": extra})
                                                for extra in ("", *requirement.extras)):
                wanted.append(dependency)
    return seen


def _imports(code: str) -> set[str]:
    names = set()
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("program", ALL_PROGRAMS, ids=[p.name for p in ALL_PROGRAMS])
def test_example_needs_only_what_its_page_installs(program: Program) -> None:
    requirements = [Requirement(need) for need in program.needs]
    extras = {e for r in requirements if canonicalize_name(r.name) == CORE for e in r.extras}
    for call, choices in USES.items():
        if call in program.code:
            assert extras & choices, f"{program.name} calls {call}...) and needs arap[{' or '.join(sorted(choices))}]"
    installs = {word.strip("'\"") for line in PIP_INSTALL.findall(_page_text(program.page)) for word in line.split()}
    for need in program.needs:
        if need != CORE:
            assert need in installs, f"{program.page} should tell the reader to pip install {need}"
    brought = _installed(program.needs)
    modules = metadata.packages_distributions()
    for module in sorted(_imports(program.code)):
        if module in sys.stdlib_module_names:
            continue
        owners = {canonicalize_name(d) for d in modules.get(module, [module])}
        assert owners & brought, (f"{program.name} imports {module}, which `pip install {' '.join(program.needs)}` "
                                  "does not bring: name what brings it in the page and above the block")


def test_a_program_that_imports_what_its_install_lacks_is_found() -> None:
    assert "pillow" not in _installed((CORE,)) and "starlette" not in _installed(("arap[notebook]",))
    assert {"anywidget", "ipywidgets", "numpy"} <= _installed(("arap[notebook]",))
    assert {"starlette", "uvicorn", "websockets"} <= _installed(("arap[studio]",))
    assert "pillow" in _installed((CORE, "pillow"))
    assert _imports("import numpy as np\nfrom PIL import Image\nfrom . import x\nimport matplotlib.pyplot") == {
        "numpy", "PIL", "matplotlib"}


def test_the_readme_has_a_python_example_that_runs() -> None:
    assert any(p.name.startswith("README.md#") and p.runs for p in PROGRAMS)


def test_every_gallery_example_runs() -> None:
    pages = [p for p in sorted((ROOT / "docs" / "examples").glob("*.md")) if p.name != "index.md"]
    assert pages
    for page in pages:
        assert any(p.name.startswith(f"docs/examples/{page.name}#") and p.runs for p in PROGRAMS), page.name


@pytest.mark.parametrize("code", [p.code for p in PROGRAMS if p.runs], ids=[p.name for p in PROGRAMS if p.runs])
def test_example_runs_as_written(code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<example>", "exec"), {"__name__": "__example__"})
    assert os.listdir(tmp_path) == [] or all((tmp_path / f).stat().st_size > 0 for f in os.listdir(tmp_path))
