"""Built-in meshes: clean, closed, one component, well shaped, deterministic."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from arap.diagnose import inspect_mesh
from arap.errors import OptionError
from arap.meshes.mesh import check_mesh
from arap.meshes.shapes import BUILTIN_MESHES, builtin_mesh, obtuse_cylinder, scan_blob, sphere, sphere_frequency_for


def signed_volume(V: np.ndarray, F: np.ndarray) -> float:
    P = V[F]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0)


def min_angle_degrees(V: np.ndarray, F: np.ndarray) -> float:
    P = V[F]
    angles = []
    for k in range(3):
        a = P[:, (k + 1) % 3] - P[:, k]
        b = P[:, (k + 2) % 3] - P[:, k]
        cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        angles.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    return float(np.min(angles))


def test_names() -> None:
    assert set(BUILTIN_MESHES) >= {"cactus", "bar", "cylinder"}
    with pytest.raises(ValueError, match="unknown built-in mesh 'teapot'"):
        builtin_mesh("teapot")


@pytest.mark.parametrize("name", BUILTIN_MESHES)
def test_builtin_is_a_clean_closed_surface(name: str) -> None:
    V, F = builtin_mesh(name)
    V2, F2 = check_mesh(V, F)
    np.testing.assert_array_equal(V2, V)
    np.testing.assert_array_equal(F2, F)
    assert 2_000 <= len(V) <= 15_000
    info = inspect_mesh(V, F)
    assert info.n_components == 1
    assert info.closed and info.euler_characteristic == 2
    assert info.problems == []
    assert info.negative_weight_share < 0.02
    assert min_angle_degrees(V, F) > 25.0
    assert signed_volume(V, F) > 0  # outward orientation
    # Standing on y = 0, centred on the y axis.
    assert V[:, 1].min() == pytest.approx(0.0, abs=1e-12)
    center = (V.min(axis=0) + V.max(axis=0)) / 2
    assert abs(center[0]) < 1e-9 and abs(center[2]) < 1e-9


@pytest.mark.parametrize("name", BUILTIN_MESHES)
def test_builtin_is_deterministic(name: str) -> None:
    V1, F1 = builtin_mesh(name)
    V2, F2 = builtin_mesh(name)
    np.testing.assert_array_equal(V1, V2)
    np.testing.assert_array_equal(F1, F2)


def test_shapes_have_their_sizes() -> None:
    V, F = builtin_mesh("bar")
    np.testing.assert_allclose(V.max(axis=0) - V.min(axis=0), [1, 5, 1])
    assert signed_volume(V, F) == pytest.approx(5.0)
    V, F = builtin_mesh("cylinder")
    np.testing.assert_allclose(V[:, 1].max(), 4.0)
    np.testing.assert_allclose(np.hypot(V[:, 0], V[:, 2]).max(), 0.5)
    assert signed_volume(V, F) == pytest.approx(np.pi * 0.25 * 4, rel=0.01)
    V, F = builtin_mesh("cactus")
    extent = V.max(axis=0) - V.min(axis=0)
    assert extent[1] > extent[0] > extent[2]  # tall, arms spread along x


def test_cactus_has_two_arms() -> None:
    V, _ = builtin_mesh("cactus")
    # A horizontal cut at 65% of the height crosses the trunk and both arms: three separate x intervals.
    y = 0.65 * V[:, 1].max()
    band = np.sort(V[np.abs(V[:, 1] - y) < 0.02, 0])
    gaps = np.diff(band) > 0.1
    assert int(gaps.sum()) == 2


@pytest.mark.parametrize("s", [0, 1, 3, 5])
def test_icosphere_counts(s: int) -> None:
    V, F = sphere(s)
    assert len(V) == 10 * 4**s + 2 and len(F) == 20 * 4**s
    check_mesh(V, F)
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 1.0)
    info = inspect_mesh(V, F)
    assert info.closed and info.n_components == 1 and info.problems == []
    assert signed_volume(V, F) > 0


def test_sphere_by_frequency_and_radius() -> None:
    k = sphere_frequency_for(100_000)
    V, F = sphere(frequency=k, radius=2.0)
    assert abs(len(V) - 100_000) < 0.02 * 100_000
    np.testing.assert_allclose(np.linalg.norm(V, axis=1), 2.0)
    check_mesh(V, F)
    assert min_angle_degrees(V, F) > 45.0
    with pytest.raises(ValueError, match="frequency"):
        sphere(frequency=0)


@pytest.mark.parametrize(("build", "share"), [
    (lambda seed: obtuse_cylinder(seed, spacing=0.1), 0.185),
    (lambda seed: scan_blob(seed, n=1500), 0.207),
])
def test_obtuse_meshes_are_clean_and_seeded(build: Callable[[int], tuple], share: float) -> None:
    V, F = build(0)
    V2, F2 = check_mesh(V, F)
    np.testing.assert_array_equal(F2, F)
    np.testing.assert_array_equal(V2, V)
    info = inspect_mesh(V, F)
    assert info.n_components == 1 and info.closed and info.euler_characteristic == 2
    assert info.problems == []
    assert signed_volume(V, F) > 0  # outward orientation
    assert info.negative_weight_share == pytest.approx(share, abs=0.001)  # as the docstrings say
    again = build(0)
    np.testing.assert_array_equal(again[0], V)
    np.testing.assert_array_equal(again[1], F)
    assert not np.array_equal(build(1)[0], V)


def test_obtuse_mesh_options_are_checked() -> None:
    with pytest.raises(ValueError, match="squash"):
        obtuse_cylinder(squash=0.0)
    with pytest.raises(ValueError, match="n >= 20"):
        scan_blob(n=10)


def test_the_sphere_names_of_the_command_line_are_built_in_meshes_too() -> None:
    """``arap --help`` lists ``sphere`` and ``sphere:N`` among the built-in meshes: the library takes them as well."""
    from arap.meshes.shapes import DEFAULT_SPHERE_SUBDIVISIONS

    V, F = builtin_mesh("sphere")
    V0, F0 = sphere(DEFAULT_SPHERE_SUBDIVISIONS)
    assert len(V) == 40_962 and np.array_equal(V, V0) and np.array_equal(F, F0)
    V, F = builtin_mesh("sphere:1000")
    assert len(V) == 1002 and len(F) == 2000
    assert builtin_mesh("sphere:1_000")[0].shape == (1002, 3)
    for bad, words in [("sphere:x", "bad sphere size"), ("sphere:3", "fewer vertices"),
                       ("sphere:99999999999", "more than"), ("spheres", "sphere:N")]:
        with pytest.raises(OptionError, match=words):
            builtin_mesh(bad)
