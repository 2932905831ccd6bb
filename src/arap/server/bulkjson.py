"""Decoding of large JSON text with bounded memory: long lists of numbers become NumPy arrays, never Python lists.

``json.loads`` builds one Python object per number and per list: a 57 MB list of short handle groups becomes
1.8 GB of lists and ints before any check can count them, and 32 million zeros take 1 GB. :func:`loads_bulk` scans
the text instead (C-speed regular expressions) and finds every list of numbers (``[1, 2, 3]``) and every list of
such lists (``[[1, 2], [3]]``) without decoding it; each becomes a :class:`NumberList` that refers to its span of
the text. The rest of the message, a skeleton of at most :data:`MAX_PARTS` values, is decoded by ``json.loads``.

A :class:`NumberList` knows how many elements it has at no cost (counting brackets and commas), so a field with a
limit is refused before its numbers are parsed; parsed, it gives arrays (``np.fromstring``: 8 bytes per number).
Decoding a message thus takes a small multiple of its size, whatever its contents.

The grammar accepted is JSON's: numbers must be JSON numbers, and ``NaN`` and ``Infinity`` are refused.
"""

from __future__ import annotations

import json
import re
import warnings
from typing import Any

import numpy as np

from arap.server.errors import RequestError

__all__ = ["MAX_PARTS", "NumberList", "loads_bulk"]

MAX_PARTS = 20_000
"""Most values, lists and objects a message may have outside its lists of numbers (a valid message has a few
thousand at most: 256 stiffness groups and 256 point handles)."""

INLINE_BYTES = 64
"""Lists of numbers up to this long (in characters) are decoded as Python lists, as ``json.loads`` would."""

_WS = rb"[ \t\n\r]"
_NUM = rb"-?+(?:0|[1-9][0-9]*+)(?:\.[0-9]++)?+(?:[eE][-+]?+[0-9]++)?+"
_FLAT = rb"\[" + _WS + rb"*+(?:" + _NUM + _WS + rb"*+(?:," + _WS + rb"*+" + _NUM + _WS + rb"*+)*+)?+\]"
_NESTED = rb"\[" + _WS + rb"*+" + _FLAT + _WS + rb"*+(?:," + _WS + rb"*+" + _FLAT + _WS + rb"*+)*+\]"
_STRING = rb'"(?:[^"\\\x00-\x1f]++|\\[^\x00-\x1f])*+"'
_TOKEN = re.compile(
    rb"(?P<gap>[^\"\[NI]++)|(?P<string>" + _STRING + rb")|(?P<nested>" + _NESTED + rb")|(?P<flat>" + _FLAT
    + rb")|(?P<constant>NaN|Infinity)|(?P<other>.)",
    re.DOTALL,
)
_FLOAT_MARK = re.compile(rb"[.eE]")
_FLOAT_TOKEN = re.compile(_NUM)
_INT64 = np.iinfo(np.int64)
_INT32 = np.iinfo(np.int32)
_LONG_INT = re.compile(rb"[0-9]{19}")
_CHUNK_BYTES = 2**18
_COMMA_RUNS = re.compile(rb",,++")


class NumberList:
    """A JSON list of numbers, or of lists of numbers, not decoded yet: a span of the message's text.

    ``len()`` is the number of its elements (numbers, or inner lists), counted without decoding them.
    """

    __slots__ = ("_count", "_data", "_end", "_start", "nested")

    def __init__(self, data: bytes, start: int, end: int, nested: bool) -> None:
        self._data = data
        self._start = start
        self._end = end
        self.nested = nested
        """Whether the elements are lists of numbers (else numbers)."""
        if nested:
            self._count = data.count(b"[", start + 1, end)
        elif data.count(b",", start, end):
            self._count = data.count(b",", start, end) + 1
        else:
            self._count = 0 if data[start + 1 : end - 1].strip() == b"" else 1

    def __len__(self) -> int:
        return self._count

    def __repr__(self) -> str:
        return f"NumberList({self._count} {'lists' if self.nested else 'numbers'})"

    @property
    def nbytes(self) -> int:
        """Length of its text."""
        return self._end - self._start

    def tolist(self) -> list[Any]:
        """Decoded as ``json.loads`` would (Python objects: for short lists only)."""
        value: list[Any] = json.loads(self._data[self._start : self._end])
        return value

    # ------------------------------------------------------------------ arrays
    def _inner(self) -> bytes:
        """The text between the outer brackets; for a nested list, without whitespace."""
        text = self._data[self._start + 1 : self._end - 1]
        return text.translate(None, b" \t\n\r") if self.nested else text

    def _text(self) -> bytes:
        """The numbers, comma-separated (without brackets, and without the empty inner lists)."""
        text = self._inner()
        if self.nested:
            text = text.translate(None, b"[]")
            if b",," in text or text.startswith(b",") or text.endswith(b","):  # empty inner lists
                text = _COMMA_RUNS.sub(b",", text).strip(b",")
        return text

    def inner_lengths(self) -> list[int]:
        """Number of numbers in each inner list of a nested list (one Python int per inner list: for short
        lists of lists only)."""
        if not self.nested:
            raise ValueError("not a list of lists")
        data = self._data
        lengths: list[int] = []
        pos = self._start + 1
        while True:
            start = data.find(b"[", pos, self._end)
            if start < 0:
                return lengths
            pos = data.index(b"]", start, self._end)
            commas = data.count(b",", start, pos)
            lengths.append(commas + 1 if commas or data[start + 1 : pos].strip() else 0)

    def _parse(self, dtype: type, count: int) -> np.ndarray:
        """The ``count`` numbers as an array of ``dtype`` (float64, or int32 widened to int64 when a number needs
        it), parsed a chunk of the text at a time so that only the array and one chunk are in memory."""
        text, pos, end = self._data, self._start + 1, self._end - 1
        integers = dtype is not np.float64
        out = np.empty(count, dtype=np.int32 if integers else np.float64)
        filled = 0
        while pos < end and count:
            cut = min(pos + _CHUNK_BYTES, end)
            if cut < end:
                comma = text.find(b",", cut, end)
                cut = end if comma < 0 else comma
            chunk = text[pos:cut]
            pos = cut + 1
            if self.nested:
                chunk = chunk.translate(None, b"[] \t\n\r")
                if b",," in chunk or chunk.startswith(b",") or chunk.endswith(b","):  # empty inner lists
                    chunk = _COMMA_RUNS.sub(b",", chunk).strip(b",")
                if not chunk:
                    continue
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                try:
                    part = np.fromstring(chunk, dtype=np.int64 if integers else np.float64, sep=",")
                except (ValueError, DeprecationWarning) as exc:
                    raise RequestError("bad_message", f"not a usable list of numbers: {str(exc)[:80]}") from exc
            if filled + len(part) > count:
                raise RequestError("bad_message", "not a usable list of numbers")
            if integers and out.dtype == np.int32 and len(part) and not (
                    _INT32.min <= part.min() and part.max() <= _INT32.max):
                out = out.astype(np.int64)  # an index beyond int32 (out of range of any mesh)
            out[filled : filled + len(part)] = part
            filled += len(part)
        if filled != count:
            raise RequestError("bad_message", "not a usable list of numbers")
        return out

    def _total(self) -> int:
        return sum(self.inner_lengths()) if self.nested else self._count

    def _first_float(self) -> tuple[int, bytes] | None:
        """Position (in the span, brackets excluded) and text of the first number that is not an integer (has a
        fraction or an exponent)."""
        m = _FLOAT_MARK.search(self._data, self._start, self._end)
        if m is None:
            return None
        begin = max(self._data.rfind(c, self._start, m.start()) for c in (b",", b"[", b" ", b"\t", b"\n", b"\r")) + 1
        token = _FLOAT_TOKEN.match(self._data, begin)
        assert token is not None  # the span matched the number grammar
        return begin - self._start - 1, token.group()

    def integers(self, where: str) -> np.ndarray | list[int]:
        """The numbers of a flat list as a (k,) int32 array (int64 when one exceeds int32, a list of Python ints
        when one exceeds int64).

        Raises
        ------
        RequestError
            A nested list, or a number that is not an integer.
        """
        if self.nested:
            raise RequestError("bad_message", f"{where} must hold integers, found a list")
        bad = self._first_float()
        if bad is not None:
            raise RequestError("bad_message", f"{where} must hold integers, found {_show_float(bad[1])}")
        return self._integers(where)

    def _integers(self, where: str) -> np.ndarray | list[int]:
        values = self._parse(np.int64, self._total())
        # np.fromstring saturates integers beyond int64: only then look for them
        if values.dtype == np.int32 or not values.size or (values.min() > _INT64.min and values.max() < _INT64.max):
            return values
        if _LONG_INT.search(self._data, self._start, self._end) is None:
            return values
        del values
        if self._total() > 65536:
            raise RequestError("bad_message", f"{where} holds an integer too large for a vertex index")
        try:
            ints = [int(t) for t in self._text().split(b",") if t.strip()]
        except ValueError as exc:  # more digits than Python converts
            raise RequestError("bad_message", f"not a usable JSON number: {str(exc)[:120]}") from exc
        try:
            return np.array(ints, dtype=np.int64)
        except OverflowError:
            return ints

    def integer_groups(self, where: str) -> list[np.ndarray] | list[np.ndarray | list[int]]:
        """The inner lists of a nested list as arrays (see :meth:`integers`)."""
        bad = self._first_float()
        if bad is not None:
            i = self._data.count(b"[", self._start + 1, self._start + 1 + bad[0]) - 1
            raise RequestError("bad_message", f"{where}[{i}] must hold integers, found {_show_float(bad[1])}")
        lengths = self.inner_lengths()
        values = self._integers(where)
        ends = np.cumsum(lengths).tolist()
        return [values[a:b] for a, b in zip([0, *ends[:-1]], ends, strict=True)]

    def points(self, where: str, width: int = 3) -> np.ndarray:
        """A nested list of ``width`` finite numbers each as a (k, width) float64 array.

        Raises
        ------
        RequestError
            An inner list of another length, or a number that is not finite.
        """
        text = self._inner()
        row = rb"\[" + rb",".join([rb"[^\[\],]++"] * width) + rb"\]"
        if re.fullmatch(row + rb"(?:," + row + rb")*+", text) is None:
            pos = 0
            for i in range(self._count):
                start = text.index(b"[", pos)
                pos = text.index(b"]", start)
                if pos == start + 1 or text.count(b",", start, pos) != width - 1:
                    raise RequestError("bad_message", f"{where}[{i}] must be a list of {width} finite numbers")
        del text
        values = self._parse(np.float64, width * self._count).reshape(-1, width)
        bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
        if bad.size:
            raise RequestError("bad_message", f"{where}[{int(bad[0])}] must be a list of {width} finite numbers")
        return values


def _show_float(token: bytes) -> str:
    return json.dumps(float(token))[:40]


def _reject_constant(name: str) -> Any:
    raise RequestError("bad_message", f"{name} is not a valid JSON number")


def loads_bulk(data: bytes, max_parts: int = MAX_PARTS) -> Any:
    """Decode UTF-8 JSON text; lists of numbers (and lists of such lists) longer than :data:`INLINE_BYTES`
    characters come back as :class:`NumberList`.

    Raises
    ------
    RequestError
        ``bad_message``: not JSON, ``NaN`` or ``Infinity``, or more than ``max_parts`` values outside lists of
        numbers (the decoder would need memory out of proportion to the message).
    """
    skeleton: list[bytes] = []
    lists: list[Any] = []
    parts = 0
    pos = 0
    for m in _TOKEN.finditer(data):
        kind = m.lastgroup
        start, end = m.span()
        if kind == "gap":
            parts += data.count(b",", start, end) + data.count(b"{", start, end)
        elif kind == "nested" or kind == "flat":
            parts += 1
            skeleton.append(data[pos:start])
            pos = end
            if end - start <= INLINE_BYTES:
                skeleton.append(data[start:end])
            else:
                skeleton.append(b"NaN")
                lists.append(NumberList(data, start, end, kind == "nested"))
        elif kind == "constant":
            raise RequestError("bad_message", f"{m.group().decode()} is not a valid JSON number")
        else:
            parts += 1
        if parts > max_parts:
            raise RequestError("bad_message", f"message has more than {max_parts:,} values outside lists of numbers")
    skeleton.append(data[pos:])
    text = b"".join(skeleton)
    del skeleton
    found = iter(lists)

    def placeholder(name: str) -> Any:
        try:
            return next(found)
        except StopIteration:  # a NaN made of letters beside a list: the text is not JSON anyway
            raise RequestError("bad_message", f"{name} is not a valid JSON number") from None

    try:
        # decoded as text first: json.loads would take bytes with a byte order mark, text with one it refuses
        return json.loads(text.decode("utf-8"), parse_constant=placeholder)
    except json.JSONDecodeError as exc:
        raise RequestError("bad_message", f"not valid JSON: {exc.msg}") from exc
    except RecursionError as exc:
        raise RequestError("bad_message", "JSON nested too deeply") from exc
    except ValueError as exc:
        raise RequestError("bad_message", f"not a usable JSON number: {str(exc)[:120]}") from exc
