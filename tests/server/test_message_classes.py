"""The message classes are the protocol's one description: specifications derive from them, parsing yields their
instances, the server's messages keep their wire form, and a session's refusals map to the error codes."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import pytest

from arap.server import protocol as P
from arap.server.client_messages import CLIENT_MESSAGE_CLASSES, CLIENT_MESSAGES, SetParams
from arap.server.errors import ERROR_CODES, SESSION_ERROR_CODES, request_error
from arap.server.messages import message_spec
from arap.server.server_messages import SERVER_MESSAGE_CLASSES, SERVER_MESSAGES, Error, Settle
from arap.server.session_errors import (
    BadValues,
    ConstraintsRejected,
    NoMesh,
    SessionError,
    SolveFailed,
    UnusableMesh,
)


def test_specifications_are_derived_from_the_classes() -> None:
    for specs, classes in ((CLIENT_MESSAGES, CLIENT_MESSAGE_CLASSES), (SERVER_MESSAGES, SERVER_MESSAGE_CLASSES)):
        assert list(specs) == list(classes)
        for name, cls in classes.items():
            spec = specs[name]
            assert spec is message_spec(cls) and spec.type == cls.type == name and spec.binary == cls.binary
            wired = [f.name for f in dataclasses.fields(cls) if "wire" in f.metadata]  # type: ignore[arg-type]
            assert [f.name for f in spec.fields] == wired


def test_absent_optional_fields_are_none() -> None:
    msg = P.parse_text('{"type": "set_params", "energy": "spokes"}')
    assert msg == SetParams(energy="spokes") and msg.iterations is None and msg.alpha is None
    assert [f.required for f in CLIENT_MESSAGES["set_params"].fields] == [False] * 6
    assert [(f.name, f.required) for f in CLIENT_MESSAGES["drag"].fields] == [
        ("seq", True), ("transforms", True), ("key", False)]


def test_every_message_type_is_parsed_into_its_class() -> None:
    for name, cls in CLIENT_MESSAGE_CLASSES.items():
        if cls.binary or message_spec(cls).fields:
            continue
        assert type(P.parse_text(json.dumps({"type": name}))) is cls


def test_server_messages_keep_their_wire_form() -> None:
    msg = Settle(status="settling", iterations=3, energy=None, seconds=0.5)
    assert json.dumps(msg.to_wire(), separators=(",", ":")) == \
        '{"type":"settle","status":"settling","iterations":3,"energy":null,"seconds":0.5}'
    with pytest.raises(TypeError):
        Settle(status="settled", iterations=0, energy=0.0)  # type: ignore[call-arg]


@pytest.mark.parametrize(("error", "code"), [
    (NoMesh("no mesh is loaded"), "no_mesh"),
    (ConstraintsRejected("fixed: vertex index 9 out of range 0..3"), "bad_constraints"),
    (BadValues("targets must be 2 points [x, y, z], one per handle vertex"), "bad_message"),
    (UnusableMesh("cannot export: no faces"), "bad_mesh"),
    (SolveFailed("the solve produced non-finite positions; the shape is unchanged"), "internal"),
])
def test_a_session_refusal_becomes_the_error_message_of_its_code(error: SessionError, code: str) -> None:
    wire = P.error_message(request_error(error, "drag"))
    assert wire == {"type": "error", "code": code, "message": error.message, "request": "drag"}
    assert wire == Error(code=code, message=error.message, request="drag").to_wire()


def test_every_session_refusal_has_a_code() -> None:
    assert set(SESSION_ERROR_CODES) == set(SessionError.__subclasses__())
    assert set(SESSION_ERROR_CODES.values()) <= set(ERROR_CODES)


def test_a_session_loads_nothing_of_the_wire_protocol() -> None:
    code = ("import sys, arap.server.session\n"
            "print(sorted(m for m in sys.modules if m.startswith('arap.server')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    for wire in ("protocol", "errors", "client_messages", "server_messages", "frames", "fields", "dispatch"):
        assert f"'arap.server.{wire}'" not in out, out
