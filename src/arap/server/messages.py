"""What every studio message is made of: the protocol version, the limits and the choices its fields take, the
kinds of value its fields carry, and the machinery that turns a message class into its specification.

Each message is a frozen dataclass (:mod:`arap.server.client_messages`, :mod:`arap.server.server_messages`); each
of its fields is declared once, on the class attribute that holds it: the field's kind by its annotation
(:class:`Wire`, usually through an alias such as :data:`Int` or :data:`Indices`), its meaning and range by
:func:`wire`. The validator (:mod:`arap.server.protocol`), the generated client module (:mod:`arap.server.jsgen`)
and the checks of ``docs/protocol.md`` read that one description: :class:`MessageSpec`, derived from a class by
:func:`message_spec`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from enum import Enum
from types import UnionType
from typing import Annotated, Any, ClassVar, Union, get_args, get_origin, get_type_hints

import arap.io.formats as formats
from arap.options import DEFAULT_ALPHA, DEFAULT_ENERGY, DEFAULT_WEIGHTS, SURFACE_ENERGY_TYPES, WEIGHT_TYPES
from arap.server.labels import ENERGY_LABELS, LOOSE_LABELS, WARP_LABELS, WEIGHT_LABELS

__all__ = [
    "ANIMATION_FORMATS",
    "ANIMATION_STATUSES",
    "EASINGS",
    "ENERGIES",
    "EXPORT_FORMATS",
    "MAX_FPS",
    "MAX_HANDLE_GROUPS",
    "MAX_KEYFRAMES",
    "MAX_KEYFRAME_MATRICES",
    "MAX_SEQ",
    "MAX_STIFFNESS_GROUPS",
    "PARAMS",
    "PROTOCOL_VERSION",
    "SENT_ONLY",
    "SETTLE_STATUSES",
    "UPLOAD_EXTENSIONS",
    "WEIGHTS",
    "Choice",
    "ClientMessage",
    "Field",
    "Flag",
    "IndexGroups",
    "IndexList",
    "Indices",
    "IndicesOrNull",
    "Int",
    "JsonObject",
    "Matrices",
    "Message",
    "MessageSpec",
    "Number",
    "PointHandlesOrNull",
    "PointsOrNull",
    "ServerMessage",
    "StiffnessOrNull",
    "Text",
    "Wire",
    "message_spec",
    "wire",
]

PROTOCOL_VERSION = 4
"""Bumped on every incompatible change of the messages below."""

MAX_HANDLE_GROUPS = 256
"""Most handle groups one constraint set may have."""

MAX_STIFFNESS_GROUPS = 256
"""Most stiffness groups (distinct painted values) in one set_constraints."""

MAX_KEYFRAMES = 1000
"""Most keyframes of a get_constraints or export_animation."""

MAX_KEYFRAME_MATRICES = 65536
"""Most transforms (keyframes times handle groups) of a get_constraints or export_animation."""

MAX_FPS = 120
"""Highest frame rate of export_animation."""

ANIMATION_STATUSES: tuple[str, ...] = ("solving", "cancelled")
"""Values of the ``status`` field of ``animation_progress`` messages."""

EASINGS: tuple[str, ...] = ("linear", "ease-in-out", "ease-in", "ease-out")
"""Easings of keyframes, by their number in ``easings`` of get_constraints and export_animation (as
:data:`arap.constraints.keyframes.EASINGS`)."""

ANIMATION_FORMATS: tuple[str, ...] = ("glb", "gif", "webp", "zip")
"""Formats of export_animation: an animated GLB; for a picture, an animated GIF or WebP or a zip of PNG frames."""

MAX_SEQ = 2**53 - 1
"""Largest ``seq`` of a drag (the largest integer a JavaScript number holds exactly)."""

ENERGIES = SURFACE_ENERGY_TYPES
WEIGHTS = WEIGHT_TYPES
EXPORT_FORMATS = formats.export_names()
"""Formats of ``export`` (those :mod:`arap.io.formats` marks for export): the mesh files, and PNG (the warped picture
of a picture, else a picture of the shape)."""
UPLOAD_EXTENSIONS = formats.upload_suffixes()
"""Files ``upload`` takes (those :mod:`arap.io.formats` marks for upload): surfaces, volume meshes (opened as solids
when they hold tetrahedra), pictures for the puppet warp (:mod:`arap.server.pictures`), and a zip of a model file with
the files it names (MTL files, textures, glTF buffers; :func:`arap.server.appearance.load_bundle_upload`)."""

PARAMS: dict[str, dict[str, Any]] = {
    "iterations": {"min": 1, "max": 100, "default": 2},
    "energy": {"choices": list(ENERGIES), "labels": dict(ENERGY_LABELS), "default": DEFAULT_ENERGY},
    "weights": {"choices": list(WEIGHTS), "labels": dict(WEIGHT_LABELS), "default": DEFAULT_WEIGHTS},
    "alpha": {"min": 0, "max": 1, "step": 0.005, "default": DEFAULT_ALPHA},
    "loose": {"choices": list(LOOSE_LABELS), "labels": dict(LOOSE_LABELS), "default": "follow"},
    "warp": {"choices": list(WARP_LABELS), "labels": dict(WARP_LABELS), "default": "rigid"},
}
"""Solver parameters a client may set, with their ranges, display labels and defaults."""

SETTLE_STATUSES: tuple[str, ...] = ("settling", "settled", "stopped", "unconverged")
"""Values of the ``status`` field of ``settle`` messages."""


# ---------------------------------------------------------------------------------------------- message fields
class Wire(str, Enum):
    """The kinds of value a message field carries on the wire: the one list of them.

    A field's kind is part of its annotation (``seq: Annotated[int, Wire.INT]``, or one of the aliases below, such
    as :data:`Int`). Every kind a client may send has a checker (:data:`arap.server.protocol.CHECKS`, verified when
    that module is imported); the kinds of :data:`SENT_ONLY` only the server sends. Each has a JSDoc type in the
    generated client module (:data:`arap.server.jsgen.JS_TYPES`; an ``enum`` field: the union of its choices).
    """

    INT = "int"
    """An integer."""
    NUMBER = "number"
    """A finite number (received as a float)."""
    STRING = "string"
    """A string."""
    ENUM = "enum"
    """One of the field's ``choices``."""
    INDICES = "indices"
    """A list of vertex indices."""
    INDICES_OR_NULL = "indices_or_null"
    """A list of vertex indices, or null."""
    INDEX_GROUPS = "index_groups"
    """A list of lists of vertex indices."""
    MATRICES = "matrices"
    """A list of affine 4×4 matrices, 16 numbers each, column-major."""
    POINTS_OR_NULL = "points_or_null"
    """A list of ``[x, y, z]``, or null."""
    STIFFNESS_OR_NULL = "stiffness_or_null"
    """A list of ``{"vertices": [...], "value": v}``, v a positive number or ``"rigid"``, or null."""
    POINT_HANDLES_OR_NULL = "point_handles_or_null"
    """A list of ``{"face": f, "barycentric": [a, b, c]}`` with optional ``"weight"`` and ``"target"``, or null."""
    BOOL = "bool"
    """True or false."""
    OBJECT = "object"
    """A JSON object."""
    LIST = "list"
    """A JSON array."""


SENT_ONLY: frozenset[Wire] = frozenset({Wire.BOOL, Wire.OBJECT, Wire.LIST})
"""Kinds only the server sends: no client message's field may have one (they have no checker)."""

IndexList = Any
"""A list of vertex indices: a Python list, or a (k,) integer NumPy array from :mod:`arap.server.decoder`."""

Int = Annotated[int, Wire.INT]
Number = Annotated[float, Wire.NUMBER]
Text = Annotated[str, Wire.STRING]
Choice = Annotated[str, Wire.ENUM]
Flag = Annotated[bool, Wire.BOOL]
JsonObject = Annotated[dict[str, Any], Wire.OBJECT]
Indices = Annotated[IndexList, Wire.INDICES]
IndicesOrNull = Annotated[IndexList | None, Wire.INDICES_OR_NULL]
IndexGroups = Annotated[list[IndexList], Wire.INDEX_GROUPS]
Matrices = Annotated[list[list[float]], Wire.MATRICES]
PointsOrNull = Annotated[Any, Wire.POINTS_OR_NULL]
"""A list of ``[x, y, z]`` (or a (t, 3) float array from :mod:`arap.server.decoder`), or None."""
StiffnessOrNull = Annotated[list[dict[str, Any]] | None, Wire.STIFFNESS_OR_NULL]
PointHandlesOrNull = Annotated[list[dict[str, Any]] | None, Wire.POINT_HANDLES_OR_NULL]


@dataclass(frozen=True)
class Field:
    """One field of a message, as declared on its class: its kind by its annotation, the rest by :func:`wire`.

    Attributes
    ----------
    name : str
        The attribute's name (also its key on the wire).
    kind : Wire
        What the field's value is.
    doc : str
        What the field means.
    required : bool
        Whether the field has no default (a default, None, stands for the field's absence).
    minimum, maximum : int or None
        Inclusive range of an ``int`` or ``number`` field.
    choices : tuple of str
        Allowed values of an ``enum`` field.
    max_length : int or None
        Longest allowed ``string``, or most elements of a list field.
    nullable : bool
        A server message's field that may be null (its annotation admits None).
    js_type : str or None
        The field's JSDoc type in the generated client module when more precise than its kind's.
    """

    name: str
    kind: Wire
    doc: str
    required: bool = True
    minimum: int | None = None
    maximum: int | None = None
    choices: tuple[str, ...] = ()
    max_length: int | None = None
    nullable: bool = False
    js_type: str | None = None


def wire(doc: str, *, minimum: int | None = None, maximum: int | None = None, choices: tuple[str, ...] = (),
         max_length: int | None = None, js_type: str | None = None) -> dict[str, dict[str, Any]]:
    """The metadata that makes a message class's dataclass field a field of the message (see :class:`Field`); its
    annotation gives its kind: ``seq: Int = field(metadata=wire("what seq means", minimum=0))``. A field with a
    default (None, which stands for its absence) is optional."""
    return {"wire": {"doc": doc, "minimum": minimum, "maximum": maximum, "choices": tuple(choices),
                     "max_length": max_length, "js_type": js_type}}


@dataclass(frozen=True)
class MessageSpec:
    """A message type: its name, whether it travels in a binary frame, its fields and what it does."""

    type: str
    doc: str
    fields: tuple[Field, ...] = ()
    binary: bool = False
    at_least_one: bool = False
    field_names: frozenset[str] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "field_names", frozenset(f.name for f in self.fields))


class Message:
    """A message class: ``type`` (its name on the wire), ``doc`` (what it does), whether it travels in a binary
    frame; its dataclass fields declared with :func:`wire` are the message's fields."""

    type: ClassVar[str]
    doc: ClassVar[str]
    binary: ClassVar[bool] = False
    at_least_one: ClassVar[bool] = False
    """Whether a message with only optional fields needs at least one of them."""


class ClientMessage(Message):
    """A structurally valid message from a client (the classes of :mod:`arap.server.client_messages`). Index and
    point lists are Python lists, or NumPy arrays when the frame was decoded by :mod:`arap.server.decoder`."""


class ServerMessage(Message):
    """A message the server sends (the classes of :mod:`arap.server.server_messages`)."""

    def to_wire(self) -> dict[str, Any]:
        """The message as sent: a text message, or the header of a binary one (``type`` first, then the fields in
        the class's order)."""
        out: dict[str, Any] = {"type": self.type}
        for f in message_spec(type(self)).fields:
            out[f.name] = getattr(self, f.name)
        return out


_SPECS: dict[type[Message], MessageSpec] = {}


def _kinds(annotation: Any) -> tuple[list[Wire], bool]:
    """The wire kinds an annotation carries (in its ``Annotated`` parts, through unions) and whether it admits None."""
    kinds: list[Wire] = []
    admits_none = False
    todo = [annotation]
    while todo:
        a = todo.pop()
        origin = get_origin(a)
        if origin is Annotated:
            kinds += [m for m in a.__metadata__ if isinstance(m, Wire)]
            todo.append(get_args(a)[0])
        elif origin is Union or origin is UnionType:
            todo += get_args(a)
        elif a is type(None):
            admits_none = True
    return kinds, admits_none


def _field_of(cls: type[Message], f: dataclasses.Field[Any], annotation: Any) -> Field:
    """The :class:`Field` declared by dataclass field ``f`` of ``cls``; a TypeError when its annotation does not give
    it exactly one kind, or a kind the message's side cannot carry."""
    where = f"{cls.__name__}.{f.name}"
    kinds, admits_none = _kinds(annotation)
    if len(kinds) != 1:
        raise TypeError(f"{where} must have one wire kind in its annotation (Annotated[..., Wire.X] or an alias such "
                        f"as Int), found {[k.value for k in kinds]}")
    kind = kinds[0]
    if issubclass(cls, ClientMessage) and kind in SENT_ONLY:
        raise TypeError(f"{where}: a client message's field cannot be of kind {kind.value!r}, which only the server "
                        "sends (it has no checker)")
    info = f.metadata["wire"]
    if kind is Wire.ENUM and not info["choices"]:
        raise TypeError(f"{where}: an enum field needs its choices")
    return Field(f.name, kind, required=f.default is dataclasses.MISSING,
                 nullable=issubclass(cls, ServerMessage) and admits_none, **info)


def message_spec(cls: type[Message]) -> MessageSpec:
    """The specification of message class ``cls``: its fields declared with :func:`wire`, in order.

    Raises
    ------
    TypeError
        A field whose annotation gives it no wire kind, or more than one, or (in a client message) a kind only the
        server sends.
    """
    spec = _SPECS.get(cls)
    if spec is None:
        hints = get_type_hints(cls, include_extras=True)
        fields = tuple(_field_of(cls, f, hints[f.name])
                       for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                       if "wire" in f.metadata)
        spec = _SPECS[cls] = MessageSpec(cls.type, cls.doc, fields, binary=cls.binary,
                                         at_least_one=cls.at_least_one)
    return spec
