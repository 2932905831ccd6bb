"""Constraint files: which vertices stay at rest, which move where.

The JSON format::

    {
      "fixed":   [0, 1, 2],                     # vertices held at their rest positions
      "handles": [40, 41],                      # vertices moved to targets
      "targets": [[0.0, 5.2, 0.1], [0.1, 5.2, 0.0]],   # one [x, y, z] per handle, same order
      "roi":     [0, 1, 2, 3, ...],             # optional region of interest (only these vertices move)
      "handle_groups": [[40, 41]],              # optional, informative (how an editor grouped the handles; each
                                                #   handle in one group at most)
      "stiffness": [{"vertices": [7, 8], "value": 10.0},      # optional (version 2): per-vertex cell weights,
                    {"vertices": [9], "value": "rigid"}],     # 1 where not given; "rigid" keeps a region rigid
      "points": [{"face": 12, "barycentric": [0.2, 0.3, 0.5],        # optional (version 2): handles inside
                  "target": [0.0, 5.0, 0.1], "weight": 10.0,         # triangles; no "weight": a hard one;
                  "angle": 30.0, "depth": 1}],                       # a picture's pin: the angle it holds and
                                                                     #   its depth (optional, the studio's)
      "version": 2,                             # optional: 1 (the default) or 2 (for "stiffness", "points")
      "meta": {...},                            # optional, free-form, ignored
      "keyframes": [...]                        # optional: poses over time for arap animate
      (arap.constraints.keyframes);
    }                                           #   ignored here, with "keyframe_base"

``stiffness`` may also be a list of one number (or ``"rigid"``) per vertex. Files without ``version`` are version 1
and load as before.

A picture's pin (a point handle of the studio's picture mesh) may carry the angle it holds (``"angle"``, degrees,
counter-clockwise as seen, from the picture as opened; left out: its surroundings turn freely with the bend) and its
depth (``"depth"``, an integer: where the warped parts overlap, the part of the pin of larger depth is drawn over
the other; left out: 0), as the studio's **Save constraints** writes them and its loading restores them
(:data:`arap.constraints.entries.PIN_KEYS`). ``arap deform``, ``arap batch`` and ``arap animate`` hold the angles on
a flat mesh with the studio's hidden rings (:func:`arap.puppet.rings.held_points`; ``arap animate`` also a keyframe's
``"point_angles"``, :mod:`arap.constraints.keyframes`) and refuse them elsewhere; depths only concern drawing, and
they ignore them.

Indices are 0-based in the mesh file's vertex order. ``fixed`` or ``handles`` may be omitted or empty, but not both.
Handles may lie outside the region of interest: like every constrained vertex they go to their targets, while the
unconstrained vertices outside the region stay at rest.

:func:`arap.constraints.selection.check_selection` is the one validator of vertex selections: this module, the command
line and the studio (:mod:`arap.server.constraints`) all use it, so the same bad selection gets the same answer
everywhere.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from arap.constraints.entries import (
    pin_entries,
    pins_from_json,
    points_and_targets,
    points_from_json,
    stiffness_from_json,
    stiffness_to_json,
)
from arap.constraints.selection import check_listed_targets, check_selection
from arap.errors import ConstraintError
from arap.io.atomic import write_atomic
from arap.io.paths import read_regular_file
from arap.meshes.mesh import bounding_box
from arap.method.points import PointConstraints
from arap.solve.indexing import check_index_array
from arap.solve.partition import check_reach

__all__ = [
    "FORMAT_VERSION",
    "Constraints",
    "check_listed_targets",
    "check_selection",
    "load_constraints",
    "points_from_json",
    "read_json",
    "save_constraints",
    "stiffness_from_json",
    "stiffness_to_json",
]

_KEYS = ("fixed", "handles", "targets", "roi", "handle_groups", "stiffness", "points", "version", "meta", "keyframes",
         "keyframe_base")
"""Keys a constraints document may hold; ``keyframes`` and ``keyframe_base`` (:mod:`arap.constraints.keyframes`) are
read by ``arap animate`` and ignored here, so a document with keyframes also deforms to its ``targets``."""

FORMAT_VERSION = 2
"""Newest constraints file format (2 added ``stiffness``); files of every version up to it load."""


@dataclass
class Constraints:
    """A validated constraint set.

    Attributes
    ----------
    fixed : (f,) int64 array
        Vertices held at their rest positions.
    handles : (h,) int64 array
        Vertices moved to ``targets``.
    targets : (h, 3) float64 array
        Target position of each handle, in the order of ``handles``.
    roi : (r,) int64 array or None
        Region of interest, or None for the whole mesh.
    handle_groups : list of list of int or None
        Optional grouping of the handles (kept for round trips, not used by the solver).
    stiffness : (n,) float64 array or None
        Per-vertex cell weights for :class:`arap.ArapSolver` (``inf``: rigid), or None for all 1.
    points : PointConstraints or None
        Handles inside triangles (:mod:`arap.method.points`).
    point_targets : (p, 3) float64 array or None
        Their targets.
    pin_angles : list of float or None, or None
        Per point handle (a picture's pin), the angle in degrees it holds, or None (turns freely); None when none
        holds one.
    pin_depth : list of int or None
        Per point handle, its depth (larger: drawn over the others where the warped parts overlap); None when the
        document gives none.

    Examples
    --------
    >>> import arap
    >>> c = arap.load_constraints({"fixed": [0, 1], "handles": [5], "targets": [[0.0, 2.0, 0.0]]}, n_vertices=42)
    >>> c.constrained.tolist(), c.targets.tolist()
    ([0, 1, 5], [[0.0, 2.0, 0.0]])
    """

    fixed: np.ndarray
    handles: np.ndarray
    targets: np.ndarray
    roi: np.ndarray | None = None
    handle_groups: list[list[int]] | None = None
    stiffness: np.ndarray | None = None
    points: PointConstraints | None = None
    point_targets: np.ndarray | None = None
    pin_angles: list[float | None] | None = None
    pin_depth: list[int] | None = None

    @property
    def constrained(self) -> np.ndarray:
        """Fixed vertices then handles, shape (f + h,): the order of :meth:`indices_and_targets`."""
        return np.concatenate([self.fixed, self.handles])

    def indices_and_targets(self, V: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Constrained vertices and their targets, fixed vertices at their rest positions.

        Parameters
        ----------
        V : (n, 3) float array
            Rest positions.

        Returns
        -------
        indices : (f + h,) int64 array
            ``fixed`` then ``handles``.
        targets : (f + h, 3) float64 array

        Raises
        ------
        ConstraintError
            The targets (of the point handles too) and the mesh together span more than
            :data:`arap.meshes.mesh.SIZE_RANGE` allows (targets absurdly far away).
        """
        V = np.asarray(V, dtype=np.float64)
        points = np.zeros((0, 3)) if self.point_targets is None else self.point_targets
        if len(V):
            check_reach(bounding_box(V), np.concatenate([self.targets, points]).reshape(-1, 3))
        return self.constrained, np.concatenate([V[self.fixed], self.targets]).reshape(-1, 3)

    def remapped(self, vertex_map: np.ndarray) -> Constraints:
        """The same constraints after a vertex renumbering (e.g. :attr:`arap.meshes.repair.RepairResult.vertex_map`).

        Copies of one vertex that repair welded together (an STL triangle soup has one per triangle) count once
        when they agree: fixed copies, or handle copies with the same target.

        Raises
        ------
        ConstraintError
            A constrained vertex was dropped (maps to -1; region-of-interest vertices may be), or welded copies
            disagree (a fixed copy and a handle copy, handle copies with different targets, or copies with different
            stiffness).
        """
        vertex_map = np.asarray(vertex_map, dtype=np.int64)

        def remap(name: str, idx: np.ndarray) -> np.ndarray:
            out = vertex_map[idx]
            if (out < 0).any():
                bad = idx[out < 0]
                raise ConstraintError(f"{len(bad)} {name} vertices were removed by mesh repair "
                                      f"(unused or invalid), first: {int(bad[0])}")
            return out

        if self.points is not None and len(self.points):
            raise ConstraintError("point handles refer to the file's triangles, which mesh repair changed; repair the "
                                  "mesh file first (arap info shows what repair changes)")
        fixed = remap("fixed", self.fixed)
        handles = remap("handle", self.handles)
        fixed = fixed[np.sort(np.unique(fixed, return_index=True)[1])]
        welded_with_fixed = np.isin(handles, fixed)
        if welded_with_fixed.any():
            k = int(np.argmax(welded_with_fixed))
            raise ConstraintError(f"mesh repair welded handle vertex {int(self.handles[k])} with a fixed vertex at the "
                                  "same position; a vertex cannot be both")
        first = np.sort(np.unique(handles, return_index=True)[1])
        keep = np.zeros(len(handles), dtype=bool)
        keep[first] = True
        if not keep.all():
            where = {int(v): int(j) for j, v in zip(first, handles[first], strict=True)}
            tol = 1e-12 * max(float(np.abs(self.targets).max(initial=0.0)), 1.0)
            for c in np.flatnonzero(~keep):
                i = where[int(handles[c])]
                if np.abs(self.targets[c] - self.targets[i]).max() > tol:
                    raise ConstraintError(
                        f"mesh repair welded handle vertices {int(self.handles[i])} and {int(self.handles[c])} (copies "
                        f"of one vertex) but their targets differ: {self.targets[i].tolist()} and "
                        f"{self.targets[c].tolist()}")
        # a region of interest may name vertices repair dropped (used by no face): they have no cell to move
        roi = None if self.roi is None else np.unique(vertex_map[self.roi][vertex_map[self.roi] >= 0])
        groups = None
        if self.handle_groups is not None:
            taken: set[int] = set()
            groups = []
            for g in self.handle_groups:
                welded = [int(vertex_map[i]) for i in g]
                groups.append([v for v in dict.fromkeys(welded) if v not in taken])
                taken.update(welded)
        stiffness = None
        if self.stiffness is not None:
            kept = np.flatnonzero(vertex_map >= 0)
            stiffness = np.ones(int(vertex_map.max(initial=-1)) + 1)
            stiffness[vertex_map[kept]] = self.stiffness[kept]
            differs = stiffness[vertex_map[kept]] != self.stiffness[kept]
            if differs.any():
                one = int(kept[np.argmax(differs)])
                copies = kept[vertex_map[kept] == vertex_map[one]]
                pair = sorted((one, int(copies[self.stiffness[copies] != self.stiffness[one]][0])))
                a, b = ("rigid" if math.isinf(self.stiffness[k]) else f"{self.stiffness[k]:g}" for k in pair)
                raise ConstraintError(f"mesh repair welded vertices {pair[0]} and {pair[1]} (copies of one vertex) "
                                      f"but their stiffness differs: {a} and {b}")
        return Constraints(fixed, handles[keep], self.targets[keep].copy(), roi, groups, stiffness)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary in the file format."""
        out: dict[str, Any] = {
            "fixed": [int(i) for i in self.fixed],
            "handles": [int(i) for i in self.handles],
            "targets": [[float(x) for x in row] for row in self.targets],
        }
        if self.roi is not None:
            out["roi"] = [int(i) for i in self.roi]
        if self.handle_groups is not None:
            out["handle_groups"] = [[int(i) for i in g] for g in self.handle_groups]
        if self.points is not None and self.point_targets is not None and len(self.points):
            out["version"] = FORMAT_VERSION
            out["points"] = pin_entries([
                {"face": int(f), "barycentric": [float(x) for x in b], "target": [float(x) for x in t]}
                | ({} if np.isinf(w) else {"weight": float(w)})
                for f, b, t, w in zip(self.points.faces, self.points.barycentric, self.point_targets,
                                      self.points.weights, strict=True)
            ], self.pin_angles, self.pin_depth)
        if self.stiffness is not None:
            out["version"] = FORMAT_VERSION
            out["stiffness"] = stiffness_to_json(self.stiffness)
        return out


#: Longest integer literal read from a constraints file (Python refuses to convert more than 4,300 digits).
_MAX_INT_DIGITS = 400


def read_json(path: Path) -> Any:
    """A JSON document of this module's kind (constraints, keyframes), refusing what is not plain JSON data."""
    try:
        text = read_regular_file(path).decode("utf-8")  # a FIFO or a device is refused before it is opened
    except OSError as exc:
        raise ConstraintError(f"cannot read constraints file {path}: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise ConstraintError(f"constraints file {path} is not UTF-8 text") from exc

    def reject(name: str) -> float:
        raise ConstraintError(f"constraints file {path} contains {name}, which is not valid JSON")

    def integer(digits: str) -> int | float:
        if len(digits) > _MAX_INT_DIGITS:
            raise ConstraintError(f"constraints file {path} contains an integer of {len(digits.lstrip('-')):,} "
                                  "digits, far beyond any vertex index or coordinate")
        return int(digits)

    try:
        return json.loads(text, parse_constant=reject, parse_int=integer)
    except json.JSONDecodeError as exc:
        raise ConstraintError(f"constraints file {path} is not valid JSON: {exc.msg} at line {exc.lineno}, "
                              f"column {exc.colno}") from exc
    except RecursionError:
        raise ConstraintError(f"constraints file {path} nests lists or objects too deeply to be a "
                              "constraints file") from None


def load_constraints(source: str | os.PathLike[str] | Mapping[str, Any], n_vertices: int,
                     n_faces: int | None = None) -> Constraints:
    """Read and validate a constraint set against a mesh of ``n_vertices`` vertices.

    Parameters
    ----------
    source : path-like or mapping
        A JSON file in the format of this module, or the already parsed object.
    n_vertices : int
        Vertex count of the mesh the indices refer to.
    n_faces : int or None
        Triangle count of that mesh; needed for files with point handles.

    Returns
    -------
    Constraints

    Raises
    ------
    ConstraintError
        Unreadable or invalid JSON (nested too deeply, integers of hundreds of digits included), unknown keys, and
        what :func:`check_selection` and :func:`check_listed_targets` refuse, a pin's angle that is not a finite
        number or depth that is not an integer, or no constraint at all.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> c = arap.load_constraints({"fixed": [0, 1], "handles": [5], "targets": [[0.0, 2.0, 0.0]]}, len(V))
    >>> indices, targets = c.indices_and_targets(V)             # fixed vertices at rest, then the handles
    >>> result = arap.ArapSolver(V, F, indices).solve(targets)
    >>> bool(result.converged), result.vertices[5].round(6).tolist()
    (True, [0.0, 2.0, 0.0])
    """
    data = source if isinstance(source, Mapping) else read_json(Path(source))
    if not isinstance(data, Mapping):
        raise ConstraintError(f"constraints must be a JSON object, got {type(data).__name__}")
    unknown = sorted(str(key)[:40] for key in set(data) - set(_KEYS))
    if unknown:
        raise ConstraintError(f"unknown constraint keys {unknown}; expected some of {list(_KEYS)}")
    if "fixed" not in data and "handles" not in data and not data.get("points"):
        raise ConstraintError('constraints need "fixed" and/or "handles" vertex lists (or "points")')
    n = int(n_vertices)
    handles = check_index_array(data.get("handles", []), n, "handles")
    fixed, _, roi = check_selection(n, data.get("fixed", []), [handles] if len(handles) else [], data.get("roi"),
                                    group_names=["handles"] if len(handles) else [])
    if len(handles) and "targets" not in data:
        raise ConstraintError('"handles" are given without "targets"')
    targets = check_listed_targets(data.get("targets", []), len(handles))
    if not len(fixed) and not len(handles) and not data.get("points"):
        raise ConstraintError("no vertex is constrained: give at least one fixed or handle vertex")

    handle_groups = None
    if data.get("handle_groups") is not None:
        raw = data["handle_groups"]
        if not isinstance(raw, list | tuple):
            raise ConstraintError("handle_groups must be a list of lists of vertex indices")
        handle_groups = [[int(i) for i in check_index_array(g, n, f"handle_groups[{k}]")] for k, g in enumerate(raw)]
        _check_handle_groups(handle_groups, handles)
    if "meta" in data and not isinstance(data["meta"], Mapping):
        raise ConstraintError("meta must be a JSON object")
    version = data.get("version", 1)
    if type(version) is not int:
        raise ConstraintError(f"constraints file version must be a JSON integer (1 to {FORMAT_VERSION}), got "
                              f"{json.dumps(version, default=repr)[:20]}")
    if not 1 <= version <= FORMAT_VERSION:
        raise ConstraintError(f"unsupported constraints file version {str(version)[:20]}; this arap reads versions "
                              f"1 to {FORMAT_VERSION}")
    stiffness = None
    if data.get("stiffness") is not None:
        if version < 2:
            raise ConstraintError('"stiffness" needs "version": 2')
        stiffness = stiffness_from_json(data["stiffness"], n)
    points, point_targets = None, None
    angles, depth = None, None
    if data.get("points") is not None:
        if version < 2:
            raise ConstraintError('"points" needs "version": 2')
        if n_faces is None:
            raise ConstraintError("point handles need the mesh's triangle count")
        points, point_targets = points_and_targets(data["points"], int(n_faces))
        angles, depth = pins_from_json(data["points"])
    return Constraints(fixed=fixed, handles=handles, targets=targets, roi=roi, handle_groups=handle_groups,
                       stiffness=stiffness, points=points, point_targets=point_targets, pin_angles=angles,
                       pin_depth=depth)


def _check_handle_groups(groups: list[list[int]], handles: np.ndarray) -> None:
    """Handle groups name handles only, each in one group (as the studio, which reads them, requires)."""
    is_handle = set(handles.tolist())
    group_of: dict[int, int] = {}
    for k, g in enumerate(groups):
        for i in g:
            if i not in is_handle:
                raise ConstraintError(f'handle_groups[{k}] names vertex {i}, which is not in "handles"; groups '
                                      'list handle vertices (or leave "handle_groups" out)')
            if i in group_of:
                raise ConstraintError(f"vertex {i} is in handle_groups[{group_of[i]}] and handle_groups[{k}]; a "
                                      "handle belongs to one group")
            group_of[i] = k


def save_constraints(path: str | os.PathLike[str], constraints: Constraints) -> None:
    """Write a constraint set as JSON (readable by :func:`load_constraints`), atomically (an earlier file stays
    intact until the complete new one replaces it).

    Raises
    ------
    ConstraintError
        Non-finite targets (JSON has no NaN) or the file cannot be written.

    Examples
    --------
    >>> import os, tempfile, arap
    >>> c = arap.load_constraints({"fixed": [0, 1], "handles": [5], "targets": [[0.0, 2.0, 0.0]]}, n_vertices=42)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "pose.json")
    ...     arap.save_constraints(path, c)
    ...     again = arap.load_constraints(path, n_vertices=42)
    >>> again.handles.tolist(), again.fixed.tolist()
    ([5], [0, 1])
    """
    data = constraints.to_dict()
    if not all(math.isfinite(x) for row in data["targets"] for x in row):
        raise ConstraintError("cannot save non-finite targets")
    try:
        write_atomic(path, json.dumps(data) + "\n")
    except OSError as exc:
        raise ConstraintError(f"cannot write constraints file {path}: {exc.strerror or exc}") from exc
