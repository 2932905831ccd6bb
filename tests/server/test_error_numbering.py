"""Errors about a constraint set name vertices as the mesh file numbers them, not as the repaired mesh the session
works on does (the user knows the file's numbering; see arap.server.numbering)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import arap
from arap.server.errors import request_error
from arap.server.mesh_model import MeshData
from arap.server.session import Session
from arap.server.session_errors import ConstraintsRejected
from tests.server.helpers import StudioClient, renumbered_bar_obj

pytestmark = pytest.mark.timeout(120)


def test_a_vertex_both_fixed_and_a_handle_is_named_as_in_the_file(studio: StudioClient) -> None:
    text, vertex_map = renumbered_bar_obj()
    studio.send_binary({"type": "upload", "filename": "bar.obj"}, text.encode())
    studio.read_mesh()
    studio.expect("state")
    fixed, top = studio.bottom_top()
    v = fixed[3]
    file_v = int(np.flatnonzero(vertex_map == v)[0])
    assert file_v != v
    studio.send({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [[*top, v]]})
    error = studio.error("bad_constraints")
    assert f"vertex {file_v} is in both" in error["message"], error["message"]


def _two_bars(vertex_map: bool) -> MeshData:
    V, F = arap.builtin_mesh("bar")
    n = len(V)
    V2 = np.concatenate([V, V + np.array([10.0, 0.0, 0.0])])
    F2 = np.concatenate([F, F + n])
    if not vertex_map:
        return MeshData.make("bars", V2, F2)
    vmap = np.concatenate([[-1], np.arange(2 * n)])
    return MeshData.make("bars", V2, F2, ["1 unused vertex removed"], vmap)


def _refusal(mesh: MeshData) -> str:
    s = Session()
    s.load(mesh)
    s.params.loose = "error"  # the library's refusal (the studio's own choices let such a part follow or stay)
    fixed = np.flatnonzero(s.V[:, 1] <= s.V[:len(s.V) // 2, 1].min() + 1e-9)
    fixed = fixed[fixed < len(s.V) // 2]
    with pytest.raises(ConstraintsRejected) as err:
        s.set_constraints(None, fixed.tolist(), [])
    assert request_error(err.value).code == "bad_constraints"
    return err.value.message


def test_an_unpinned_part_is_named_by_the_files_vertices() -> None:
    plain = _refusal(_two_bars(False))
    renumbered = _refusal(_two_bars(True))
    sample = [int(x) for x in re.search(r"vertices \[([0-9, ]+)\]", plain)[1].split(", ")]  # type: ignore[index]
    shifted = "[" + ", ".join(str(i + 1) for i in sample) + "]"
    assert renumbered == plain.replace(str(sample), shifted), (plain, renumbered)
