"""Checks of the values of client message fields, by field kind (see :class:`arap.server.messages.Field`).

Every check raises :class:`~arap.server.errors.RequestError` (``bad_message``) with a message naming the field.
"""

from __future__ import annotations

import json
import math
import sys
from typing import TYPE_CHECKING, Any

from arap.server.bulkjson import NumberList
from arap.server.errors import RequestError

if TYPE_CHECKING:
    from arap.server.messages import Field

__all__ = ["AFFINE_TOLERANCE", "check_field"]

AFFINE_TOLERANCE = 1e-9
"""How far the last row of a drag transform may be from (0, 0, 0, 1)."""


def _is_int(x: Any) -> bool:
    return type(x) is int


_FLOAT_MAX = sys.float_info.max


def _is_number(x: Any) -> bool:
    """A finite float, or an integer a float64 can hold (comparing an int with a float is exact in Python)."""
    if type(x) is float:
        return math.isfinite(x)
    return type(x) is int and -_FLOAT_MAX <= x <= _FLOAT_MAX


SHORT_LIST_BYTES = 2**20
"""A :class:`~arap.server.bulkjson.NumberList` where a list of objects or matrices is expected is decoded into
Python lists (and then refused or accepted by the usual checks) only up to this length of text."""


def _shown_list(value: Any) -> Any:
    """How a long list of numbers appears in a message (``json.dumps``'s ``default``)."""
    if isinstance(value, NumberList):
        return f"<list of {len(value)}>"
    raise TypeError(f"{type(value).__name__} is not JSON")


def _check_index_list(value: Any, where: str) -> Any:
    if isinstance(value, NumberList):
        return value.integers(where)
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of vertex indices")
    if not all(type(x) is int for x in value):
        bad = next(x for x in value if type(x) is not int)
        shown = json.dumps(bad, default=_shown_list)[:40]
        raise RequestError("bad_message", f"{where} must hold integers, found {shown}")
    return value


def check_field(f: Field, value: Any, mtype: str) -> Any:
    """Check the value of field ``f`` of a ``mtype`` message; returns it (numbers of ``number`` fields as float).

    Raises
    ------
    RequestError
        ``bad_message``: a value of the wrong kind, out of range or too long.
    """
    where = f"{mtype}.{f.name}"
    kind = f.kind
    if isinstance(value, NumberList):
        value = _number_list(f, value, where)
    if kind == "int":
        if not _is_int(value):
            raise RequestError("bad_message", f"{where} must be an integer")
        if (f.minimum is not None and value < f.minimum) or (f.maximum is not None and value > f.maximum):
            raise RequestError("bad_message", f"{where} must be in {f.minimum}..{f.maximum}, got {str(value)[:40]}")
        return value
    if kind == "number":
        if not _is_number(value):
            raise RequestError("bad_message", f"{where} must be a finite number")
        if (f.minimum is not None and value < f.minimum) or (f.maximum is not None and value > f.maximum):
            raise RequestError("bad_message", f"{where} must be in {f.minimum}..{f.maximum}, got {str(value)[:40]}")
        return float(value)
    if kind in ("string", "enum"):
        if not isinstance(value, str):
            raise RequestError("bad_message", f"{where} must be a string")
        if f.max_length is not None and len(value) > f.max_length:
            raise RequestError("bad_message", f"{where} is longer than {f.max_length} characters")
        if kind == "enum" and value not in f.choices:
            raise RequestError("bad_message", f"{where} must be one of {list(f.choices)}, got {value[:40]!r}")
        return value
    if kind == "indices_or_null" and value is None:
        return None
    if kind in ("indices", "indices_or_null"):
        return _check_index_list(value, where)
    if kind == "index_groups":
        if isinstance(value, NumberList):
            return value.integer_groups(where)
        if not isinstance(value, list):
            raise RequestError("bad_message", f"{where} must be a list of lists of vertex indices")
        if f.max_length is not None and len(value) > f.max_length:
            raise RequestError("bad_message", f"{where} has {len(value)} groups, at most {f.max_length}")
        return [_check_index_list(g, f"{where}[{i}]") for i, g in enumerate(value)]
    if kind == "matrices":
        if not isinstance(value, list):
            raise RequestError("bad_message", f"{where} must be a list of 4x4 matrices (16 numbers each)")
        if f.max_length is not None and len(value) > f.max_length:
            raise RequestError("bad_message", f"{where} has {len(value)} matrices, at most {f.max_length}")
        for i, m in enumerate(value):
            if not isinstance(m, list) or len(m) != 16:
                raise RequestError("bad_message", f"{where}[{i}] must be a list of 16 numbers")
            if not all(_is_number(x) for x in m):
                raise RequestError("bad_message", f"{where}[{i}] must hold 16 finite numbers")
            if max(abs(m[3]), abs(m[7]), abs(m[11]), abs(m[15] - 1)) > AFFINE_TOLERANCE:
                raise RequestError(
                    "bad_message", f"{where}[{i}] must be affine (last row 0, 0, 0, 1; column-major elements "
                    "3, 7, 11, 15)")
        return value
    if kind == "points_or_null":
        if value is None:
            return None
        if isinstance(value, NumberList):
            return value.points(where)
        if not isinstance(value, list):
            raise RequestError("bad_message", f"{where} must be a list of [x, y, z] points or null")
        for i, p in enumerate(value):
            if not isinstance(p, list) or len(p) != 3 or not all(_is_number(x) for x in p):
                raise RequestError("bad_message", f"{where}[{i}] must be a list of 3 finite numbers")
        return value
    if kind == "stiffness_or_null":
        if value is None:
            return None
        if not isinstance(value, list):
            raise RequestError("bad_message", f"{where} must be a list of {{vertices, value}} objects or null")
        if f.max_length is not None and len(value) > f.max_length:
            raise RequestError("bad_message", f"{where} has {len(value)} groups, at most {f.max_length}")
        for i, item in enumerate(value):
            if not isinstance(item, dict) or set(item) != {"vertices", "value"}:
                raise RequestError("bad_message", f'{where}[{i}] must be an object with "vertices" and "value"')
            item["vertices"] = _check_index_list(item["vertices"], f"{where}[{i}].vertices")
            v = item["value"]
            if v != "rigid" and not (_is_number(v) and v > 0):
                raise RequestError("bad_message", f'{where}[{i}].value must be a positive number or "rigid"')
        return value
    if kind == "point_handles_or_null":
        return _check_point_handles(f, value, where)
    raise AssertionError(f"field kind {kind!r} cannot be received")


def _number_list(f: Field, value: NumberList, where: str) -> Any:
    """A long list of numbers (or of lists of numbers) given for field ``f``: counted against the field's limit
    before anything is decoded; kept for the fields that take it as arrays, else decoded into Python lists when
    short (the usual checks then answer), else refused."""
    if f.max_length is not None and len(value) > f.max_length:
        what = {"index_groups": "groups", "matrices": "matrices", "stiffness_or_null": "groups",
                "point_handles_or_null": "point handles"}.get(f.kind, "elements")
        raise RequestError("bad_message", f"{where} has {len(value)} {what}, at most {f.max_length}")
    if f.kind in ("indices", "indices_or_null") and not value.nested:
        return value
    if f.kind in ("index_groups", "points_or_null") and (value.nested or not len(value)):
        return value if len(value) else []
    if f.kind in ("int", "number", "string", "enum"):
        return value  # not of the field's kind: refused as any list would be
    if value.nbytes > SHORT_LIST_BYTES:
        raise RequestError("bad_message", f"{where} is a list of {len(value):,} "
                           f"{'lists of numbers' if value.nested else 'numbers'}, not what it must hold")
    return value.tolist()


_POINT_KEYS = frozenset({"face", "barycentric", "weight", "target"})


def _check_point_handles(f: Field, value: Any, where: str) -> Any:
    """The form of ``set_constraints.points``; ranges and coordinates are checked against the mesh by
    :func:`arap.constraints.points_from_json` (``bad_constraints``)."""
    if value is None:
        return None
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of {{face, barycentric}} objects or null")
    if f.max_length is not None and len(value) > f.max_length:
        raise RequestError("bad_message", f"{where} has {len(value)} point handles, at most {f.max_length}")
    for i, item in enumerate(value):
        if not isinstance(item, dict) or not {"face", "barycentric"} <= set(item) or not set(item) <= _POINT_KEYS:
            raise RequestError("bad_message", f'{where}[{i}] must be an object with "face", "barycentric" and '
                               'optionally "weight" and "target"')
        if not _is_int(item["face"]):
            raise RequestError("bad_message", f"{where}[{i}].face must be an integer triangle index")
        for key in ("barycentric", "target"):
            p = item.get(key, [0, 0, 0])
            if isinstance(p, NumberList) and p.nbytes <= SHORT_LIST_BYTES:
                p = item[key] = p.tolist()
            if not isinstance(p, list) or len(p) != 3 or not all(_is_number(x) for x in p):
                raise RequestError("bad_message", f"{where}[{i}].{key} must be a list of 3 finite numbers")
        w = item.get("weight", 1)
        if not (_is_number(w) and w > 0):
            raise RequestError("bad_message", f"{where}[{i}].weight must be a positive number (omit it for a "
                               "hard handle)")
    return value
