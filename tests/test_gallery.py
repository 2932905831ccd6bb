"""The generated documentation pictures and pages: tools/gallery.py pictures the examples gallery from the examples'
own code, and docs/notebook-example.md is what tools/notebook_page.py makes from the example notebook."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from tests.png_files import decode_png
from tests.tool_modules import ROOT, load_tool

gallery = load_tool("gallery")
notebook_page = load_tool("notebook_page")


def _changed_share(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.any(a != b, axis=2)))


@pytest.mark.parametrize("name", ["bend", "rigid-parts"])
def test_gallery_pictures_decode_and_show_the_deformation(name: str, tmp_path: Path) -> None:
    assert gallery.main([name, "--out", str(tmp_path), "--width", "160", "--height", "120"]) == 0
    before = decode_png((tmp_path / f"{name}-before.png").read_bytes())
    after = decode_png((tmp_path / f"{name}-after.png").read_bytes())
    both = decode_png((tmp_path / f"{name}.png").read_bytes())
    assert before.shape == after.shape == (120, 160, 3)
    assert both.shape == (120, 320, 3)
    assert np.array_equal(both[:, :160], before) and np.array_equal(both[:, 160:], after)
    background = before[0, 0]
    for picture in (before, after):
        assert 0.03 < float(np.mean(np.any(picture != background, axis=2))) < 0.9  # a mesh, framed, not cut off
        for edge in (picture[0], picture[-1], picture[:, 0], picture[:, -1]):
            assert np.all(edge == background)
    assert _changed_share(before, after) > 0.02  # the shape moved


def test_gallery_pictures_follow_the_example_code(tmp_path: Path) -> None:
    """A change to an example's code changes its pictures: they are made from the page, not kept on their own."""
    pages = tmp_path / "pages"
    pages.mkdir()
    page = (gallery.PAGES / "bend.md").read_text(encoding="utf-8")
    assert "move=np.array([1.5, -1.0, 0.0])" in page
    (pages / "bend.md").write_text(page.replace("move=np.array([1.5, -1.0, 0.0])", "move=np.array([0.0, 0.0, 0.0])"))
    still = gallery.render("bend", tmp_path / "still", width=96, height=72, pages=pages)
    moved = gallery.render("bend", tmp_path / "moved", width=96, height=72)
    unmoved_before, unmoved_after = (decode_png(p.read_bytes()) for p in still[:2])
    assert _changed_share(unmoved_before, unmoved_after) < 0.002
    assert _changed_share(*(decode_png(p.read_bytes()) for p in moved[:2])) > 0.02


@pytest.mark.parametrize("name", ["bend", "twist"])
def test_committed_pictures_are_what_the_code_makes(name: str, tmp_path: Path) -> None:
    """The pictures in docs/images/gallery were made from the example as it is now (run tools/gallery.py after a
    change); a few pixels may differ with the platform's rounding."""
    for path in gallery.render(name, tmp_path):
        committed = decode_png((gallery.OUT / path.name).read_bytes())
        made = decode_png(path.read_bytes())
        assert committed.shape == made.shape, path.name
        assert _changed_share(committed, made) < 0.005, f"{path.name}: run python tools/gallery.py {name}"


def test_every_example_page_is_in_the_gallery_and_shows_its_pictures() -> None:
    pages = sorted(p.stem for p in gallery.PAGES.glob("*.md") if p.name != "index.md")
    assert pages == sorted(gallery.EXAMPLES)
    index = (gallery.PAGES / "index.md").read_text(encoding="utf-8")
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    total = 0
    for name in gallery.EXAMPLES:
        text = (gallery.PAGES / f"{name}.md").read_text(encoding="utf-8")
        assert f"]({name}.md)" in index and f"examples/{name}.md" in nav
        for picture in re.findall(r"\(\.\./images/gallery/([\w.-]+\.png)\)", text + index):
            path = ROOT / "docs" / "images" / "gallery" / picture
            pixels = decode_png(path.read_bytes())
            assert pixels.shape[0] <= 400 and pixels.shape[1] <= 640, picture
        assert f"{name}-before.png" in text and f"{name}-after.png" in text
    for path in (ROOT / "docs" / "images" / "gallery").glob("*.png"):
        total += path.stat().st_size
    assert 0 < total < 1_500_000


def test_notebook_page_is_up_to_date() -> None:
    notebook = json.loads(notebook_page.NOTEBOOK.read_text(encoding="utf-8"))
    page = notebook_page.notebook_markdown(notebook, "docs/notebooks/first-deformation.ipynb")
    assert notebook_page.OUT.read_text(encoding="utf-8") == page, "run python tools/notebook_page.py"
    assert "notebook-example.md" in (ROOT / "mkdocs.yml").read_text(encoding="utf-8")


def test_notebook_page_holds_every_cell(tmp_path: Path) -> None:
    notebook = {"cells": [
        {"cell_type": "markdown", "source": ["# Title\n", "Some *text*."]},
        {"cell_type": "code", "source": "import arap\nx = 1", "outputs": [
            {"output_type": "stream", "name": "stdout", "text": ["hello\n"]},
            {"output_type": "display_data", "data": {"image/png": "AAAA", "text/plain": "<Figure>"}}]},
        {"cell_type": "code", "source": "", "outputs": []},
        {"cell_type": "code", "source": ["x + 1"], "outputs": [
            {"output_type": "execute_result", "data": {"text/plain": ["2"]}}]}]}
    path = tmp_path / "nb.ipynb"
    path.write_text(json.dumps(notebook))
    out = tmp_path / "page.md"
    assert notebook_page.main(["--notebook", str(path), "--out", str(out), "--check"]) == 1
    assert notebook_page.main(["--notebook", str(path), "--out", str(out)]) == 0
    assert notebook_page.main(["--notebook", str(path), "--out", str(out), "--check"]) == 0
    page = out.read_text()
    assert "# Title\nSome *text*." in page
    assert "```python\n# In [1]:\nimport arap\nx = 1\n```" in page
    assert "```python\n# In [2]:\nx + 1\n```\n\n```text\n2\n```" in page
    assert "```text\nhello\n```" in page and "<Figure>" not in page and "AAAA" not in page
    out.write_text(page + "edited by hand\n")
    assert notebook_page.main(["--notebook", str(path), "--out", str(out), "--check"]) == 1
