"""The studio page and widget that arap serves and packages carry no test hook: ``window.__arap`` (web/src/hook.js)
is built only into the browser tests' client (``npm run build:e2e``, build/studio-e2e)."""

from __future__ import annotations

from pathlib import Path

import pytest

from arap.server.client_files import STATIC_DIR

E2E_CLIENT = Path(__file__).resolve().parents[1] / "build" / "studio-e2e"
HOOK = "__arap"
"""The hook's global (the page's other globals are upper case, e.g. ``__ARAP_HOST__``)."""


def _scripts(folder: Path) -> list[Path]:
    return sorted([*folder.glob("assets/*.js"), folder / "widget.js", folder / "index.html"])


def test_the_packaged_client_has_no_test_hook() -> None:
    if not (STATIC_DIR / "index.html").is_file():
        pytest.skip("the web client is not built (./dev setup)")
    scripts = [p for p in _scripts(STATIC_DIR) if p.is_file()]
    assert any(p.suffix == ".js" and p.parent.name == "assets" for p in scripts), scripts
    assert [p.name for p in scripts if HOOK in p.read_text(encoding="utf-8")] == []


def test_the_test_build_has_the_hook() -> None:
    """The check above would pass for a hook that no build has. The test build is made here when missing or stale
    (as the browser tests do): whether another test built it first depends on the order the tests run in."""
    from tests.e2e.conftest import _build_client

    reason = _build_client()
    if reason is not None:
        pytest.skip(reason)
    for name in ("assets", "widget.js"):
        texts = [p.read_text(encoding="utf-8") for p in _scripts(E2E_CLIENT) if name in p.as_posix()]
        assert any(f"window.{HOOK}=" in t for t in texts), name
