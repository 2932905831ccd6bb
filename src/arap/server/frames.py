"""Binary frames of the studio protocol: ``u32 LE header length | JSON header padded with spaces | payload``.

Part of the wire protocol (:mod:`arap.server.protocol`).
"""

from __future__ import annotations

import json
import struct
from typing import Any

from arap.server.errors import RequestError

__all__ = ["MAX_HEADER_BYTES", "decode_binary", "encode_binary", "loads_json"]

MAX_HEADER_BYTES = 65536
"""Largest JSON header accepted in a binary frame."""


def encode_binary(header: dict[str, Any], *payload: bytes | bytearray | memoryview) -> bytes:
    """Build a binary frame: ``u32 LE header length | JSON header padded with spaces | payload``.

    The header is padded so that the payload starts at a multiple of 4 bytes.

    Parameters
    ----------
    header : dict
        JSON-serialisable header with a ``type``.
    *payload : bytes-like
        Payload parts, concatenated.

    Returns
    -------
    bytes
    """
    text = json.dumps(header, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-(4 + len(text)) % 4)
    return b"".join([struct.pack("<I", len(text)), text, *payload])


def decode_binary(data: bytes | bytearray | memoryview) -> tuple[dict[str, Any], memoryview]:
    """Split a binary frame into its JSON header and its payload.

    Parameters
    ----------
    data : bytes-like

    Returns
    -------
    header : dict
    payload : memoryview

    Raises
    ------
    RequestError
        ``bad_message`` when the frame is truncated or its header is not a JSON object.
    """
    view = memoryview(data)
    if len(view) < 4:
        raise RequestError("bad_message", "binary frame shorter than its 4-byte header length")
    (n,) = struct.unpack_from("<I", view, 0)
    if n > MAX_HEADER_BYTES:
        raise RequestError("bad_message", f"binary frame header of {n} bytes exceeds {MAX_HEADER_BYTES}")
    if 4 + n > len(view):
        raise RequestError("bad_message", f"binary frame header length {n} exceeds the frame ({len(view)} B)")
    try:
        header = loads_json(bytes(view[4 : 4 + n]).decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise RequestError("bad_message", "binary frame header is not UTF-8") from exc
    if not isinstance(header, dict):
        raise RequestError("bad_message", "binary frame header must be a JSON object")
    return header, view[4 + n :]


def _reject_constant(name: str) -> float:
    raise RequestError("bad_message", f"{name} is not a valid JSON number")


def _parse_int(text: str) -> int:
    # A Python-level hook: the decoder calls back into the interpreter for every integer, which lets other
    # threads (the event loop) take the GIL while a large message is decoded.
    return int(text)


def _parse_float(text: str) -> float:
    return float(text)


def loads_json(text: str, *, cooperative: bool = False) -> Any:
    """Decode JSON text, rejecting ``NaN``/``Infinity``; raises :class:`RequestError` (``bad_message``).

    Parameters
    ----------
    text : str
    cooperative : bool
        Decode numbers through Python-level hooks, so that a thread decoding a large message lets other
        threads run (slower: the price of not holding the interpreter for the whole message).

    Raises
    ------
    RequestError
        Not JSON, nested too deeply, or an integer too long to convert (more than
        ``sys.get_int_max_str_digits()`` digits).
    """
    hooks: dict[str, Any] = {"parse_int": _parse_int, "parse_float": _parse_float} if cooperative else {}
    try:
        return json.loads(text, parse_constant=_reject_constant, **hooks)
    except json.JSONDecodeError as exc:
        raise RequestError("bad_message", f"not valid JSON: {exc.msg} at position {exc.pos}") from exc
    except RecursionError as exc:
        raise RequestError("bad_message", "JSON nested too deeply") from exc
    except ValueError as exc:
        raise RequestError("bad_message", f"not a usable JSON number: {str(exc)[:120]}") from exc
