"""The entries of a constraints document that are more than vertex lists: point handles (a triangle, barycentric
coordinates, an optional weight and target each; in a document, a picture's pin may also carry the angle it holds
and its depth) and painted stiffness (groups of vertices with a positive value or
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

__all__ = ["PIN_KEYS", "pin_entries", "pins_from_json", "points_and_targets", "points_from_json",
           "stiffness_from_json", "stiffness_to_json"]

#: Largest finite double: larger JSON integers are not numbers a coordinate or weight can take.
_FLOAT_MAX = sys.float_info.max

PIN_KEYS = ("angle", "depth")
"""What a point handle of a constraints document may carry besides its place, target and weight: a picture's pin's
``"angle"`` (degrees, counter-clockwise as seen, from the picture as opened: the studio's ``set_pin_angle``; left
out: its surroundings turn freely) and ``"depth"`` (an integer: where the pins' parts overlap, the part of the pin of
larger depth is drawn over the other: ``set_pin_depth``; left out: 0). They are the per-pin values the studio's
autosaved session keeps (``pins``: ``angles`` and ``depth``)."""


def points_and_targets(raw: Any, n_faces: int) -> tuple[PointConstraints, np.ndarray]:
    """Point handles of a file: ``[{"face", "barycentric", "target", optional "weight", "angle", "depth"}, ...]``
    (:data:`PIN_KEYS`: read by :func:`pins_from_json`)."""
    points, targets, _ = points_from_json(raw, n_faces, pin_keys=True)
    return points, targets


def pins_from_json(raw: list[Any]) -> tuple[list[float | None] | None, list[int] | None]:
    """The angles and depths of a document's point handles (:data:`PIN_KEYS`), already read by
    :func:`points_from_json`.

    Returns
    -------
    angles : list of float or None, or None
        Per point handle, the angle in degrees it holds or None (turns freely); None when no point gives one.
    depth : list of int, or None
        Per point handle, its depth (0 where not given); None when no point gives one.

    Raises
    ------
    ConstraintError
        An angle that is not a finite number, a depth that is not an integer.
    """
    angles: list[float | None] = []
    depth: list[int] = []
    for k, item in enumerate(raw):
        a = item.get("angle")
        if a is not None and (type(a) not in (int, float) or not -_FLOAT_MAX <= a <= _FLOAT_MAX):
            raise ConstraintError(f"points[{k}].angle must be a finite number of degrees (or left out: the pin turns "
                                  f"freely), got {json.dumps(a, default=repr)[:40]}")
        d = item.get("depth", 0)
        if type(d) is not int or abs(d) > 2**31:
            raise ConstraintError(f"points[{k}].depth must be an integer (larger: drawn over the others), got "
                                  f"{json.dumps(d, default=repr)[:40]}")
        angles.append(None if a is None else float(a))
        depth.append(d)
    return (angles if any(a is not None for a in angles) else None,
            depth if any("depth" in item for item in raw) else None)


def pin_entries(points: list[dict[str, Any]], angles: list[float | None] | None,
                depth: list[int] | None) -> list[dict[str, Any]]:
    """``points`` (a document's point handles) with each pin's ``"angle"`` (when not None) and ``"depth"`` (when
    ``depth`` is given; pins beyond it: 0): the entries :func:`pins_from_json` reads."""
    out = []
    for k, item in enumerate(points):
        item = dict(item)
        if angles is not None and k < len(angles) and angles[k] is not None:
            item["angle"] = float(angles[k])  # type: ignore[arg-type]
        if depth:
            item["depth"] = int(depth[k]) if k < len(depth) else 0
        out.append(item)
    return out


def points_from_json(raw: Any, n_faces: int, *, require_target: bool = True, pin_keys: bool = False
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
    allowed = {"face", "barycentric", "target", "weight", *(PIN_KEYS if pin_keys else ())}
    faces, bary, targets, weights, given = [], [], [], [], []
    for k, item in enumerate(raw):
        if not isinstance(item, Mapping) or not required <= set(item) or not set(item) <= allowed:
            what = '"target" and optionally "weight"' if require_target else 'optionally "target" and "weight"'
            if pin_keys:
                what = '"target" and optionally "weight", "angle" and "depth"'
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
