"""Hypothesis strategies of studio text frames: messages of every known type with valid, corrupted, missing or extra
fields, and junk (the fuzz tests of the session and of the two decoders)."""

from __future__ import annotations

import json
from typing import Any

from hypothesis import strategies as st

from arap.server.client_messages import CLIENT_MESSAGES
from arap.server.messages import Field

N_VERTICES = 5250  # the cactus of the studio fixture; indices beyond it are generated too

json_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=20),
)
junk = st.recursive(json_scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                          st.dictionaries(st.text(max_size=8), inner, max_size=4)),
                    max_leaves=12)
index = st.integers(min_value=-2, max_value=N_VERTICES + 2)
indices = st.lists(index, max_size=12)
number = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
matrix = st.one_of(
    st.just([1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0.1, 0.2, 0.0, 1]),
    st.lists(number, min_size=16, max_size=16),
)


def _valid(f: Field) -> st.SearchStrategy[Any]:
    """Values of a field's kind (mostly in range; indices may fall outside the mesh)."""
    if f.kind == "int":
        return st.integers(min_value=f.minimum if f.minimum is not None else -1000,
                           max_value=f.maximum if f.maximum is not None else 1000)
    if f.kind == "number":
        return st.floats(min_value=f.minimum if f.minimum is not None else -1e6,
                         max_value=f.maximum if f.maximum is not None else 1e6, allow_nan=False)
    if f.kind == "string":
        return st.one_of(st.sampled_from(["cactus", "bar", "a.obj"]), st.text(max_size=f.max_length or 40))
    if f.kind == "enum":
        return st.sampled_from(f.choices)
    if f.kind == "indices":
        return indices
    if f.kind == "indices_or_null":
        return st.one_of(st.none(), indices)
    if f.kind == "index_groups":
        return st.lists(st.lists(index, min_size=1, max_size=6), max_size=3)
    if f.kind == "matrices":
        return st.lists(matrix, max_size=3)
    if f.kind == "points_or_null":
        return st.one_of(st.none(), st.lists(st.lists(number, min_size=3, max_size=3), max_size=6))
    if f.kind == "stiffness_or_null":
        value = st.one_of(st.just("rigid"), st.floats(min_value=1e-3, max_value=1e6))
        return st.one_of(st.none(), st.lists(st.fixed_dictionaries(
            {"vertices": st.lists(index, max_size=6), "value": value}), max_size=3))
    if f.kind == "point_handles_or_null":
        bary = st.lists(st.floats(min_value=-0.5, max_value=1.5), min_size=3, max_size=3)
        point = st.fixed_dictionaries({"face": st.integers(min_value=-2, max_value=2 * N_VERTICES),
                                       "barycentric": st.one_of(st.just([0.2, 0.3, 0.5]), bary)},
                                      optional={"weight": st.floats(min_value=1e-3, max_value=1e6),
                                                "target": st.lists(number, min_size=3, max_size=3)})
        return st.one_of(st.none(), st.lists(point, max_size=3))
    raise AssertionError(f"no strategy for field kind {f.kind!r}")


@st.composite
def messages(draw: st.DrawFn) -> str:
    """A text frame: a message of a known type with valid, corrupted, missing or extra fields, or junk."""
    shape = draw(st.sampled_from(["message", "message", "message", "unknown type", "junk", "broken json"]))
    if shape == "junk":
        return json.dumps(draw(junk))
    if shape == "broken json":
        text = json.dumps({"type": draw(st.sampled_from(sorted(CLIENT_MESSAGES))), "x": draw(junk)})
        return text[: draw(st.integers(min_value=0, max_value=len(text) - 1))]
    mtype = draw(st.sampled_from(sorted(CLIENT_MESSAGES))) if shape == "message" else draw(st.text(max_size=12))
    out: dict[str, Any] = {"type": mtype}
    spec = CLIENT_MESSAGES.get(mtype)
    for f in spec.fields if spec is not None else ():
        how = draw(st.sampled_from(["valid", "valid", "valid", "junk", "missing"]))
        if how == "valid":
            out[f.name] = draw(_valid(f))
        elif how == "junk":
            out[f.name] = draw(junk)
    if draw(st.booleans()) and draw(st.booleans()):
        out[draw(st.text(min_size=1, max_size=8))] = draw(junk)
    return json.dumps(out)
