"""The entries of a constraints document that are more than vertex lists: point handles (a triangle, barycentric
coordinates, an optional weight and target each) and painted stiffness (groups of vertices with a positive value or
``"rigid"``), checked and converted to and from JSON. The constraints document (:mod:`arap.constraints.document`)
and the studio (:mod:`arap.server.constraints`) both use them.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Mapping
from typing import Any

import numpy as np

from arap.constraints.selection import check_listed_targets
from arap.errors import ConstraintError
from arap.method.points import PointConstraints, check_points
from arap.solve.indexing import check_index_array

__all__ = ["points_and_targets", "points_from_json", "stiffness_from_json", "stiffness_to_json"]

#: Largest finite double: larger JSON integers are not numbers a coordinate or weight can take.
_FLOAT_MAX = sys.float_info.max


def points_and_targets(raw: Any, n_faces: int) -> tuple[PointConstraints, np.ndarray]:
    """Point handles of a file: ``[{"face", "barycentric", "target", optional "weight"}, ...]``."""
    points, targets, _ = points_from_json(raw, n_faces)
    return points, targets


def points_from_json(raw: Any, n_faces: int, *, require_target: bool = True
                     ) -> tuple[PointConstraints, np.ndarray, np.ndarray]:
    """Point handles from ``[{"face", "barycentric", "target", optional "weight"}, ...]``: the one validator of
    point handles in JSON (constraints files and the studio's ``set_constraints``).

    Parameters
    ----------
    raw : Any
        The decoded list.
    n_faces : int
        Triangle count of the mesh.
    require_target : bool
        Whether every point must carry a ``"target"`` (files: yes; the studio: optional, a point without one
        stays where the surface puts it).

    Returns
    -------
    points : PointConstraints
    targets : (p, 3) float64 array
        The targets given (rows of points without one are 0).
    given : (p,) bool array
        Which points carry a target.

    Raises
    ------
    ConstraintError
        Not a list of such objects, and what :func:`arap.method.points.check_points` and
        :func:`check_listed_targets` refuse.
    """
    if not isinstance(raw, list):
        raise ConstraintError("points must be a list")
    required = {"face", "barycentric", "target"} if require_target else {"face", "barycentric"}
    faces, bary, targets, weights, given = [], [], [], [], []
    for k, item in enumerate(raw):
        if not isinstance(item, Mapping) or not required <= set(item) or \
                not set(item) <= {"face", "barycentric", "target", "weight"}:
            what = '"target" and optionally "weight"' if require_target else 'optionally "target" and "weight"'
            raise ConstraintError(f'points[{k}] must be an object with "face", "barycentric", {what}')
        if type(item["face"]) is not int:
            raise ConstraintError(f"points[{k}].face must be an integer triangle index")
        if not 0 <= item["face"] < n_faces:  # compared as Python integers: 10**30 must not overflow int64
            raise ConstraintError(f"point face {str(item['face'])[:40]} out of range 0..{n_faces - 1}")
        b = item["barycentric"]
        if not isinstance(b, list | tuple) or len(b) != 3 or not all(
                type(x) in (int, float) for x in b):
            raise ConstraintError(f"points[{k}].barycentric must be a list of 3 numbers")
        faces.append(item["face"])
        bary.append(b)
        given.append("target" in item)
        targets.append(item["target"] if "target" in item else [0.0, 0.0, 0.0])
        w = item.get("weight", math.inf)
        if type(w) not in (int, float):
            raise ConstraintError(f"points[{k}].weight must be a positive number")
        if type(w) is int and abs(w) > _FLOAT_MAX:
            raise ConstraintError(f"points[{k}].weight is too large for a number (beyond 1.8e308); leave "
                                  '"weight" out for a hard handle')
        weights.append(float(w))
    points = check_points(np.asarray(faces, dtype=np.int64), bary, weights, n_faces)
    return points, check_listed_targets(targets, len(faces)), np.asarray(given, dtype=bool)


def _stiffness_value(value: Any, where: str) -> float:
    if value == "rigid":
        return math.inf
    if type(value) not in (int, float) or not -_FLOAT_MAX <= value <= _FLOAT_MAX or value <= 0:
        raise ConstraintError(f'{where} must be a positive number or "rigid", got {json.dumps(value)[:40]}')
    return float(value)


def stiffness_to_json(stiffness: np.ndarray) -> list[dict[str, Any]]:
    """Per-vertex stiffness (n,) as ``[{"vertices": [...], "value": v}, ...]`` (vertices at 1 left out, ``inf`` as
    ``"rigid"``): the form of constraints files and of the studio's messages."""
    return [
        {"vertices": np.flatnonzero(stiffness == value).tolist(),
         "value": "rigid" if math.isinf(value) else float(value)}
        for value in np.unique(stiffness[stiffness != 1.0])
    ]


def stiffness_from_json(raw: Any, n: int) -> np.ndarray:
    """Per-vertex stiffness, shape (n,), from n values or ``[{"vertices": [...], "value": v}, ...]`` (1 elsewhere,
    so ``[]`` is all 1; ``"rigid"`` is ``inf``): the one validator of painted stiffness (files, command line,
    studio).

    Raises
    ------
    ConstraintError
        Not such a list, a value that is not a positive number or ``"rigid"``, bad vertex indices, or a vertex
        given two values.
    """
    if not isinstance(raw, list):
        raise ConstraintError("stiffness must be a list")
    if raw and all(not isinstance(item, Mapping) for item in raw):
        if len(raw) != n:
            raise ConstraintError(f"stiffness lists one value per vertex: {n} expected, {len(raw)} given")
        return np.array([_stiffness_value(v, f"stiffness[{i}]") for i, v in enumerate(raw)])
    out = np.ones(n)
    seen = np.zeros(n, dtype=bool)
    for k, item in enumerate(raw):
        if not isinstance(item, Mapping) or set(item) != {"vertices", "value"}:
            raise ConstraintError(f'stiffness[{k}] must be an object with "vertices" and "value"')
        idx = check_index_array(item["vertices"], n, f"stiffness[{k}].vertices")
        if seen[idx].any():
            raise ConstraintError(f"vertex {int(idx[seen[idx]][0])} is given two stiffness values")
        seen[idx] = True
        out[idx] = _stiffness_value(item["value"], f"stiffness[{k}].value")
    return out
