"""The model list shows the model loaded: a built-in one by its entry, an uploaded file by its name."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page

from tests.e2e.conftest import wait_idle
from tests.e2e.test_studio import sphere_obj

pytestmark = pytest.mark.e2e

SHOWN = "() => { const s = document.getElementById('builtin-select'); return s.options[s.selectedIndex]?.text ?? ''; }"


def test_the_model_list_names_an_uploaded_mesh(page: Page, tmp_path: Path) -> None:
    builtins = page.evaluate("() => window.__arap.builtins")
    first = page.evaluate("() => window.__arap.meshName")
    assert page.evaluate(SHOWN) == first
    text, _ = sphere_obj(1)
    path = tmp_path / "ball.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'ball'")
    wait_idle(page)
    assert page.evaluate(SHOWN) == "ball (file)"
    other = next(n for n in builtins if n != first)
    page.get_by_test_id("builtin-select").select_option(other)
    page.wait_for_function(f"() => window.__arap.meshName === {other!r}")
    wait_idle(page)
    assert page.evaluate(SHOWN) == other
    options = page.evaluate("() => Array.from(document.getElementById('builtin-select').options, (o) => o.text)")
    assert options == ["Built-in model…", *builtins]
