"""Constraints without the studio: vertices picked by where they lie, handles moved or turned by a given amount.

A selector is a condition on a vertex's position, with ``x``, ``y`` and ``z`` measured across the mesh's bounding box
(0 at its lowest, 1 at its highest along that axis), so that ``y<0.1`` is the lowest tenth of the mesh whatever its
size and units. Conditions compare one coordinate with a number (``<``, ``<=``, ``>``, ``>=``), may chain
(``0.4<x<0.6``) and combine with ``&`` (and) and ``|`` (or), ``&`` binding first; ``all`` picks every vertex.
``X``, ``Y`` and ``Z`` (capitals) are the coordinates themselves, in mesh units.

>>> import numpy as np
>>> V = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 2.0, 0.0]])
>>> select(V, "y<0.25").tolist(), select(V, "y>0.9 & x<0.5").tolist(), select(V, "Y>=1 | x>0.5").tolist()
([0], [2], [1, 2, 3])

:func:`constraints_from_selectors` turns selectors into a constraint set: fixed vertices, and handle groups each
moved by a translation and turned about its centroid (``--fix``, ``--handle``, ``--move``, ``--rotate`` of
``arap constraints`` and ``arap deform``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from arap.constraints import Constraints, check_selection
from arap.errors import ConstraintError, OptionError
from arap.meshes.mesh import bounding_box

__all__ = ["HandleSpec", "constraints_from_selectors", "parse_rotation", "parse_vector", "select"]

_TOKEN = re.compile(r"\s*(?:(?P<num>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|(?P<op><=|>=|<|>)|(?P<axis>[xyzXYZ])"
                    r"|(?P<join>[&|])|(?P<word>and|or|all))")
MAX_SELECTOR = 1000
"""Longest selector, in characters."""


def _tokens(text: str) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    pos = 0
    text = text.strip()
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None or m.end() == pos:
            raise OptionError(f"selector {text!r}: cannot read {text[pos:pos + 12]!r}; write conditions such as "
                              "'y<0.1', '0.4<x<0.6' or 'y>0.9 & z>0.5' (x, y, z from 0 to 1 across the mesh)")
        kind = m.lastgroup or ""
        value = m.group(kind)
        if kind == "word" and value in ("and", "or"):
            kind, value = "join", "&" if value == "and" else "|"
        out.append((kind, value))
        pos = m.end()
    return out


def _condition(tokens: list[tuple[str, str]], text: str, P: NDArray[np.float64], A: NDArray[np.float64]
               ) -> NDArray[np.bool_]:
    """One chain of comparisons (``y<0.1``, ``0.2<x<=0.8``, ``0.5>z``) or ``all``."""
    if tokens == [("word", "all")]:
        return np.ones(len(P), dtype=bool)
    kinds = [k for k, _ in tokens]
    if len(tokens) not in (3, 5) or kinds[1] != "op" or (len(tokens) == 5 and kinds[3] != "op"):
        raise OptionError(f"selector {text!r}: each condition compares one coordinate with a number, as 'y<0.1' "
                          "or '0.4<x<0.6'")
    values: list[NDArray[np.float64] | float] = []
    axes = 0
    for kind, value in tokens[::2]:
        if kind == "axis":
            axes += 1
            values.append((P if value.islower() else A)[:, "xyz".index(value.lower())])
        elif kind == "num":
            number = float(value)
            if not math.isfinite(number):
                raise OptionError(f"selector {text!r}: {value} is not a finite number")
            values.append(number)
        else:
            raise OptionError(f"selector {text!r}: expected a coordinate or a number, got {value!r}")
    if axes != 1:
        raise OptionError(f"selector {text!r}: each condition names exactly one coordinate (x, y or z)")
    result = np.ones(len(P), dtype=bool)
    for (left, (_, op), right) in zip(values[:-1], tokens[1::2], values[1:], strict=True):
        test = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal}[op]
        result &= np.broadcast_to(test(left, right), (len(P),))
    return result


def select(V: NDArray[np.floating], selector: str) -> NDArray[np.int64]:
    """Vertices whose position meets ``selector`` (see the module description), in increasing order.

    Parameters
    ----------
    V : (n, 3) float array
    selector : str

    Returns
    -------
    (k,) int64 array

    Raises
    ------
    OptionError
        A selector that cannot be read.
    """
    if not isinstance(selector, str) or not selector.strip():
        raise OptionError("a selector is a condition such as 'y<0.1' (x, y, z from 0 to 1 across the mesh)")
    if len(selector) > MAX_SELECTOR:
        raise OptionError(f"a selector is at most {MAX_SELECTOR} characters")
    X: NDArray[np.float64] = np.asarray(V, dtype=np.float64)
    lo, hi = bounding_box(X)
    span = np.where(hi - lo > 0, hi - lo, 1.0)
    P = (X - lo) / span
    tokens = _tokens(selector)
    picked = np.zeros(len(X), dtype=bool)
    for alternative in _split(tokens, "|"):
        part = np.ones(len(X), dtype=bool)
        for condition in _split(alternative, "&"):
            part &= _condition(condition, selector, P, X)
        picked |= part
    return np.flatnonzero(picked).astype(np.int64)


def _split(tokens: list[tuple[str, str]], join: str) -> list[list[tuple[str, str]]]:
    parts: list[list[tuple[str, str]]] = [[]]
    for token in tokens:
        if token == ("join", join):
            parts.append([])
        else:
            parts[-1].append(token)
    if any(not p for p in parts):
        raise OptionError("a selector has an empty condition before or after '&' or '|'")
    return parts


def parse_vector(text: str) -> NDArray[np.float64]:
    """``"dx,dy,dz"`` as a (3,) array (``--move``)."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise OptionError(f"--move takes three numbers, as 0.1,0,0; got {text!r}")
    return np.array(values)


def parse_rotation(text: str) -> NDArray[np.float64]:
    """``"AXIS:DEGREES"`` (``z:30``, or ``1,1,0:45`` for any axis) as a 3×3 rotation matrix (``--rotate``)."""
    axis_text, sep, angle_text = text.rpartition(":")
    axes = {"x": [1.0, 0.0, 0.0], "y": [0.0, 1.0, 0.0], "z": [0.0, 0.0, 1.0]}
    try:
        angle = math.radians(float(angle_text))
        axis = np.array(axes[axis_text.lower()] if axis_text.lower() in axes
                        else [float(v) for v in axis_text.split(",")], dtype=np.float64)
    except (ValueError, KeyError):
        axis = np.zeros(0)
        angle = math.nan
    if not sep or axis.shape != (3,) or not np.isfinite(axis).all() or not math.isfinite(angle) \
            or np.linalg.norm(axis) == 0:
        raise OptionError(f"--rotate takes AXIS:DEGREES, as z:30 or 1,1,0:45; got {text!r}")
    k = axis / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


@dataclass(frozen=True)
class HandleSpec:
    """A handle group: the vertices ``selector`` picks, turned by ``rotation`` about their centroid and then moved
    by ``move``."""

    selector: str
    move: NDArray[np.float64] | None = None
    rotation: NDArray[np.float64] | None = None


def constraints_from_selectors(V: NDArray[np.floating], fixed: Sequence[str] = (),
                               handles: Sequence[HandleSpec] = (), roi: str | None = None) -> Constraints:
    """A constraint set from selectors: every vertex any ``fixed`` selector picks is held; each handle group is
    moved and turned as its :class:`HandleSpec` says (a vertex picked by an earlier group or as fixed stays there).

    Raises
    ------
    OptionError
        A selector that cannot be read.
    ConstraintError
        A selector that picks no vertex, or nothing constrained at all.
    """
    V = np.asarray(V, dtype=np.float64)
    taken = np.zeros(len(V), dtype=bool)
    fixed_idx: list[NDArray[np.int64]] = []
    for text in fixed:
        idx = select(V, text)
        if not len(idx):
            raise ConstraintError(f"--fix {text!r} picks no vertex")
        fixed_idx.append(idx)
        taken[idx] = True
    fixed_all = np.flatnonzero(taken).astype(np.int64)
    groups: list[list[int]] = []
    targets: list[NDArray[np.float64]] = []
    for spec in handles:
        idx = select(V, spec.selector)
        idx = idx[~taken[idx]]
        if not len(idx):
            raise ConstraintError(f"--handle {spec.selector!r} picks no vertex that is not already fixed or in an "
                                  "earlier handle group")
        taken[idx] = True
        P = np.array(V[idx], dtype=np.float64)
        if spec.rotation is not None:
            centre = P.mean(axis=0)
            P = (P - centre) @ spec.rotation.T + centre
        if spec.move is not None:
            P = P + spec.move
        groups.append(idx.tolist())
        targets.append(np.asarray(P, dtype=np.float64))
    if not len(fixed_all) and not groups:
        raise ConstraintError("no vertex is constrained: give --fix and/or --handle selectors")
    handles_all = np.array([i for g in groups for i in g], dtype=np.int64)
    roi_idx = None
    if roi is not None:
        roi_idx = select(V, roi)
        if not len(roi_idx):
            raise ConstraintError(f"--roi {roi!r} picks no vertex")
    fixed_checked, _, roi_checked = check_selection(len(V), fixed_all, [handles_all] if len(handles_all) else [],
                                                    roi_idx, group_names=["handles"] if len(handles_all) else [])
    return Constraints(fixed=fixed_checked, handles=handles_all,
                       targets=np.concatenate(targets) if targets else np.zeros((0, 3)), roi=roi_checked,
                       handle_groups=groups or None)
