"""The studio's messages, as data: every message type a client may send and the server sends, with its fields
(kind, range, meaning), the protocol version, the limits and the choices the fields take. :mod:`arap.server.protocol`
validates and builds messages from these specifications and re-exports them; ``web/src/protocol.js`` and
``docs/protocol.md`` are checked against them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from arap.options import DEFAULT_ALPHA, DEFAULT_ENERGY, DEFAULT_WEIGHTS, ENERGY_TYPES, WEIGHT_TYPES
from arap.server.errors import ERROR_CODES
from arap.server.labels import ENERGY_LABELS, WEIGHT_LABELS

__all__ = [
    "ANIMATION_STATUSES",
    "CLIENT_MESSAGES",
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
    "SERVER_MESSAGES",
    "SETTLE_STATUSES",
    "UPLOAD_EXTENSIONS",
    "WEIGHTS",
    "Field",
    "MessageSpec",
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

MAX_SEQ = 2**53 - 1
"""Largest ``seq`` of a drag (the largest integer a JavaScript number holds exactly)."""

ENERGIES = ENERGY_TYPES
WEIGHTS = WEIGHT_TYPES
EXPORT_FORMATS = ("obj", "ply", "glb")
UPLOAD_EXTENSIONS = (".obj", ".off", ".ply", ".stl", ".glb")

PARAMS: dict[str, dict[str, Any]] = {
    "iterations": {"min": 1, "max": 100, "default": 2},
    "energy": {"choices": list(ENERGIES), "labels": dict(ENERGY_LABELS), "default": DEFAULT_ENERGY},
    "weights": {"choices": list(WEIGHTS), "labels": dict(WEIGHT_LABELS), "default": DEFAULT_WEIGHTS},
    "alpha": {"min": 0, "max": 1, "step": 0.005, "default": DEFAULT_ALPHA},
}
"""Solver parameters a client may set, with their ranges, display labels and defaults."""

# ---------------------------------------------------------------------------------------------- message specs
@dataclass(frozen=True)
class Field:
    """One field of a message.

    Attributes
    ----------
    name : str
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
        Inclusive range of an ``int`` field.
    choices : tuple of str
        Allowed values of an ``enum`` field.
    max_length : int or None
        Longest allowed ``string``, or most elements of a list field.
    """

    name: str
    kind: str
    doc: str
    required: bool = True
    minimum: int | None = None
    maximum: int | None = None
    choices: tuple[str, ...] = ()
    max_length: int | None = None

    def to_json(self) -> dict[str, Any]:
        """Plain description (for the generated client module)."""
        out: dict[str, Any] = {"name": self.name, "kind": self.kind, "required": self.required}
        if self.minimum is not None:
            out["min"] = self.minimum
        if self.maximum is not None:
            out["max"] = self.maximum
        if self.choices:
            out["choices"] = list(self.choices)
        if self.max_length is not None:
            out["maxLength"] = self.max_length
        return out


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


def _spec(
    type_: str, doc: str, *fields: Field, binary: bool = False, at_least_one: bool = False
) -> MessageSpec:
    return MessageSpec(type_, doc, tuple(fields), binary=binary, at_least_one=at_least_one)


CLIENT_MESSAGES: dict[str, MessageSpec] = {
    s.type: s
    for s in (
        _spec("load_builtin", "replace the session's mesh by a built-in model",
              Field("name", "string", "built-in model name (welcome.builtin_meshes)", max_length=64)),
        _spec("upload", "load an uploaded OBJ/OFF/PLY/STL/GLB file (payload: the file's bytes)",
              Field("filename", "string", "original file name; only its extension is used", max_length=255),
              binary=True),
        _spec("set_constraints", "new constraint set; transforms of all groups reset to identity",
              Field("roi", "indices_or_null", "region of interest, or null for the whole mesh"),
              Field("fixed", "indices", "vertices held in place"),
              Field("handle_groups", "index_groups", "vertices moved together by one transform per group",
                    max_length=MAX_HANDLE_GROUPS),
              Field("targets", "points_or_null", "positions of the handle vertices (groups concatenated), or null "
                    "to keep them where they are", required=False),
              Field("stiffness", "stiffness_or_null", "painted stiffness (cell weights) as [{vertices, value}], "
                    'value > 0 or "rigid", 1 elsewhere; null or absent: all 1', required=False,
                    max_length=MAX_STIFFNESS_GROUPS),
              Field("points", "point_handles_or_null", "point handles as [{face, barycentric, weight?, target?}] "
                    "(no weight: hard); each is a handle group of its own, after handle_groups; null or absent: none",
                    required=False, max_length=MAX_HANDLE_GROUPS)),
        _spec("drag", "move the handle groups; only the newest pending drag is solved",
              Field("seq", "int", "sequence number echoed by the answering vertices frame", minimum=0,
                    maximum=MAX_SEQ),
              Field("transforms", "matrices", "one affine 4x4 matrix per handle group, then per point handle, "
                    "column-major",
                    max_length=MAX_HANDLE_GROUPS)),
        _spec("end_drag", "the current deformation becomes one undo step"),
        _spec("set_params", "change solver parameters (any of the fields)",
              Field("iterations", "int", "local/global iterations per update", required=False,
                    minimum=PARAMS["iterations"]["min"], maximum=PARAMS["iterations"]["max"]),
              Field("energy", "enum", "ARAP energy", required=False, choices=ENERGIES),
              Field("weights", "enum", "edge weights", required=False, choices=WEIGHTS),
              Field("alpha", "number", "weight of the rotation term of smooth_rotations (SR-ARAP)", required=False,
                    minimum=PARAMS["alpha"]["min"], maximum=PARAMS["alpha"]["max"]),
              at_least_one=True),
        _spec("undo", "step back in the edit history"),
        _spec("redo", "step forward in the edit history"),
        _spec("reset", "back to the rest pose (undoable)"),
        _spec("apply", "the deformed shape becomes the new rest pose (undoable)"),
        _spec("export", "ask for the deformed mesh as a file (GLB keeps a textured or coloured source's UVs, "
              "textures and colours)",
              Field("format", "enum", "file format", choices=EXPORT_FORMATS)),
        _spec("get_constraints", "ask for the constraints document (command-line format), with the timeline's "
              "keyframes when given (as arap animate reads them)",
              Field("times_ms", "indices", "keyframe times in milliseconds, increasing (absent or empty: no "
                    "keyframes)", required=False, max_length=MAX_KEYFRAMES),
              Field("transforms", "matrices", "per keyframe, one column-major 4x4 matrix per handle group (point "
                    "handles excluded), keyframe after keyframe", required=False, max_length=MAX_KEYFRAME_MATRICES)),
        _spec("export_animation", "solve the keyframed animation at fps, every frame to convergence from the "
              "previous one with the session's solver and parameters (point handles hold still), and answer with an "
              "animated GLB (morph targets); animation_progress messages report the frames solved, and any new "
              "request cancels it",
              Field("times_ms", "indices", "keyframe times in milliseconds, increasing", max_length=MAX_KEYFRAMES),
              Field("transforms", "matrices", "per keyframe, one column-major 4x4 matrix per handle group (point "
                    "handles excluded), keyframe after keyframe", max_length=MAX_KEYFRAME_MATRICES),
              Field("fps", "number", "frames per second", minimum=1, maximum=MAX_FPS)),
        _spec("get_distortion", "ask for the per-vertex distortion of the current shape (the heat map)"),
    )
}
"""Messages a client may send, by type."""

SETTLE_STATUSES: tuple[str, ...] = ("settling", "settled", "stopped", "unconverged")
"""Values of the ``status`` field of ``settle`` messages."""

SERVER_MESSAGES: dict[str, MessageSpec] = {
    s.type: s
    for s in (
        _spec("welcome", "sent once on connect, followed by a mesh frame",
              Field("version", "string", "server package version"),
              Field("protocol", "int", "PROTOCOL_VERSION"),
              Field("builtin_meshes", "list", "names accepted by load_builtin"),
              Field("limits", "object", "max_upload_bytes, max_vertices, max_frame_bytes, max_handle_groups"),
              Field("params", "object", "current solver parameters")),
        _spec("mesh", "a new mesh (payload: float32[n_vertices*3], uint32[n_faces*3], then int32[file_vertices]); "
              "history is cleared",
              Field("name", "string", "model name"),
              Field("n_vertices", "int", "number of vertices"),
              Field("n_faces", "int", "number of triangles"),
              Field("report", "list", "repairs made while loading, one line each"),
              Field("file_vertices", "int", "vertices of the mesh file when repair renumbered them (the payload then "
                    "ends with the mesh vertex each file vertex became, -1 for one dropped), else 0: constraints "
                    "documents use the file's numbering"),
              binary=True),
        _spec("appearance", "how the mesh just sent is drawn, right after its mesh frame when its file has vertex "
              "colours or a texture (none for a plain mesh); payload: uint32[render_vertices] (the mesh vertex each "
              "render vertex follows), float32[render_vertices*2] (UVs, v down from the image's top row), "
              "uint32[render_faces*3] (render triangles), uint8[n_vertices*3] (sRGB vertex colours) when colors, "
              "then the texture image's texture_bytes bytes",
              Field("colors", "bool", "the payload holds a colour per mesh vertex"),
              Field("render_vertices", "int", "vertices of the render mesh (0: no texture shown)"),
              Field("render_faces", "int", "triangles of the render mesh"),
              Field("texture_bytes", "int", "size of the base-colour image at the end of the payload (0: none)"),
              Field("texture_mime", "string", "its type: image/png or image/jpeg (empty without one)"),
              Field("notes", "list", "what is not shown and why (a texture over the size limit), one line each"),
              binary=True),
        _spec("vertices", "current deformed positions (payload: float32[n_vertices*3] then uint32[movable] in a "
              "full frame, float32[subset*3] in a subset frame)",
              Field("seq", "int", "seq of the drag answered, or -1"),
              Field("skipped", "int", "stale drags dropped since the previous answer"),
              Field("iterations", "int", "iterations run"),
              Field("energies", "list", "energy after each iteration"),
              Field("solve_ms", "number", "solve time"),
              Field("ms_per_iteration", "number", "solve time per iteration"),
              Field("subset", "int", "-1: a full frame, the positions of all vertices; k >= 0: a subset frame, the "
                    "positions of the k movable vertices listed by the last full frame, in its order (the others "
                    "keep their positions)"),
              Field("movable", "int", "in a full frame, length of the list of movable vertices appended to the "
                    "positions (0: none, and no subset frame follows until the next full frame); 0 in a subset "
                    "frame"),
              binary=True),
        _spec("settle", "progress of settling: after a drag ends (and after loading, undo, redo, reset, apply or a "
              "parameter change) the server iterates until converged, streaming vertices frames (seq -1, at most 30 "
              "per second); any new request stops it at once",
              Field("status", "enum", "settling, settled (converged; also sent after undo, redo, apply and "
                    "loading when the shape shown is already settled), stopped (a request interrupted it; it "
                    "resumes once the requests are answered) or unconverged (the iteration cap was reached)",
                    choices=SETTLE_STATUSES),
              Field("iterations", "int", "iterations run so far in this settling run (0: the shape was settled "
                    "already)"),
              Field("energy", "number", "current energy, or null before the first iteration"),
              Field("seconds", "number", "time since settling started")),
        _spec("state", "session state after any change",
              Field("can_undo", "bool", ""), Field("can_redo", "bool", ""),
              Field("params", "object", "solver parameters"),
              Field("constraints", "object", "roi, fixed, handle_groups, stiffness, points as last accepted"),
              Field("transforms", "matrices", "current transform of each handle group"),
              Field("stats", "object", "n_vertices, n_faces, roi_size, n_free, factor_ms"),
              Field("rest_id", "int", "the rest pose: a new value after apply, the earlier one again when an undo "
                    "or redo goes back to it")),
        _spec("constraints", "answer to get_constraints",
              Field("document", "object", "constraints document (command-line format)")),
        _spec("export", "answer to export (payload: the file's bytes)",
              Field("filename", "string", "suggested file name"),
              Field("mime", "string", "media type"),
              binary=True),
        _spec("animation_progress", "progress of export_animation: sent before the first frame, then at most 10 "
              "times per second while frames are solved, and once more when a new request cancelled it",
              Field("status", "enum", "solving, or cancelled (a request arrived; nothing is exported)",
                    choices=ANIMATION_STATUSES),
              Field("frame", "int", "frames solved so far"),
              Field("frames", "int", "frames of the animation"),
              Field("seconds", "number", "time since the export started")),
        _spec("animation", "answer to export_animation (payload: the GLB file's bytes: the first frame as the mesh, "
              "every frame a morph target, and an animation of the morph weights)",
              Field("filename", "string", "suggested file name"),
              Field("mime", "string", "media type"),
              Field("frames", "int", "frames in the file"),
              Field("seconds", "number", "time spent solving and encoding"),
              binary=True),
        _spec("distortion", "answer to get_distortion: how far each cell is from rigid, its energy over its "
              "weighted rest size (payload: float32[n_vertices])",
              Field("high", "number", "98th percentile of the values: the top of the colour scale"),
              Field("max", "number", "largest value"),
              binary=True),
        _spec("error", "a request was rejected; the session continues unchanged",
              Field("code", "enum", "error code", choices=tuple(ERROR_CODES)),
              Field("message", "string", "explanation"),
              Field("request", "string", "type of the rejected message, or null")),
    )
}
"""Messages the server sends, by type."""
