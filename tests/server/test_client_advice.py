"""A missing browser client is reported at start, with advice that fits how arap was installed."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from arap.server import client_files
from arap.server.app import client_missing_advice, create_app


def test_checkout_advice_names_dev_setup(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    # This test runs from a checkout: web/ lies beside src/.
    with caplog.at_level(logging.WARNING, logger="arap.server.app"):
        create_app("bar", static_dir=tmp_path / "nothing")
    assert "./dev setup" in caplog.text and "browser client is missing" in caplog.text
    assert str(tmp_path / "nothing") in caplog.text


def test_installed_advice_does_not_mention_dev(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    static = tmp_path / "site-packages" / "arap" / "static"
    monkeypatch.setattr(client_files, "STATIC_DIR", static)
    advice = client_missing_advice(static)
    assert advice is not None
    assert "./dev" not in advice and "pip install" in advice and "Node.js" in advice


def test_no_advice_when_built(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "index.html").write_text("<title>studio</title>")
    assert client_missing_advice(tmp_path) is None
    with caplog.at_level(logging.WARNING, logger="arap.server.app"):
        create_app("bar", static_dir=tmp_path)
    assert "missing" not in caplog.text
