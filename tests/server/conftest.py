"""Fixtures of the studio server tests: an in-process app and a greeted protocol client."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from arap.server import create_app
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_builtin
from arap.server.session import Session
from tests.server.helpers import StudioClient


@pytest.fixture
def static_dir(tmp_path: Path) -> Path:
    """A folder standing in for the built client."""
    d = tmp_path / "static"
    (d / "assets").mkdir(parents=True)
    (d / "index.html").write_text("<!doctype html><title>studio</title>")
    (d / "assets" / "app.js").write_text("console.log('studio');")
    return d


@pytest.fixture
def app(static_dir: Path) -> Any:
    return create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"])


@pytest.fixture
def http(app: Any) -> Iterator[TestClient]:
    with TestClient(app) as client:
        yield client


@pytest.fixture
def studio(http: TestClient) -> Iterator[StudioClient]:
    """A connected, greeted session on the cactus."""
    with http.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.greet()
        yield client


@pytest.fixture(scope="module")
def bar() -> MeshData:
    """The built-in bar, loaded once per module."""
    return load_builtin("bar")


@pytest.fixture
def bar_session(bar: MeshData) -> Session:
    """An editing session (no network) on the bar."""
    s = Session()
    s.load(bar)
    return s
