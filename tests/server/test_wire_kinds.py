"""Each message field is declared once: its wire kind by its annotation, the check of a client's value by the one
table from kind to checker, its client type by the kind's JSDoc type; a field or a kind that misses any of these is
refused when its module is imported, not when a client first sends it."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from dataclasses import field
from enum import Enum
from typing import Annotated

import pytest

from arap.server.client_messages import CLIENT_MESSAGE_CLASSES, Upload
from arap.server.errors import RequestError
from arap.server.jsgen import JS_TYPES, generate_js
from arap.server.messages import (
    SENT_ONLY,
    ClientMessage,
    Flag,
    Int,
    Message,
    ServerMessage,
    Text,
    Wire,
    message_spec,
    wire,
)
from arap.server.protocol import CHECKS, checks_of_every_kind, parse_text
from arap.server.server_messages import SERVER_MESSAGE_CLASSES


def _message_classes() -> list[type[Message]]:
    return [*CLIENT_MESSAGE_CLASSES.values(), *SERVER_MESSAGE_CLASSES.values()]


def test_every_field_of_every_message_has_a_wire_kind_with_a_checker() -> None:
    for cls in _message_classes():
        declared = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        payload = ["payload"] if cls is Upload else []
        spec = message_spec(cls)
        assert [f.name for f in spec.fields] + payload == declared, f"{cls.__name__} has a field not on the wire"
        for f in spec.fields:
            where = f"{cls.__name__}.{f.name}"
            assert isinstance(f.kind, Wire), where
            assert f.kind is Wire.ENUM or f.kind in JS_TYPES, f"{where}: no JSDoc type of kind {f.kind.value}"
            if issubclass(cls, ClientMessage):
                assert f.kind in CHECKS, f"{where}: no checker of kind {f.kind.value}"
            if f.kind is Wire.ENUM:
                assert f.choices, where


def test_the_kinds_are_listed_once_and_every_one_a_client_sends_has_a_checker() -> None:
    assert set(CHECKS) == set(Wire) - SENT_ONLY
    assert set(JS_TYPES) == set(Wire) - {Wire.ENUM}


def test_the_checker_of_the_kind_answers_a_client_field() -> None:
    for text, message in [('{"type": "drag", "seq": 1.5, "transforms": []}', "drag.seq must be an integer"),
                          ('{"type": "export_animation", "times_ms": [0], "transforms": [], "fps": "x"}',
                           "export_animation.fps must be a finite number"),
                          ('{"type": "remesh", "density": "dense"}',
                           "remesh.density must be one of ['coarse', 'normal', 'fine'], got 'dense'")]:
        with pytest.raises(RequestError) as info:
            parse_text(text)
        assert info.value.message == message


def _declare(annotation: object, base: type[Message] = ClientMessage) -> type[Message]:
    """A message class with one field, ``x``, of that annotation."""
    return dataclasses.make_dataclass("Declared", [("x", annotation, field(metadata=wire("a field")))], bases=(base,),
                                      frozen=True, namespace={"type": "declared", "doc": "a message of a test"})


@pytest.mark.parametrize(("annotation", "match"), [
    (int, "must have one wire kind in its annotation"),
    (Annotated[int, "int"], "must have one wire kind in its annotation"),
    (Annotated[int, Wire.INT, Wire.NUMBER], "must have one wire kind in its annotation"),
    (Flag, "cannot be of kind 'bool', which only the server sends"),
    (Annotated[str, Wire.ENUM], "needs its choices"),
])
def test_a_message_field_without_a_usable_kind_is_refused_when_its_class_is_registered(annotation: object,
                                                                                        match: str) -> None:
    with pytest.raises(TypeError, match=match):
        message_spec(_declare(annotation))


def test_a_declared_field_takes_its_kind_and_nullability_from_its_annotation() -> None:
    assert message_spec(_declare(Int | None)).fields[0].kind is Wire.INT
    assert not message_spec(_declare(Int | None)).fields[0].nullable  # absent, not null: a client's optional field
    server = message_spec(_declare(Text | None, ServerMessage)).fields[0]
    assert (server.kind, server.nullable) == (Wire.STRING, True)
    assert not message_spec(_declare(Text, ServerMessage)).fields[0].nullable
    assert message_spec(_declare(Flag, ServerMessage)).fields[0].kind is Wire.BOOL


def test_a_nullable_server_field_is_typed_null_once_for_the_client() -> None:
    js = generate_js()
    assert " * @property {number[]|null} [picture] " in js
    assert "|null|null" not in js


def test_a_kind_without_a_checker_is_refused() -> None:
    new = Enum("NewWire", {"VEC3": "vec3"}, type=str)  # type: ignore[misc]
    with pytest.raises(TypeError, match=r"field kinds without a checker: \['vec3'\]"):
        checks_of_every_kind(CHECKS, [*Wire, new.VEC3])  # type: ignore[attr-defined]
    with pytest.raises(TypeError, match=r"field kinds without a checker: \['matrices'\]"):
        checks_of_every_kind({k: c for k, c in CHECKS.items() if k is not Wire.MATRICES}, Wire)
    with pytest.raises(TypeError, match=r"checkers of field kinds a client cannot send: \['bool'\]"):
        checks_of_every_kind({**CHECKS, Wire.BOOL: CHECKS[Wire.INT]}, Wire)


def test_a_kind_a_client_may_send_without_a_checker_fails_the_import_of_the_validator() -> None:
    code = ("import arap.server.messages as m\n"
            "m.SENT_ONLY = frozenset({m.Wire.OBJECT, m.Wire.LIST})  # bool: now a kind a client may send\n"
            "try:\n"
            "    import arap.server.protocol\n"
            "except TypeError as exc:\n"
            "    print('refused:', exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.startswith("refused: field kinds without a checker: ['bool']"), out.stdout + out.stderr
