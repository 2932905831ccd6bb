"""Every bad input to the solver raises its specific error with a clear message."""

from __future__ import annotations

import numpy as np
import pytest

from arap.errors import ArapError, ConstraintError, UnconstrainedRegionError
from arap.solve.solver import ArapSolver


def test_out_of_range_constraint(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ConstraintError, match="out of range"):
        ArapSolver(V, F, [0, len(V)])
    with pytest.raises(ConstraintError, match="out of range"):
        ArapSolver(V, F, [-1, 3])


def test_duplicate_constraint(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ConstraintError, match="more than once"):
        ArapSolver(V, F, [1, 2, 1])


def test_non_integer_indices(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ConstraintError, match="integer"):
        ArapSolver(V, F, [0.5, 2])
    with pytest.raises(ConstraintError, match="flat list"):
        ArapSolver(V, F, [[0, 1]])


def test_targets_of_wrong_shape_or_not_finite(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    solver = ArapSolver(V, F, [0, 1, 2])
    with pytest.raises(ConstraintError, match=r"shape \(3, 3\)"):
        solver.solve(np.zeros((2, 3)))
    with pytest.raises(ConstraintError, match=r"shape \(3, 3\)"):
        solver.solve(np.zeros((3, 2)))
    bad = V[[0, 1, 2]].copy()
    bad[1, 2] = np.nan
    with pytest.raises(ConstraintError, match="row 1"):
        solver.solve(bad)


def test_no_constraint_at_all(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(UnconstrainedRegionError, match=f"{len(V)} free vertices"):
        ArapSolver(V, F, [])


def test_component_without_constraint_is_named(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    V2 = np.concatenate([V, V + np.array([3.0, 0.0, 0.0])])
    F2 = np.concatenate([F, F + len(V)])
    with pytest.raises(UnconstrainedRegionError) as info:
        ArapSolver(V2, F2, [0, 1, 2])
    assert info.value.size == len(V)
    assert all(v >= len(V) for v in info.value.vertices)
    assert isinstance(info.value, ArapError)


def test_every_part_without_constraint_is_counted(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    """Floating islands: the message names the largest part and says how many more there are."""
    V, F = icosphere
    copies = [V + np.array([3.0 * k, 0.0, 0.0]) for k in range(4)]
    with pytest.raises(UnconstrainedRegionError, match=rf"and so are 2 more such parts \({2 * len(V)} vertices\); "
                                                       "add an anchor or handle to each$"):
        ArapSolver(np.concatenate(copies), np.concatenate([F + k * len(V) for k in range(4)]), [0])


def test_roi_part_without_constraint(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    V2 = np.concatenate([V, V + np.array([3.0, 0.0, 0.0])])
    F2 = np.concatenate([F, F + len(V)])
    roi = np.arange(len(V), 2 * len(V))
    with pytest.raises(UnconstrainedRegionError, match="region of interest"):
        ArapSolver(V2, F2, [0], roi=roi)


def test_bad_options(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    with pytest.raises(ValueError, match="energy"):
        ArapSolver(V, F, [0], energy="elastic")
    with pytest.raises(ValueError, match="weights"):
        ArapSolver(V, F, [0], weights="mean_value")
    solver = ArapSolver(V, F, [0])
    with pytest.raises(ValueError, match="max_iterations"):
        solver.solve(V[[0]], max_iterations=-1)
    with pytest.raises(ValueError, match="initial"):
        solver.solve(V[[0]], initial=V[:10])


def test_targets_initial_and_point_targets_that_are_not_numbers(icosphere: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = icosphere
    solver = ArapSolver(V, F, [0, 1], points=([5], [[1, 0, 0]]))
    P = [[0.0, 0.0, 0.0]]
    with pytest.raises(ConstraintError, match=r"targets must be numbers: \(2, 3\) floats, one row per constrained"):
        solver.solve([["a", 0, 0], [1, 1, 1]], point_targets=P)
    with pytest.raises(ConstraintError, match=r"targets must be numbers"):
        solver.solve([[0, 0], [1, 1, 1]], point_targets=P)  # ragged
    with pytest.raises(ConstraintError, match=r"targets must be numbers"):
        solver.solve({"a": 1}, point_targets=P)
    with pytest.raises(ConstraintError, match=r"targets must be real numbers, got complex128"):
        solver.solve(V[[0, 1]] * (1 + 1j), point_targets=P)
    with pytest.raises(ConstraintError, match=r"point_targets must be numbers"):
        solver.solve(V[[0, 1]], point_targets=[["x", 0, 0]])
    with pytest.raises(ConstraintError, match=r"the targets lie too far from the mesh: with them, the coordinates"):
        solver.solve([[1e300, 0, 0], [1, 1, 1]], point_targets=P)  # gave NaN energies, not converged, no error
    with pytest.raises(ConstraintError, match=r"the point targets lie too far from the mesh"):
        solver.solve(V[[0, 1]], point_targets=[[0, -1e300, 0]])
    with pytest.raises(ArapError, match=r"initial must be numbers"):
        solver.solve(V[[0, 1]], point_targets=P, initial=np.full((len(V), 3), "a"))
