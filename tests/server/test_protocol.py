"""The protocol module: binary frames, structural validation, bounds checks and the generated client module."""

from __future__ import annotations

import json
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from arap.server import protocol as P
from arap.server.client_messages import CLIENT_MESSAGES, Drag, SetConstraints, SetParams, Upload
from arap.server.errors import ERROR_CODES, RequestError
from arap.server.frames import MAX_HEADER_BYTES, decode_binary, encode_binary
from arap.server.jsgen import generate_js
from arap.server.messages import PARAMS, PROTOCOL_VERSION
from arap.server.server_messages import SERVER_MESSAGES

ROOT = Path(__file__).resolve().parents[2]
JS_PATH = ROOT / "web" / "src" / "protocol.js"


def _identity() -> list[float]:
    return [1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


# ---------------------------------------------------------------------------------------------- binary frames
@pytest.mark.parametrize("extra", ["", "x", "xy", "xyz", "wxyz"])
def test_binary_roundtrip_pads_header_to_four_bytes(extra: str) -> None:
    header = {"type": "mesh", "name": "a" + extra}
    payload = bytes(range(12))
    frame = encode_binary(header, payload)
    (n,) = struct.unpack_from("<I", frame)
    assert (4 + n) % 4 == 0
    assert frame[4 : 4 + n].decode().rstrip(" ") == json.dumps(header, separators=(",", ":"))
    got, body = decode_binary(frame)
    assert got == header
    assert bytes(body) == payload


def test_encode_binary_concatenates_payload_parts() -> None:
    _, body = decode_binary(encode_binary({"type": "x"}, b"ab", b"cd"))
    assert bytes(body) == b"abcd"


@pytest.mark.parametrize(
    "frame",
    [
        b"",
        b"\x01\x02",
        struct.pack("<I", 100) + b"{}",
        struct.pack("<I", MAX_HEADER_BYTES + 1) + b" " * 16,
        struct.pack("<I", 4) + b"\xff\xfe{}",
        struct.pack("<I", 4) + b"[1] ",
        struct.pack("<I", 4) + b"nope",
    ],
)
def test_decode_binary_rejects_garbage(frame: bytes) -> None:
    with pytest.raises(RequestError) as info:
        decode_binary(frame)
    assert info.value.code == "bad_message"


# ---------------------------------------------------------------------------------------------- validation
def test_parse_valid_messages() -> None:
    msg = P.parse_text(json.dumps({"type": "drag", "seq": 3, "transforms": [_identity()]}))
    assert isinstance(msg, Drag) and msg.type == "drag" and msg.seq == 3 and not hasattr(msg, "payload")
    msg = P.parse_text('{"type": "set_params", "iterations": 5}')
    assert msg == SetParams(iterations=5)
    msg = P.parse_binary(encode_binary({"type": "upload", "filename": "a.obj"}, b"v 0 0 0"))
    assert isinstance(msg, Upload) and msg.type == "upload" and bytes(msg.payload or b"") == b"v 0 0 0"
    msg = P.parse_text('{"type": "set_constraints", "roi": null, "fixed": [1, 2], "handle_groups": [[3]]}')
    assert isinstance(msg, SetConstraints) and msg.roi is None and msg.handle_groups == [[3]]


BAD_TEXT = {
    "not JSON": "hello",
    "array": "[1, 2]",
    "number": "3",
    "no type": '{"seq": 1}',
    "type not a string": '{"type": 5}',
    "unknown type": '{"type": "explode"}',
    "upload as text": '{"type": "upload", "filename": "a.obj"}',
    "unknown field": '{"type": "undo", "force": true}',
    "missing field": '{"type": "drag", "seq": 1}',
    "seq as string": '{"type": "drag", "seq": "1", "transforms": []}',
    "seq as bool": '{"type": "drag", "seq": true, "transforms": []}',
    "seq negative": '{"type": "drag", "seq": -1, "transforms": []}',
    "seq float": '{"type": "drag", "seq": 1.5, "transforms": []}',
    "NaN in matrix": '{"type": "drag", "seq": 1, "transforms": [[NaN, 0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}',
    "Infinity in matrix": '{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, Infinity,0,0,1]]}',
    "overflow in matrix": '{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 1e999,0,0,1]]}',
    "null in matrix": '{"type": "drag", "seq": 1, "transforms": [[null,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}',
    "15 numbers": '{"type": "drag", "seq": 1, "transforms": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0]]}',
    "projective": '{"type": "drag", "seq": 1, "transforms": [[1,0,0,0.5, 0,1,0,0, 0,0,1,0, 0,0,0,1]]}',
    "matrix not a list": '{"type": "drag", "seq": 1, "transforms": {"a": 1}}',
    "index float": '{"type": "set_constraints", "roi": null, "fixed": [1.0], "handle_groups": []}',
    "index string": '{"type": "set_constraints", "roi": null, "fixed": ["1"], "handle_groups": []}',
    "groups flat": '{"type": "set_constraints", "roi": null, "fixed": [], "handle_groups": [1, 2]}',
    "roi string": '{"type": "set_constraints", "roi": "all", "fixed": [], "handle_groups": []}',
    "empty set_params": '{"type": "set_params"}',
    "iterations 0": '{"type": "set_params", "iterations": 0}',
    "iterations 101": '{"type": "set_params", "iterations": 101}',
    "unknown energy": '{"type": "set_params", "energy": "elastic"}',
    "export stl": '{"type": "export", "format": "stl"}',
    "builtin name number": '{"type": "load_builtin", "name": 3}',
    "deep nesting": "[" * 100000 + "]" * 100000,
}


@pytest.mark.parametrize("text", BAD_TEXT.values(), ids=BAD_TEXT.keys())
def test_parse_text_rejects(text: str) -> None:
    with pytest.raises(RequestError) as info:
        P.parse_text(text)
    assert info.value.code == "bad_message"
    assert info.value.message


def test_error_names_the_request() -> None:
    with pytest.raises(RequestError) as info:
        P.parse_text('{"type": "drag", "seq": "x", "transforms": []}')
    assert P.error_message(info.value) == {"type": "error", "code": "bad_message", "message": info.value.message,
                                       "request": "drag"}
    with pytest.raises(RequestError) as info:
        P.parse_text('{"type": "explode"}')
    assert info.value.request == "explode"
    with pytest.raises(RequestError) as info:
        P.parse_text("[]")
    assert info.value.request is None


def test_binary_frame_of_a_text_type_is_rejected() -> None:
    with pytest.raises(RequestError, match="text frame"):
        P.parse_binary(encode_binary({"type": "drag", "seq": 1, "transforms": []}))


def test_check_against_mesh() -> None:
    ok = P.parse_text('{"type": "set_constraints", "roi": [0, 9], "fixed": [1], "handle_groups": [[2, 3]]}')
    P.check_against_mesh(ok, n_vertices=10, n_groups=0)
    for fields in ('"roi": [10], "fixed": [], "handle_groups": []',
                   '"roi": null, "fixed": [-1], "handle_groups": []',
                   '"roi": null, "fixed": [], "handle_groups": [[0], [99]]'):
        msg = P.parse_text('{"type": "set_constraints", ' + fields + "}")
        with pytest.raises(RequestError) as info:
            P.check_against_mesh(msg, n_vertices=10, n_groups=0)
        assert info.value.code == "bad_constraints"
    drag = P.parse_text(json.dumps({"type": "drag", "seq": 0, "transforms": [_identity()]}))
    P.check_against_mesh(drag, n_vertices=10, n_groups=1)
    with pytest.raises(RequestError, match="2 handle groups") as info:
        P.check_against_mesh(drag, n_vertices=10, n_groups=2)
    assert info.value.code == "bad_message"


def test_request_error_rejects_unknown_codes() -> None:
    with pytest.raises(ValueError, match="unknown error code"):
        RequestError("oops", "x")


# ---------------------------------------------------------------------------------------------- generated client module
def test_generated_js_is_up_to_date() -> None:
    expected = generate_js()
    actual = JS_PATH.read_text(encoding="utf-8") if JS_PATH.exists() else ""
    assert actual == expected, "web/src/protocol.js is stale: run `python -m arap.server.protocol > " \
                               "web/src/protocol.js`"


def test_generator_entry_point_prints_the_module() -> None:
    out = subprocess.run([sys.executable, "-m", "arap.server.protocol"], capture_output=True, text=True,
                         check=True)
    assert out.stdout == generate_js()
    assert "RuntimeWarning" not in out.stderr


def test_generated_js_lists_every_type_and_code() -> None:
    js = generate_js()
    for name in [*CLIENT_MESSAGES, *SERVER_MESSAGES, *ERROR_CODES]:
        assert f'"{name}"' in js
    assert f"PROTOCOL_VERSION = {PROTOCOL_VERSION};" in js


def test_docs_describe_every_type_and_code() -> None:
    doc = (ROOT / "docs" / "protocol.md").read_text(encoding="utf-8")
    for name in [*CLIENT_MESSAGES, *SERVER_MESSAGES, *ERROR_CODES]:
        assert f"`{name}`" in doc, name


NODE_CHECK = """
import { encodeBinary, decodeBinary, meshArrays, vertexArray } from '%s';
import { CLIENT, PARAMS } from '%s';
const out = {};
const frame = encodeBinary({type: CLIENT.UPLOAD, filename: 'a.obj'}, new Uint8Array([1, 2, 3]));
const d = decodeBinary(frame);
out.upload = {header: d.header, payload: Array.from(d.payload), aligned: d.payload.byteOffset %% 4};
out.uploadFrame = Buffer.from(frame).toString('base64');
const pos = new Float32Array([1.5, 2.5, 3.5]);
const faces = new Uint32Array([0, 0, 0]);
const body = new Uint8Array(24);
body.set(new Uint8Array(pos.buffer), 0);
body.set(new Uint8Array(faces.buffer), 12);
const m = meshArrays(decodeBinary(encodeBinary({type: 'mesh', n_vertices: 1, n_faces: 1}, body)));
out.mesh = {positions: Array.from(m.positions), faces: Array.from(m.faces)};
const py = Buffer.from(process.argv[2], 'base64');
const v = decodeBinary(py.buffer.slice(py.byteOffset, py.byteOffset + py.length));
out.fromPython = {header: v.header, positions: Array.from(vertexArray(v))};
out.iterations = PARAMS.iterations;
process.stdout.write(JSON.stringify(out));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_js_helpers_agree_with_python(tmp_path: Path) -> None:
    import base64

    import numpy as np

    module = tmp_path / "protocol.mjs"
    module.write_text(generate_js(), encoding="utf-8")
    script = tmp_path / "check.mjs"
    script.write_text(NODE_CHECK % ((ROOT / "web" / "src" / "frames.js").as_uri(), module.as_uri()), encoding="utf-8")
    frame = encode_binary({"type": "vertices", "seq": 7}, np.array([0.25, -1.0, 8.0], dtype="<f4").tobytes())
    out = subprocess.run(["node", str(script), base64.b64encode(frame).decode()], capture_output=True, text=True,
                         check=True, timeout=60)
    got = json.loads(out.stdout)
    assert got["upload"] == {"header": {"type": "upload", "filename": "a.obj"}, "payload": [1, 2, 3], "aligned": 0}
    js_frame = base64.b64decode(got["uploadFrame"])
    assert js_frame == encode_binary({"type": "upload", "filename": "a.obj"}, b"\x01\x02\x03")
    msg = P.parse_binary(js_frame)
    assert isinstance(msg, Upload) and msg == Upload("a.obj", msg.payload)
    assert bytes(msg.payload or b"") == b"\x01\x02\x03"
    assert got["mesh"] == {"positions": [1.5, 2.5, 3.5], "faces": [0, 0, 0]}
    assert got["fromPython"] == {"header": {"type": "vertices", "seq": 7}, "positions": [0.25, -1.0, 8.0]}
    assert got["iterations"] == PARAMS["iterations"]
