"""Large text frames are decoded with bounded memory (lists of numbers straight into arrays, limits counted before
decoding) and give the same messages and the same refusals as small ones."""

from __future__ import annotations

import json
import time
import tracemalloc
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings

from arap.server import bulkjson
from arap.server.bulkjson import INLINE_BYTES, MAX_PARTS, NumberList, loads_bulk
from arap.server.client_messages import SetConstraints
from arap.server.decoder import arrays_from_lists, decode_text_frame
from arap.server.errors import RequestError
from arap.server.messages import ClientMessage
from arap.server.protocol import check_against_mesh, parse_large_text, parse_text
from tests.server.fuzz_messages import messages as fuzzed_messages
from tests.waiting import scaled

pytestmark = pytest.mark.timeout(120)

LONG = list(range(1000, 1100))  # longer than INLINE_BYTES as JSON
FLOATS = [0.1 * i + 1e-17 for i in range(40)]


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b) and type(a) is type(b)


def _both(text: str) -> tuple[ClientMessage | RequestError, ClientMessage | RequestError]:
    out: list[ClientMessage | RequestError] = []
    for decode in (lambda: arrays_from_lists(parse_text(text)), lambda: parse_large_text(text.encode())):
        try:
            out.append(arrays_from_lists(decode()))
        except RequestError as exc:
            out.append(exc)
    return out[0], out[1]


def _message(**fields: Any) -> str:
    return json.dumps({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": [], **fields})


VALID = [
    _message(fixed=LONG, roi=[*LONG, 5, 6], handle_groups=[[1, 2], LONG[:30], []]),
    _message(fixed=LONG, handle_groups=[LONG], targets=[[x, -x, 2.5e-3] for x in FLOATS[:len(LONG)]] * 3
             and [[float(x), 0, -1e-300] for x in LONG]),
    _message(handle_groups=[[1]], targets=[[0.123456789012345678, 1e10, -3]],
             stiffness=[{"vertices": LONG, "value": 2.5}, {"vertices": [7], "value": "rigid"}],
             points=[{"face": 3, "barycentric": [0.333333333333333314829616256247, 0.33333333333333331482961625,
                                                 0.33333333333333331482961625], "target": FLOATS[:3]}]),
    _message(fixed=[-0, 0, 2**40, 3], handle_groups=[[2**31], [-(2**31) - 1], LONG]),
    json.dumps({"type": "drag", "seq": 3, "transforms": [[1.00000000000001, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0,
                                                          0.1234567890123, 2.5, -3.75, 1]] * 3}),
    json.dumps({"type": "undo"}) + " " * 1000,
    '{"type":"set_constraints","\\u0066ixed":[' + ",".join(map(str, LONG)) + '],"roi":null,"handle_groups":[[ 1 ,'
    '\n2\t] , [ ] ,[\r3]]}',
    '{"type":"set_constraints","roi":null,"fixed":[],"handle_groups":[[],[' + ", ".join(map(str, LONG)) + "],[]]}",
    _message(fixed=LONG).replace("1050", "9" * 30).replace("1060", "-" + "8" * 19),  # beyond int64: a list
    _message(fixed=LONG).replace("1050", str(2**63 - 1)).replace("1060", str(-(2**63))),
    _message(fixed=[0] * 300_000 + [2**31, 5] + [1] * 300_000),  # more than one chunk, widened to int64
]

INVALID = [
    _message(fixed=[*LONG, 1.5]),
    _message(fixed=[*LONG, 1e3]),
    _message(handle_groups=[LONG, [*LONG[:3], 2.0]]),
    _message(handle_groups=[LONG] * 300),
    _message(handle_groups=[[i] for i in range(300)]),
    _message(handle_groups=LONG),
    _message(fixed=[LONG, LONG]),
    _message(roi=[[1, 2]] * 40),
    _message(handle_groups=[LONG], targets=[[1.0, 2.0]] * len(LONG)),
    _message(handle_groups=[LONG], targets=[[1.0, 2.0, 3.0]] * (len(LONG) - 1)),
    _message(handle_groups=[LONG], targets=[[1.0, 2.0, 3.0]] * (len(LONG) - 1) + [[1e308, 1e400, 0]]),
    _message(fixed=LONG, stiffness=[LONG]),
    _message(fixed=LONG, stiffness=[{"vertices": [*LONG, 0.5], "value": 2}]),
    _message(fixed=LONG, stiffness=[{"vertices": LONG, "value": LONG}]),
    _message(fixed=LONG, points=LONG),
    _message(fixed=LONG, points=[{"face": 1, "barycentric": FLOATS}]),
    _message(fixed=LONG, points=[[1, 2, 3]] * 300),
    json.dumps({"type": "drag", "seq": LONG, "transforms": []}),
    json.dumps({"type": "drag", "seq": 1, "transforms": [FLOATS[:16]]}),
    json.dumps({"type": "drag", "seq": 1, "transforms": [FLOATS[:15]] * 3}),
    json.dumps({"type": "drag", "seq": 1, "transforms": [[1.5] * 16] * 300}),
    json.dumps({"type": LONG}),
    json.dumps({"type": "undo", "extra": LONG}),
    json.dumps(LONG),
    json.dumps([LONG, LONG]),
    _message(fixed=LONG)[:-1],
    _message(fixed=LONG).replace("1050", "01050"),
    _message(fixed=LONG).replace("1050", "+1050"),
    _message(fixed=LONG).replace("1050", "1050.").replace("1051", ".5"),
    _message(fixed=LONG).replace("1050", "NaN"),
    _message(fixed=LONG).replace("1050", "-Infinity"),
    _message(fixed=LONG).replace(", 1050", ",, 1050"),
    _message(fixed=LONG).replace("1099]", "1099,]"),
    _message(fixed=LONG).replace("1050", "9" * 5000),
    '{"type":"set_constraints","roi":null,"fixed":[' + ",".join(map(str, LONG)) + '],"handle_groups":[],"x":"\x01"}',
    '{"type":"set_constraints","roi":null,"fixed":"[' + ",".join(map(str, LONG)) + ']","handle_groups":[]}',
    "\ufeff" + _message(fixed=LONG),
    _message(roi=[LONG, None]),
    _message(roi=[{"a": LONG}]),
    _message(fixed=LONG, handle_groups=[[1], {"a": [LONG]}]),
    _message(fixed=LONG).replace('"fixed": [', '"fixed": Na['),
    _message(fixed=LONG).replace('"fixed": [', '"fixed": -[').replace('"handle_groups": []', '"handle_groups": Na'),
]


@pytest.mark.parametrize("text", VALID)
def test_large_text_gives_the_same_message(text: str) -> None:
    small, large = _both(text)
    assert isinstance(small, ClientMessage), small
    assert isinstance(large, ClientMessage), large
    assert small.type == large.type
    assert _same(vars(small), vars(large)), (small, large)


@pytest.mark.parametrize("text", INVALID)
def test_large_text_gives_the_same_refusal(text: str) -> None:
    small, large = _both(text)
    assert isinstance(small, RequestError), small
    assert isinstance(large, RequestError), large
    assert small.code == large.code, (small.message, large.message)
    assert small.request in (large.request, None), (small.request, large.request)  # json.loads may refuse first


def test_long_lists_are_kept_as_text_until_checked() -> None:
    obj = loads_bulk(_message(fixed=LONG, handle_groups=[[1], [2, 3]], targets=[[1, 2, 3]] * 40).encode())
    assert isinstance(obj["fixed"], NumberList) and len(obj["fixed"]) == len(LONG) and not obj["fixed"].nested
    assert obj["handle_groups"] == [[1], [2, 3]]  # short: decoded as json.loads does (len < INLINE_BYTES)
    assert isinstance(obj["targets"], NumberList) and len(obj["targets"]) == 40 and obj["targets"].nested
    assert len(json.dumps([[1], [2, 3]])) <= INLINE_BYTES
    # brackets in strings are text
    assert loads_bulk(b'{"a": "[1,2,3] \\" [[4]]", "b": [' + b"1," * 100 + b"2]}")["a"] == '[1,2,3] " [[4]]'


def test_too_many_values_outside_number_lists_are_refused_before_decoding() -> None:
    text = json.dumps({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": [],
                       "stiffness": [{}] * (MAX_PARTS + 1)})
    with pytest.raises(RequestError, match="values outside lists of numbers"):
        loads_bulk(text.encode())


def _peak(fn: Any, *args: Any) -> tuple[Any, int, float]:
    """Result (or RequestError), peak of traced allocations (bytes) and seconds of ``fn(*args)``."""
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        try:
            result = fn(*args)
        except RequestError as exc:
            result = exc
        return result, tracemalloc.get_traced_memory()[1], time.perf_counter() - t0
    finally:
        tracemalloc.stop()


def test_many_handle_groups_are_refused_by_count_in_bounded_memory() -> None:
    data = ('{"type":"set_constraints","roi":null,"fixed":[],"handle_groups":['
            + ",".join(["[1]"] * 2_000_000) + "]}").encode()  # 8 MB
    error, peak, seconds = _peak(decode_text_frame, data)
    assert peak < 2 * len(data), peak  # json.loads: 2 million lists, about 20 times the text
    assert isinstance(error, RequestError) and error.code == "bad_message"
    assert "handle_groups has 2000000 groups, at most 256" in error.message
    assert seconds < scaled(10)  # stretched on a machine running other jobs too


def test_many_indices_take_a_few_bytes_each() -> None:
    count = 3_000_000
    data = ('{"type":"set_constraints","roi":null,"fixed":[' + ",".join(["0"] * count) + '],"handle_groups":['
            + ",".join(["7"] * count) + "]]").encode()[:-1] + b"]}"
    data = data.replace(b'"handle_groups":[', b'"handle_groups":[[')
    msg, peak, _ = _peak(decode_text_frame, data)
    assert peak < 2.5 * len(data), peak  # json.loads: a list of 8-byte pointers and the int64 array, 8 times
    assert isinstance(msg, ClientMessage), msg
    assert isinstance(msg, SetConstraints)
    assert len(msg.fixed) == count and msg.handle_groups[0].sum() == 7 * count
    assert msg.fixed.dtype == np.int32


def test_an_index_list_longer_than_the_mesh_is_refused_before_the_session_copies_it() -> None:
    msg = parse_large_text(_message(fixed=[0] * 1000, handle_groups=[[1, 2]]).encode())
    with pytest.raises(RequestError, match="fixed lists 1,000 vertex indices, more than the mesh's 999") as info:
        check_against_mesh(msg, n_vertices=999, n_groups=0)
    assert info.value.code == "bad_constraints"
    check_against_mesh(msg, n_vertices=1000, n_groups=0)


def test_frames_decoded_on_a_thread_take_bounded_memory_too() -> None:
    text = ('{"type":"set_constraints","roi":null,"fixed":[],"handle_groups":['
            + ",".join(["[1]"] * 400_000) + "]}")  # 1.6 MB: between OFF_LOOP_BYTES and PROCESS_BYTES
    error, peak, _ = _peak(lambda: parse_text(text, cooperative=True))
    assert peak < 3 * len(text), peak  # json.loads: 400,000 lists
    assert isinstance(error, RequestError) and "has 400000 groups, at most 256" in error.message
    msg = parse_text(_message(fixed=LONG), cooperative=True)
    assert isinstance(msg, SetConstraints) and isinstance(msg.fixed, np.ndarray) and msg.fixed.tolist() == LONG


@settings(max_examples=300, deadline=None, database=None)
@given(text=fuzzed_messages())
def test_fuzzed_messages_get_the_same_answer_from_both_decoders(text: str) -> None:
    """Every list of numbers, however short, decoded the bulk way (INLINE_BYTES 0) gives what json.loads gives."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(bulkjson, "INLINE_BYTES", 0)
        small, large = _both(text)
    if isinstance(small, RequestError):
        assert isinstance(large, RequestError), (text, small.message, large)
        assert small.code == large.code, (text, small.message, large.message)
    else:
        assert isinstance(large, ClientMessage), (text, large)
        assert small.type == large.type and _same(vars(small), vars(large)), (text, small, large)
