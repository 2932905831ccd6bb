"""What every studio message is made of: the protocol version, the limits and the choices its fields take, and
the machinery that turns a message class into its specification.

Each message is a frozen dataclass (:mod:`arap.server.client_messages`, :mod:`arap.server.server_messages`) whose
fields are declared with :func:`wire`: the wire kind, meaning and range of a field live on the class attribute that
holds it, so the validator (:mod:`arap.server.protocol`), the generated client module (:mod:`arap.server.jsgen`)
and the checks of ``docs/protocol.md`` read one description. :class:`MessageSpec` is that description, derived
from a class by :func:`message_spec`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar

import arap.io.formats as formats
from arap.options import DEFAULT_ALPHA, DEFAULT_ENERGY, DEFAULT_WEIGHTS, SURFACE_ENERGY_TYPES, WEIGHT_TYPES
from arap.server.labels import ENERGY_LABELS, LOOSE_LABELS, WARP_LABELS, WEIGHT_LABELS

__all__ = [
    "ANIMATION_STATUSES",
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
    "SETTLE_STATUSES",
    "UPLOAD_EXTENSIONS",
    "WEIGHTS",
    "ClientMessage",
    "Field",
    "Message",
    "MessageSpec",
    "ServerMessage",
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
@dataclass(frozen=True)
class Field:
    """One field of a message, as declared on its class by :func:`wire`.

    Attributes
    ----------
    name : str
        The attribute's name (also its key on the wire).
    kind : str
        ``int``, ``number``, ``string``, ``enum``, ``indices`` (list of vertex indices),
        ``indices_or_null``, ``index_groups`` (list of lists of vertex indices), ``matrices`` (list of 4×4
        matrices, 16 numbers each, column-major), ``points_or_null`` (list of ``[x, y, z]``, or null),
        ``stiffness_or_null`` (list of ``{"vertices": [...], "value": v}``, v a positive number or ``"rigid"``,
        or null), ``point_handles_or_null`` (list of ``{"face": f, "barycentric": [a, b, c]}`` with optional
        ``"weight"`` and ``"target"``, or null), ``bool``, ``object``, ``list``.
    doc : str
        What the field means.
    required : bool
    minimum, maximum : int or None
        Inclusive range of an ``int`` or ``number`` field.
    choices : tuple of str
        Allowed values of an ``enum`` field.
    max_length : int or None
        Longest allowed ``string``, or most elements of a list field.
    nullable : bool
        A server message's field that may be null.
    js_type : str or None
        The field's JSDoc type in the generated client module when more precise than its kind's.
    """

    name: str
    kind: str
    doc: str
    required: bool = True
    minimum: int | None = None
    maximum: int | None = None
    choices: tuple[str, ...] = ()
    max_length: int | None = None
    nullable: bool = False
    js_type: str | None = None


def wire(kind: str, doc: str, *, minimum: int | None = None, maximum: int | None = None,
         choices: tuple[str, ...] = (), max_length: int | None = None, nullable: bool = False,
         js_type: str | None = None) -> dict[str, Field]:
    """The metadata that makes a message class's dataclass field a field of the message (see :class:`Field`):
    ``x: int = field(metadata=wire("int", "what x means"))``. A field with a default (None, which stands for its
    absence) is optional."""
    return {"wire": Field("", kind, doc, True, minimum, maximum, tuple(choices), max_length, nullable, js_type)}


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


def message_spec(cls: type[Message]) -> MessageSpec:
    """The specification of message class ``cls``: its fields declared with :func:`wire`, in order."""
    spec = _SPECS.get(cls)
    if spec is None:
        fields = tuple(dataclasses.replace(f.metadata["wire"], name=f.name, required=f.default is dataclasses.MISSING)
                       for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                       if "wire" in f.metadata)
        spec = _SPECS[cls] = MessageSpec(cls.type, cls.doc, fields, binary=cls.binary,
                                         at_least_one=cls.at_least_one)
    return spec
