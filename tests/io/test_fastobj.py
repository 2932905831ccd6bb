"""The plain-OBJ reader gives what the general parser gives, and leaves every other file to it."""

from __future__ import annotations

import io

import numpy as np
import pytest

from arap.io.fastobj import parse_plain_obj
from arap.io.meshfile import _parse


def _obj(V: np.ndarray, F: np.ndarray, face: str = "{a} {b} {c}") -> bytes:
    lines = ["# generated", "s off"] + [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in V]
    lines += ["vn 0 0 1", "vt 0 0"]
    lines += ["f " + face.format(a=a + 1, b=b + 1, c=c + 1) for a, b, c in F]
    return ("\r\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("face", ["{a} {b} {c}", "{a}/1 {b}/1 {c}/1", "{a}//1 {b}//1 {c}//1",
                                  "{a}/1/1 {b}/1/1 {c}/1/1"])
def test_plain_files_read_as_the_general_parser_reads_them(face: str) -> None:
    rng = np.random.default_rng(3)
    V = rng.normal(size=(50, 3)) * 10.0 ** rng.integers(-8, 8, size=(50, 1))
    F = rng.integers(0, 50, size=(80, 3))
    data = _obj(V, F, face)
    parsed = parse_plain_obj(data)
    assert parsed is not None
    V0, F0 = _parse(io.BytesIO(data), "obj", "test")
    np.testing.assert_array_equal(parsed[0], V0)
    np.testing.assert_array_equal(parsed[1], F0)
    np.testing.assert_array_equal(parsed[0], V)


@pytest.mark.parametrize("text", [
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4\n",  # a quad
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -3\n",  # relative indices
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\ng part\nf 1 2 3\n",  # a group
    b"v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nf 1 2 3\n",  # vertex colours
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",  # a missing vertex
    b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",  # not a plain number
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\n",  # no face
])
def test_other_files_are_left_to_the_general_parser(text: bytes) -> None:
    assert parse_plain_obj(text) is None


@pytest.mark.parametrize("every", [1, 7, 1000])
def test_vertex_lines_interleaved_with_normals_read_as_the_general_parser_reads_them(every: int) -> None:
    rng = np.random.default_rng(5)
    V = rng.normal(size=(200, 3))
    F = rng.integers(0, 200, size=(300, 3))
    lines: list[str] = []
    for i, (x, y, z) in enumerate(V.tolist()):
        lines.append(f"v\t{x!r} {y!r} {z!r}")
        if i % every == 0:
            lines.append("vn 0 0 1")
    lines += [f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}" for a, b, c in F]
    data = ("\n".join(lines)).encode()  # no line break at the end
    parsed = parse_plain_obj(data)
    assert parsed is not None
    np.testing.assert_array_equal(parsed[0], V)
    np.testing.assert_array_equal(parsed[1], F)


@pytest.mark.parametrize("text", [
    b"v 0 0 0\nv 1 v 0\nv 0 1 0\nf 1 2 3\n",  # a keyword letter inside a line
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 f\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvx 1 2 3\nf 1 2 3\n",
    b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 /3\n",
])
def test_stray_letters_are_left_to_the_general_parser(text: bytes) -> None:
    assert parse_plain_obj(text) is None
