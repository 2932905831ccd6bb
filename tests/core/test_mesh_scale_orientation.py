"""Coordinate scales the computations cannot represent are refused by name, scales inside the supported range
deform exactly like the unit-sized mesh, and inconsistent face orientation is diagnosed."""

from __future__ import annotations

import numpy as np
import pytest

from arap.diagnose import inspect_mesh
from arap.errors import MeshError
from arap.meshes.mesh import SIZE_RANGE, check_mesh
from arap.meshes.repair import repair_mesh
from arap.meshes.shapes import builtin_mesh, sphere
from arap.solve.solver import ArapSolver


@pytest.mark.parametrize("check", [check_mesh, repair_mesh])
@pytest.mark.parametrize(("scale", "message"), [
    (1e300, "too large"), (1e200, "too large"), (1e-300, "too small"), (1e-200, "too small"),
])
def test_unsupported_scales_are_named(check: object, scale: float, message: str) -> None:
    V, F = sphere(1)
    with np.errstate(all="raise"):  # no overflow on the way to the message
        with pytest.raises(MeshError, match=rf"coordinates are {message}: .* across \(coordinates range from "
                                            rf"-?[0-9.e+-]+ to [0-9.e+-]+\); meshes from 1e-12 to 1e\+12"):
            check(V * scale, F)  # type: ignore[operator]


def test_a_far_away_vertex_nobody_uses_does_not_matter_to_repair() -> None:
    V, F = sphere(1)
    result = repair_mesh(np.vstack([V, [[1e300, 0, 0]]]), F)
    assert len(result.V) == len(V) and result.counts["unreferenced_vertices"] == 1


@pytest.mark.parametrize("scale", [SIZE_RANGE[0] * 20, SIZE_RANGE[1] / 20])
def test_solver_is_exact_across_the_supported_range(scale: float) -> None:
    """Deforming the bar scaled by s gives s times the deformation of the bar."""
    V, F = builtin_mesh("bar")
    V = V / np.ptp(V, axis=0).max()  # one unit across
    fixed = np.flatnonzero(V[:, 1] < 0.05)
    handles = np.flatnonzero(V[:, 1] > 0.95)
    idx = np.concatenate([fixed, handles])
    targets = np.concatenate([V[fixed], V[handles] + [0.2, 0, 0]])
    reference = ArapSolver(V, F, idx).solve(targets, max_iterations=4).vertices
    scaled = ArapSolver(V * scale, F, idx).solve(targets * scale, max_iterations=4).vertices
    np.testing.assert_allclose(scaled / scale, reference, rtol=0, atol=1e-9)


def test_consistent_meshes_have_no_orientation_defect() -> None:
    V, F = sphere(2)
    info = inspect_mesh(V, F)
    assert (info.inconsistent_edges, info.misoriented_faces, info.non_orientable_parts) == (0, 0, 0)
    info = inspect_mesh(V, F[:, ::-1])  # inside out, but consistently so
    assert info.misoriented_faces == 0 and info.problems == []


@pytest.mark.parametrize("flipped", [[0], [3, 17, 40], list(range(0, 60, 2))])
def test_flipped_faces_are_counted(flipped: list[int]) -> None:
    V, F = sphere(2)
    F = F.copy()
    F[flipped] = F[flipped][:, ::-1]
    info = inspect_mesh(V, F)
    assert info.misoriented_faces == len(flipped)
    assert info.inconsistent_edges > 0
    assert f"{len(flipped)} faces oriented against their neighbours" in str(info)
    assert "defects: none" not in str(info)


def test_moebius_strip_is_non_orientable() -> None:
    k = 16
    V = []
    for a in np.linspace(0, 2 * np.pi, k, endpoint=False):
        for w in (-0.3, 0.3):
            r = 1 + w * np.cos(a / 2)
            V.append([r * np.cos(a), r * np.sin(a), w * np.sin(a / 2)])
    F = []
    for i in range(k):
        j = (i + 1) % k
        b0, b1 = (2 * j, 2 * j + 1) if j else (1, 0)  # the half twist joins the strip's ends crosswise
        F += [[2 * i, 2 * i + 1, b1], [2 * i, b1, b0]]
    info = inspect_mesh(np.array(V), np.array(F))
    assert info.non_orientable_parts == 1
    assert "non-orientable" in str(info)


def test_inspect_survives_absurd_scales_and_reports_them() -> None:
    V, F = sphere(2)
    for scale, word in ((1e300, "too large"), (1e-300, "too small")):
        with np.errstate(all="raise"):
            info = inspect_mesh(V * scale, F)
        assert info.problems[0].startswith(f"the coordinates are {word}")
        assert info.duplicate_vertices == 0 and info.degenerate_faces == 0  # counted at a representable scale
