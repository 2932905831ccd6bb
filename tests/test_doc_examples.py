"""The Python examples of the README and the documentation pages (the examples gallery included) run as written, in
an empty folder.

A block runs when it is a whole program (its first line imports); blocks that continue an earlier one, or open a
studio page (a server and a browser), are shown as fragments and left to the tests of what they call.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
         *sorted((ROOT / "docs" / "examples").glob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def _programs() -> list[tuple[str, str]]:
    found = []
    for page in PAGES:
        for k, code in enumerate(BLOCK.findall(page.read_text(encoding="utf-8"))):
            first = code.lstrip().splitlines()[0] if code.strip() else ""
            if first.startswith(("import ", "from ")) and "arap.studio(" not in code:
                found.append((f"{page.relative_to(ROOT).as_posix()}#{k + 1}", code))
    return found


PROGRAMS = _programs()


def test_the_readme_has_a_python_example_that_runs() -> None:
    assert any(name.startswith("README.md#") for name, _ in PROGRAMS)


def test_every_gallery_example_runs() -> None:
    pages = [p for p in sorted((ROOT / "docs" / "examples").glob("*.md")) if p.name != "index.md"]
    assert pages
    for page in pages:
        assert any(name.startswith(f"docs/examples/{page.name}#") for name, _ in PROGRAMS), page.name


@pytest.mark.parametrize("code", [c for _, c in PROGRAMS], ids=[n for n, _ in PROGRAMS])
def test_example_runs_as_written(code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<example>", "exec"), {"__name__": "__example__"})
    assert os.listdir(tmp_path) == [] or all((tmp_path / f).stat().st_size > 0 for f in os.listdir(tmp_path))
