"""The ``mesh`` message says whether the mesh is a built-in model, not a file, upload, picture or arrays that share a
built-in's name (which a page restoring the session must load as themselves, not as the built-in)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image
from starlette.testclient import TestClient

from arap.io import save_mesh
from arap.meshes.grids import rectangle_triangles
from arap.server import create_app
from arap.server.mesh_model import MeshData
from tests.server.helpers import StudioClient

pytestmark = pytest.mark.timeout(120)


def _grid() -> tuple[np.ndarray, np.ndarray]:
    """A small flat grid, unlike every built-in model."""
    V, F = rectangle_triangles(4, 3)
    return np.column_stack([V, np.zeros(len(V))]), F


@contextmanager
def _studio(spec: Any, static_dir: Path) -> Iterator[tuple[StudioClient, dict[str, Any]]]:
    """A session of a studio started on ``spec``, with the header of the mesh it greets with (its state, after an
    appearance for a picture, is still to read)."""
    app = create_app(spec, static_dir=static_dir, allowed_hosts=["testserver"])
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.welcome = client.expect("welcome").data
        yield client, client.read_mesh().data


def test_built_in_models_say_so(static_dir: Path) -> None:
    with _studio("bar", static_dir) as (client, mesh):
        assert mesh["name"] == "bar" and mesh["builtin"] is True
        client.expect("state")
        for name in ("cylinder", "solid bar"):
            client.send({"type": "load_builtin", "name": name})
            loaded = client.read_mesh().data
            client.expect("state")
            assert loaded["name"] == name and loaded["builtin"] is True
    with _studio(None, static_dir) as (_, mesh):
        assert mesh["builtin"] is True


def test_a_file_named_like_a_built_in_model_is_not_it(static_dir: Path, tmp_path: Path) -> None:
    V, F = _grid()
    path = tmp_path / "bar.obj"
    save_mesh(path, V, F)
    with _studio(path, static_dir) as (client, mesh):
        assert mesh["name"] == "bar" and mesh["n_vertices"] == len(V) and mesh["builtin"] is False
        client.expect("state")
        client.send_binary({"type": "upload", "filename": "cylinder.obj"}, path.read_bytes())
        uploaded = client.read_mesh().data
        client.expect("state")
        assert uploaded["name"] == "cylinder" and uploaded["n_vertices"] == len(V) and uploaded["builtin"] is False


def test_a_picture_or_arrays_named_like_a_built_in_model_are_not_it(static_dir: Path, tmp_path: Path) -> None:
    rgba = np.zeros((40, 60, 4), dtype=np.uint8)
    rgba[8:32, 10:50] = [200, 60, 40, 255]
    picture = tmp_path / "cactus.png"
    Image.fromarray(rgba, "RGBA").save(picture, format="PNG")
    with _studio(picture, static_dir) as (_, mesh):
        assert mesh["name"] == "cactus" and mesh["picture"] == [60, 40] and mesh["builtin"] is False
    V, F = _grid()
    with _studio(MeshData.make("bar", V, F), static_dir) as (_, mesh):
        assert mesh["name"] == "bar" and mesh["builtin"] is False
