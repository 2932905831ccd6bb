"""The studio wire protocol: decoding and validation of a client's messages.

The messages are classes, :mod:`arap.server.client_messages` and :mod:`arap.server.server_messages` (their
specifications, derived from the classes, the kinds of their fields and the protocol's constants are in
:mod:`arap.server.messages`), the error codes live in :mod:`arap.server.errors` and the binary frame helpers in
:mod:`arap.server.frames`.

This module is the single source of truth of the protocol spoken over the studio's WebSocket (see
``docs/protocol.md``). The browser client's copy, ``web/src/protocol.js``, is generated from it::

    python -m arap.server.protocol > web/src/protocol.js

Incoming messages are validated in two stages: :func:`parse_text` / :func:`parse_binary` check the structure of a
frame (JSON object, known type, every field of the right type and range: the checker of its kind in :data:`CHECKS`)
without knowing the session and return an instance of the message's class, and :func:`check_against_mesh` checks
what depends on the session's current mesh (vertex index bounds, number of handle groups). Both raise
:class:`RequestError`, which the server turns into an ``error`` reply.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any, TypeGuard

import numpy as np

from arap.server.bulkjson import NumberList, loads_bulk
from arap.server.client_messages import CLIENT_MESSAGE_CLASSES, Drag, SetConstraints, Upload
from arap.server.errors import RequestError
from arap.server.frames import decode_binary, loads_json
from arap.server.messages import (
    MAX_HANDLE_GROUPS,
    MAX_STIFFNESS_GROUPS,
    SENT_ONLY,
    ClientMessage,
    Field,
    Wire,
    message_spec,
)
from arap.server.server_messages import Error

__all__ = [
    "AFFINE_TOLERANCE",
    "CHECKS",
    "SHORT_LIST_BYTES",
    "Check",
    "check_against_mesh",
    "check_field",
    "error_message",
    "main",
    "parse_binary",
    "parse_large_text",
    "parse_text",
    "validate",
]


def error_message(exc: RequestError) -> dict[str, Any]:
    """The ``error`` message that tells the client why ``exc``'s request was rejected."""
    return Error(code=exc.code, message=exc.message, request=exc.request).to_wire()


# ---------------------------------------------------------------------------------------------- field checks
AFFINE_TOLERANCE = 1e-9
"""How far the last row of a drag transform may be from (0, 0, 0, 1)."""

SHORT_LIST_BYTES = 2**20
"""A :class:`~arap.server.bulkjson.NumberList` where a list of objects or matrices is expected is decoded into
Python lists (and then refused or accepted by the usual checks) only up to this length of text."""

Check = Callable[[Field, Any, str], Any]
"""The checker of a field kind: ``check(field, value, where)`` returns the value as the message's class holds it, or
raises :class:`RequestError` (``bad_message``) with a message that starts with ``where`` (``"drag.seq"``)."""

_FLOAT_MAX = sys.float_info.max


def _is_int(x: Any) -> TypeGuard[int]:
    return type(x) is int


def _is_number(x: Any) -> bool:
    """A finite float, or an integer a float64 can hold (comparing an int with a float is exact in Python)."""
    if type(x) is float:
        return math.isfinite(x)
    return type(x) is int and -_FLOAT_MAX <= x <= _FLOAT_MAX


def _shown_list(value: Any) -> Any:
    """How a long list of numbers appears in a message (``json.dumps``'s ``default``)."""
    if isinstance(value, NumberList):
        return f"<list of {len(value)}>"
    raise TypeError(f"{type(value).__name__} is not JSON")


def _counted(f: Field, value: Any, where: str, what: str = "elements") -> None:
    """Refuse a long list of numbers (:class:`~arap.server.bulkjson.NumberList`) with more elements than ``f``
    allows, before any of them is decoded."""
    if isinstance(value, NumberList) and f.max_length is not None and len(value) > f.max_length:
        raise RequestError("bad_message", f"{where} has {len(value)} {what}, at most {f.max_length}")


def _decoded(value: NumberList, where: str) -> list[Any]:
    """A long list of numbers given where Python lists are checked: decoded when short, else refused."""
    if value.nbytes > SHORT_LIST_BYTES:
        raise RequestError("bad_message", f"{where} is a list of {len(value):,} "
                           f"{'lists of numbers' if value.nested else 'numbers'}, not what it must hold")
    return value.tolist()


def _in_range(f: Field, value: Any, where: str) -> None:
    if (f.minimum is not None and value < f.minimum) or (f.maximum is not None and value > f.maximum):
        raise RequestError("bad_message", f"{where} must be in {f.minimum}..{f.maximum}, got {str(value)[:40]}")


def _check_int(f: Field, value: Any, where: str) -> int:
    _counted(f, value, where)
    if not _is_int(value):
        raise RequestError("bad_message", f"{where} must be an integer")
    _in_range(f, value, where)
    return value


def _check_number(f: Field, value: Any, where: str) -> float:
    _counted(f, value, where)
    if not _is_number(value):
        raise RequestError("bad_message", f"{where} must be a finite number")
    _in_range(f, value, where)
    return float(value)


def _check_string(f: Field, value: Any, where: str) -> str:
    _counted(f, value, where)
    if not isinstance(value, str):
        raise RequestError("bad_message", f"{where} must be a string")
    if f.max_length is not None and len(value) > f.max_length:
        raise RequestError("bad_message", f"{where} is longer than {f.max_length} characters")
    return value


def _check_enum(f: Field, value: Any, where: str) -> str:
    text = _check_string(f, value, where)
    if text not in f.choices:
        raise RequestError("bad_message", f"{where} must be one of {list(f.choices)}, got {text[:40]!r}")
    return text


def _index_list(value: Any, where: str) -> Any:
    if isinstance(value, NumberList):
        return value.integers(where)
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of vertex indices")
    if not all(type(x) is int for x in value):
        bad = next(x for x in value if type(x) is not int)
        shown = json.dumps(bad, default=_shown_list)[:40]
        raise RequestError("bad_message", f"{where} must hold integers, found {shown}")
    return value


def _check_indices(f: Field, value: Any, where: str) -> Any:
    _counted(f, value, where)
    if isinstance(value, NumberList) and value.nested:
        value = _decoded(value, where)
    return _index_list(value, where)


def _check_indices_or_null(f: Field, value: Any, where: str) -> Any:
    return None if value is None else _check_indices(f, value, where)


def _check_index_groups(f: Field, value: Any, where: str) -> Any:
    if isinstance(value, NumberList):
        _counted(f, value, where, "groups")
        if value.nested:
            return value.integer_groups(where)
        value = _decoded(value, where) if len(value) else []
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of lists of vertex indices")
    if f.max_length is not None and len(value) > f.max_length:
        raise RequestError("bad_message", f"{where} has {len(value)} groups, at most {f.max_length}")
    return [_index_list(g, f"{where}[{i}]") for i, g in enumerate(value)]


def _check_matrices(f: Field, value: Any, where: str) -> Any:
    if isinstance(value, NumberList):
        _counted(f, value, where, "matrices")
        value = _decoded(value, where)
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


def _check_points_or_null(f: Field, value: Any, where: str) -> Any:
    if value is None:
        return None
    if isinstance(value, NumberList):
        _counted(f, value, where)
        if value.nested:
            return value.points(where)
        value = _decoded(value, where) if len(value) else []
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of [x, y, z] points or null")
    for i, p in enumerate(value):
        if not isinstance(p, list) or len(p) != 3 or not all(_is_number(x) for x in p):
            raise RequestError("bad_message", f"{where}[{i}] must be a list of 3 finite numbers")
    return value


def _object_list(f: Field, value: Any, where: str, what: str, form: str) -> list[Any]:
    """A list of objects (``form`` names their keys in the error), at most ``f.max_length`` of ``what``, counted
    before a bulk-decoded list is turned into Python objects."""
    if isinstance(value, NumberList):
        _counted(f, value, where, what)
        value = _decoded(value, where)
    if not isinstance(value, list):
        raise RequestError("bad_message", f"{where} must be a list of {{{form}}} objects or null")
    if f.max_length is not None and len(value) > f.max_length:
        raise RequestError("bad_message", f"{where} has {len(value)} {what}, at most {f.max_length}")
    return value


def _check_stiffness_or_null(f: Field, value: Any, where: str) -> Any:
    if value is None:
        return None
    value = _object_list(f, value, where, "groups", "vertices, value")
    for i, item in enumerate(value):
        if not isinstance(item, dict) or set(item) != {"vertices", "value"}:
            raise RequestError("bad_message", f'{where}[{i}] must be an object with "vertices" and "value"')
        item["vertices"] = _index_list(item["vertices"], f"{where}[{i}].vertices")
        v = item["value"]
        if v != "rigid" and not (_is_number(v) and v > 0):
            raise RequestError("bad_message", f'{where}[{i}].value must be a positive number or "rigid"')
    return value


_POINT_KEYS = frozenset({"face", "barycentric", "weight", "target"})


def _check_point_handles_or_null(f: Field, value: Any, where: str) -> Any:
    """The form of ``set_constraints.points``; ranges and coordinates are checked against the mesh by
    :func:`arap.constraints.points_from_json` (``bad_constraints``)."""
    if value is None:
        return None
    value = _object_list(f, value, where, "point handles", "face, barycentric")
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


def checks_of_every_kind(checks: Mapping[Wire, Check], kinds: Iterable[Wire]) -> dict[Wire, Check]:
    """``checks`` as a dict, when it has a checker for each of ``kinds`` a client may send and for no other.

    Raises
    ------
    TypeError
        A kind a client may send without a checker, or a checker of a kind only the server sends (or of no kind).
    """
    receivable = [k for k in kinds if k not in SENT_ONLY]
    missing = [k.value for k in receivable if k not in checks]
    if missing:
        raise TypeError(f"field kinds without a checker: {missing}; add one to arap.server.protocol.CHECKS, or the "
                        "kind to SENT_ONLY when only the server sends it")
    extra = [str(getattr(k, "value", k)) for k in checks if k not in receivable]
    if extra:
        raise TypeError(f"checkers of field kinds a client cannot send: {extra}")
    return dict(checks)


CHECKS: dict[Wire, Check] = checks_of_every_kind({
    Wire.INT: _check_int,
    Wire.NUMBER: _check_number,
    Wire.STRING: _check_string,
    Wire.ENUM: _check_enum,
    Wire.INDICES: _check_indices,
    Wire.INDICES_OR_NULL: _check_indices_or_null,
    Wire.INDEX_GROUPS: _check_index_groups,
    Wire.MATRICES: _check_matrices,
    Wire.POINTS_OR_NULL: _check_points_or_null,
    Wire.STIFFNESS_OR_NULL: _check_stiffness_or_null,
    Wire.POINT_HANDLES_OR_NULL: _check_point_handles_or_null,
}, Wire)
"""The checker of each kind of field a client may send (every :class:`~arap.server.messages.Wire` but those of
:data:`~arap.server.messages.SENT_ONLY`: checked when this module is imported)."""


def check_field(f: Field, value: Any, mtype: str) -> Any:
    """Check the value of field ``f`` of a ``mtype`` message with the checker of its kind (:data:`CHECKS`); returns
    it as the message's class holds it (numbers of ``number`` fields as float).

    Raises
    ------
    RequestError
        ``bad_message``: a value of the wrong kind, out of range or too long.
    """
    return CHECKS[f.kind](f, value, f"{mtype}.{f.name}")


# ---------------------------------------------------------------------------------------------- validation
def _check_fields_together(mtype: str, fields: dict[str, Any]) -> None:
    """Checks across the fields of one message."""
    if mtype == "set_constraints" and fields.get("points"):
        total = len(fields["handle_groups"]) + len(fields["points"])
        if total > MAX_HANDLE_GROUPS:
            raise RequestError("bad_message", f"set_constraints has {total} handle groups and point handles, at "
                               f"most {MAX_HANDLE_GROUPS}")
    if mtype == "set_constraints" and fields.get("targets") is not None:
        n_handles = sum(len(g) for g in fields["handle_groups"])
        if len(fields["targets"]) != n_handles:
            raise RequestError("bad_message", f"set_constraints.targets has {len(fields['targets'])} points but "
                               f"the handle groups have {n_handles} vertices")


def _request_name(obj: dict[str, Any]) -> str | None:
    t = obj.get("type")
    return t[:64] if isinstance(t, str) else None


def validate(obj: Any, binary: bool, payload: memoryview | None = None) -> ClientMessage:
    """Check a decoded message against its class's specification (:data:`CLIENT_MESSAGES`) and build it.

    Parameters
    ----------
    obj : Any
        Decoded JSON (text message) or header (binary message).
    binary : bool
        Whether it came in a binary frame.
    payload : memoryview or None
        Payload of a binary frame.

    Returns
    -------
    ClientMessage
        An instance of the message's class (:mod:`arap.server.client_messages`); absent optional fields are None.

    Raises
    ------
    RequestError
        ``bad_message`` for anything that does not match.
    """
    if not isinstance(obj, dict):
        kind = "list" if isinstance(obj, NumberList) else type(obj).__name__
        raise RequestError("bad_message", f"a message must be a JSON object, got {kind}")
    request = _request_name(obj)
    if "type" not in obj:
        raise RequestError("bad_message", "message has no 'type'")
    if request is None:
        raise RequestError("bad_message", "'type' must be a string")
    cls = CLIENT_MESSAGE_CLASSES.get(obj["type"])
    if cls is None:
        raise RequestError("bad_message", f"unknown message type {request!r}", request)
    spec = message_spec(cls)
    if spec.binary != binary:
        how = "a binary frame" if spec.binary else "a text frame"
        raise RequestError("bad_message", f"{spec.type} must be sent as {how}", request)
    unknown = sorted(k for k in obj if k != "type" and k not in spec.field_names)
    if unknown:
        raise RequestError("bad_message", f"unknown field {unknown[0][:40]!r} in {spec.type}", request)
    fields: dict[str, Any] = {}
    try:
        for f in spec.fields:
            if f.name not in obj:
                if f.required:
                    raise RequestError("bad_message", f"{spec.type} needs field {f.name!r}")
                continue
            fields[f.name] = check_field(f, obj[f.name], spec.type)
        if spec.at_least_one and not fields:
            names = ", ".join(f.name for f in spec.fields)
            raise RequestError("bad_message", f"{spec.type} needs at least one of {names}")
        _check_fields_together(spec.type, fields)
    except RequestError as exc:
        exc.request = request
        raise
    if cls is Upload:
        return Upload(**fields, payload=payload if payload is not None else memoryview(b""))
    return cls(**fields)


def parse_text(text: str, *, cooperative: bool = False, max_indices: int | None = None) -> ClientMessage:
    """Decode and validate a text frame. Raises :class:`RequestError`.

    ``cooperative`` is for a large frame decoded on a thread: it is decoded as by :func:`parse_large_text`, in
    memory proportional to its size and without building a Python object per number (which would also hold the
    interpreter lock from the other threads for as long); its long lists come back as NumPy arrays, and those of
    vertex indices are counted against ``max_indices`` first.
    """
    if cooperative:
        return parse_large_text(text.encode("utf-8"), max_indices)
    return validate(loads_json(text), binary=False)


def parse_large_text(data: bytes, max_indices: int | None = None) -> ClientMessage:
    """Decode and validate a large UTF-8 text frame in memory proportional to its size. Raises
    :class:`RequestError`.

    Long lists of numbers are counted against their field's limits before they are decoded, and come back as
    NumPy arrays: index lists as (k,) int32 arrays (int64 when an index exceeds int32, a list when one exceeds
    int64), handle groups as a list
    of them, targets as a (t, 3) float64 array (see :mod:`arap.server.bulkjson`); short ones as Python lists.

    ``max_indices`` (the largest mesh the server accepts, in vertices) refuses a list of vertex indices longer than
    that (``too_large``) when it has been counted, before any of its numbers is decoded: no mesh could use it, and
    decoding it would take memory out of proportion to any valid message.
    """
    obj = loads_bulk(data)
    if max_indices is not None:
        _refuse_long_index_lists(obj, max_indices)
    return validate(obj, binary=False)


def _refuse_long_index_lists(obj: Any, max_indices: int) -> None:
    """Refuse (``too_large``) a ``set_constraints`` whose long lists of vertex indices (not decoded yet: counted by
    :class:`~arap.server.bulkjson.NumberList`) hold more than ``max_indices`` each; anything else is left to
    :func:`validate`."""
    if not isinstance(obj, dict) or obj.get("type") != "set_constraints":
        return
    lists: list[tuple[str, Any]] = [("fixed", obj.get("fixed")), ("roi", obj.get("roi"))]
    groups = obj.get("handle_groups")
    if isinstance(groups, NumberList) and groups.nested and len(groups) <= MAX_HANDLE_GROUPS:
        for i, count in enumerate(groups.inner_lengths()):
            if count > max_indices:
                _too_many(f"handle_groups[{i}]", count, max_indices)
    elif isinstance(groups, list):
        lists += [(f"handle_groups[{i}]", g) for i, g in enumerate(groups[:MAX_HANDLE_GROUPS])]
    stiffness = obj.get("stiffness")
    if isinstance(stiffness, list):
        lists += [(f"stiffness[{i}].vertices", s.get("vertices"))
                  for i, s in enumerate(stiffness[:MAX_STIFFNESS_GROUPS]) if isinstance(s, dict)]
    for name, value in lists:
        if isinstance(value, NumberList) and not value.nested and len(value) > max_indices:
            _too_many(name, len(value), max_indices)


def _too_many(name: str, count: int, max_indices: int) -> None:
    raise RequestError("too_large", f"set_constraints.{name} lists {count:,} vertex indices, more than the "
                       f"{max_indices:,} vertices of the largest mesh this server accepts", "set_constraints")


def parse_binary(data: bytes | bytearray | memoryview) -> ClientMessage:
    """Decode and validate a binary frame. Raises :class:`RequestError`."""
    header, payload = decode_binary(data)
    return validate(header, binary=True, payload=payload)


def _first_out_of_range(values: list[int] | np.ndarray, n: int) -> int | None:
    if isinstance(values, np.ndarray):
        if not values.size or (values.min() >= 0 and values.max() < n):  # no temporary arrays when all are in range
            return None
        bad = np.flatnonzero((values < 0) | (values >= n))
        return int(values[bad[0]]) if bad.size else None
    return next((v for v in values if v < 0 or v >= n), None)


def check_against_mesh(msg: ClientMessage, n_vertices: int, n_groups: int) -> None:
    """Check what depends on the session: vertex indices in range, one transform per handle group.

    Parameters
    ----------
    msg : ClientMessage
        A message returned by :func:`parse_text` / :func:`parse_binary`.
    n_vertices : int
        Vertices of the session's mesh.
    n_groups : int
        Handle groups of the session's current constraint set.

    Raises
    ------
    RequestError
        ``bad_constraints`` for an index out of range or a list longer than the mesh has vertices (some must
        repeat), ``bad_message`` for a wrong number of transforms.
    """
    if isinstance(msg, SetConstraints):
        lists: list[tuple[str, list[int] | np.ndarray]] = [("fixed", msg.fixed)]
        if msg.roi is not None:
            lists.append(("roi", msg.roi))
        lists += [(f"handle_groups[{i}]", g) for i, g in enumerate(msg.handle_groups)]
        for name, values in lists:
            bad = _first_out_of_range(values, n_vertices)
            if bad is not None:
                raise RequestError("bad_constraints",
                                   f"{name}: vertex index {str(bad)[:40]} out of range 0..{n_vertices - 1}", msg.type)
            if len(values) > n_vertices:
                # checked here, before the session copies the list to look for the repeated ones
                raise RequestError("bad_constraints", f"{name} lists {len(values):,} vertex indices, more than the "
                                   f"mesh's {n_vertices:,} vertices: some repeat", msg.type)
    elif isinstance(msg, Drag):
        got = len(msg.transforms)
        if got != n_groups:
            raise RequestError("bad_message",
                               f"drag has {got} transforms but the constraints have {n_groups} handle groups",
                               msg.type)


def main() -> None:
    """Write the generated client module (``web/src/protocol.js``) to standard output."""
    import sys

    from arap.server.jsgen import generate_js

    sys.stdout.write(generate_js())


if __name__ == "__main__":
    main()
