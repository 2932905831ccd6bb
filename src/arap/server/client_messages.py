"""The messages a client sends, one frozen dataclass each, each field declared once: its kind by its annotation
(:class:`arap.server.messages.Wire`), its meaning and range by :func:`arap.server.messages.wire`. This is the single
description of these messages, from which the validator (:func:`arap.server.protocol.validate`) builds instances,
the dispatcher picks a handler by class, and the client module and the protocol document take their field lists
(:data:`CLIENT_MESSAGES`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, ClassVar

from arap.options import EnergyType, LoosePartsMode, WeightType
from arap.server.messages import (
    ANIMATION_FORMATS,
    EASINGS,
    ENERGIES,
    EXPORT_FORMATS,
    MAX_FPS,
    MAX_HANDLE_GROUPS,
    MAX_KEYFRAME_MATRICES,
    MAX_KEYFRAMES,
    MAX_SEQ,
    MAX_STIFFNESS_GROUPS,
    PARAMS,
    WEIGHTS,
    Choice,
    ClientMessage,
    IndexGroups,
    Indices,
    IndicesOrNull,
    Int,
    Matrices,
    MessageSpec,
    Number,
    PointHandlesOrNull,
    PointsOrNull,
    StiffnessOrNull,
    Text,
    Wire,
    message_spec,
    wire,
)

__all__ = [
    "CLIENT_MESSAGES",
    "CLIENT_MESSAGE_CLASSES",
    "Apply",
    "Drag",
    "EndDrag",
    "Export",
    "ExportAnimation",
    "GetConstraints",
    "GetDistortion",
    "KeepShape",
    "LoadBuiltin",
    "Redo",
    "Remesh",
    "Reset",
    "SetConstraints",
    "SetParams",
    "SetPinAngle",
    "SetPinDepth",
    "Undo",
    "Upload",
]

@dataclass(frozen=True)
class LoadBuiltin(ClientMessage):
    type: ClassVar[str] = "load_builtin"
    doc: ClassVar[str] = "replace the session's mesh by a built-in model"
    name: Text = field(metadata=wire("built-in model name (welcome.builtin_meshes)", max_length=64))


@dataclass(frozen=True)
class Upload(ClientMessage):
    type: ClassVar[str] = "upload"
    doc: ClassVar[str] = ("load an uploaded OBJ/OFF/PLY/STL/GLB/glTF file, or a zip of one with the files it names "
                          "(payload: the file's bytes)")
    binary: ClassVar[bool] = True
    filename: Text = field(metadata=wire("original file name; only its extension is used", max_length=255))
    payload: memoryview = field(repr=False, compare=False)
    """The file's bytes (the binary frame's payload)."""


@dataclass(frozen=True)
class SetConstraints(ClientMessage):
    type: ClassVar[str] = "set_constraints"
    doc: ClassVar[str] = "new constraint set; transforms of all groups reset to identity"
    roi: IndicesOrNull = field(metadata=wire("region of interest, or null for the whole mesh"))
    fixed: Indices = field(metadata=wire("vertices held in place"))
    handle_groups: IndexGroups = field(
        metadata=wire(
            "vertices moved together by one transform per group", max_length=MAX_HANDLE_GROUPS
        )
    )
    targets: PointsOrNull = field(
        default=None,
        metadata=wire(
            "positions of the handle vertices (groups concatenated), or null to keep them where they are",
        ),
    )
    stiffness: StiffnessOrNull = field(
        default=None,
        metadata=wire(
            'painted stiffness (cell weights) as [{vertices, value}], value > 0 or "rigid", 1 '
            "elsewhere; null or absent: all 1",
            max_length=MAX_STIFFNESS_GROUPS,
        ),
    )
    points: PointHandlesOrNull = field(
        default=None,
        metadata=wire(
            "point handles as [{face, barycentric, weight?, target?}] (no weight: hard); each "
            "is a handle group of its own, after handle_groups; null or absent: none",
            max_length=MAX_HANDLE_GROUPS,
        ),
    )


@dataclass(frozen=True)
class Drag(ClientMessage):
    type: ClassVar[str] = "drag"
    doc: ClassVar[str] = "move the handle groups; only the newest pending drag is solved"
    seq: Int = field(
        metadata=wire("sequence number echoed by the answering vertices frame", minimum=0, maximum=MAX_SEQ)
    )
    transforms: Matrices = field(
        metadata=wire(
            "one affine 4x4 matrix per handle group, then per point handle, column-major",
            max_length=MAX_HANDLE_GROUPS,
        )
    )
    key: Int | None = field(
        default=None,
        metadata=wire(
            "the keyframe (keep_shape's key) these transforms are the pose of: its kept shape is shown, unsolved, "
            "while its handles are where these transforms put them",
            minimum=0,
            maximum=MAX_SEQ,
        ),
    )


@dataclass(frozen=True)
class KeepShape(ClientMessage):
    type: ClassVar[str] = "keep_shape"
    doc: ClassVar[str] = (
        "keep the current shape, settled first, as a keyframe's (a drag or an export at that keyframe gives it "
        "back); no answer"
    )
    key: Int = field(metadata=wire("the keyframe's number, chosen by the client", minimum=0, maximum=MAX_SEQ))
    shape: PointsOrNull = field(default=None, metadata=wire(
        "the keyframe's shape, one [x, y, z] per vertex, kept as it is instead of the current shape "
        "(a keyframe kept before the connection was lost, given back to the new session); null: the current shape"))


@dataclass(frozen=True)
class EndDrag(ClientMessage):
    type: ClassVar[str] = "end_drag"
    doc: ClassVar[str] = "the current deformation becomes one undo step"


@dataclass(frozen=True)
class SetParams(ClientMessage):
    type: ClassVar[str] = "set_params"
    doc: ClassVar[str] = "change solver parameters (any of the fields)"
    at_least_one: ClassVar[bool] = True
    iterations: Int | None = field(
        default=None,
        metadata=wire(
            "local/global iterations per update",
            minimum=PARAMS["iterations"]["min"],
            maximum=PARAMS["iterations"]["max"],
        ),
    )
    energy: Annotated[EnergyType, Wire.ENUM] | None = field(
        default=None, metadata=wire("ARAP energy", choices=ENERGIES))
    weights: Annotated[WeightType, Wire.ENUM] | None = field(
        default=None, metadata=wire("edge weights", choices=WEIGHTS))
    alpha: Number | None = field(
        default=None,
        metadata=wire(
            "weight of the rotation term of smooth_rotations (SR-ARAP)",
            minimum=PARAMS["alpha"]["min"],
            maximum=PARAMS["alpha"]["max"],
        )
    )
    loose: Annotated[LoosePartsMode, Wire.ENUM] | None = field(default=None, metadata=wire(
        "what parts no constraint reaches do", choices=tuple(PARAMS["loose"]["choices"])))
    warp: Choice | None = field(default=None, metadata=wire(
        "how a picture bends (the puppet warp's mode): rigid, normal or distort",
        choices=tuple(PARAMS["warp"]["choices"])))


@dataclass(frozen=True)
class Undo(ClientMessage):
    type: ClassVar[str] = "undo"
    doc: ClassVar[str] = "step back in the edit history"


@dataclass(frozen=True)
class Redo(ClientMessage):
    type: ClassVar[str] = "redo"
    doc: ClassVar[str] = "step forward in the edit history"


@dataclass(frozen=True)
class Reset(ClientMessage):
    type: ClassVar[str] = "reset"
    doc: ClassVar[str] = "back to the rest pose (undoable)"


@dataclass(frozen=True)
class Apply(ClientMessage):
    type: ClassVar[str] = "apply"
    doc: ClassVar[str] = "the deformed shape becomes the new rest pose (undoable)"


@dataclass(frozen=True)
class SetPinDepth(ClientMessage):
    type: ClassVar[str] = "set_pin_depth"
    doc: ClassVar[str] = ("a picture's depth per pin: where parts overlap, the part of the pin of larger depth is "
                          "drawn over the other (Export PNG)")
    depth: Indices = field(metadata=wire("one depth per point handle, in their order (absent: 0)",
                                           max_length=MAX_HANDLE_GROUPS))


@dataclass(frozen=True)
class SetPinAngle(ClientMessage):
    type: ClassVar[str] = "set_pin_angle"
    doc: ClassVar[str] = ("a picture's pin holds its surroundings turned by an angle about it (Alt-drag about a pin): "
                          "a turn of the pin's transform about z adds to it; solved at once, and like a drag an undo "
                          "step with the next end_drag")
    pin: Int = field(metadata=wire("the pin: its number among the point handles", minimum=0,
                                   maximum=MAX_HANDLE_GROUPS - 1))
    angle: Number | None = field(default=None, metadata=wire(
        "degrees, counter-clockwise as seen, from the picture as opened (absent: the angle its surroundings show now)",
        minimum=-36000, maximum=36000))


@dataclass(frozen=True)
class Remesh(ClientMessage):
    type: ClassVar[str] = "remesh"
    doc: ClassVar[str] = "mesh a picture again at another density, its pins kept at their places and targets"
    density: Choice = field(metadata=wire("the mesh's density", choices=("coarse", "normal", "fine")))


@dataclass(frozen=True)
class Export(ClientMessage):
    type: ClassVar[str] = "export"
    doc: ClassVar[str] = (
        "ask for the deformed mesh as a file (GLB keeps a textured or coloured source's UVs, textures and colours)"
    )
    format: Choice = field(metadata=wire("file format", choices=EXPORT_FORMATS))


@dataclass(frozen=True)
class GetConstraints(ClientMessage):
    type: ClassVar[str] = "get_constraints"
    doc: ClassVar[str] = (
        "ask for the constraints document (command-line format), with the timeline's keyframes "
        "when given (as arap animate reads them)"
    )
    times_ms: Indices | None = field(
        default=None,
        metadata=wire(
            "keyframe times in milliseconds, increasing (absent or empty: no keyframes)",
            max_length=MAX_KEYFRAMES,
        ),
    )
    transforms: Matrices | None = field(
        default=None,
        metadata=wire(
            "per keyframe, one column-major 4x4 matrix per handle group (then, optionally, per point handle), "
            "keyframe after keyframe",
            max_length=MAX_KEYFRAME_MATRICES,
        ),
    )
    easings: IndicesOrNull = field(
        default=None,
        metadata=wire(
            "per keyframe, how the handles move to the next one: " + ", ".join(
                f"{k} {name}" for k, name in enumerate(EASINGS)) + " (absent: all linear)",
            max_length=MAX_KEYFRAMES,
        ),
    )
    keys: IndicesOrNull = field(
        default=None,
        metadata=wire(
            "per keyframe, its number for keep_shape: a shape kept under it is the keyframe's shape",
            max_length=MAX_KEYFRAMES,
        ),
    )


@dataclass(frozen=True)
class ExportAnimation(ClientMessage):
    type: ClassVar[str] = "export_animation"
    doc: ClassVar[str] = (
        "solve the keyframed animation at fps, every frame to convergence from the previous one with the session's "
        "solver and parameters (a keyframe with a kept shape gives that shape), and answer with an animated GLB "
        "(morph targets) or, for a picture, an animated GIF or WebP or a zip of PNG frames; animation_progress "
        "messages report the frames solved, and any new request cancels it"
    )
    times_ms: Indices = field(
        metadata=wire("keyframe times in milliseconds, increasing", max_length=MAX_KEYFRAMES)
    )
    transforms: Matrices = field(
        metadata=wire(
            "per keyframe, one column-major 4x4 matrix per handle group "
            "(then, optionally, per point handle), keyframe after keyframe",
            max_length=MAX_KEYFRAME_MATRICES,
        )
    )
    fps: Number = field(metadata=wire("frames per second", minimum=1, maximum=MAX_FPS))
    easings: IndicesOrNull = field(
        default=None,
        metadata=wire(
            "per keyframe, how the handles move to the next one: " + ", ".join(
                f"{k} {name}" for k, name in enumerate(EASINGS)) + " (absent: all linear)",
            max_length=MAX_KEYFRAMES,
        ),
    )
    keys: IndicesOrNull = field(
        default=None,
        metadata=wire(
            "per keyframe, its number for keep_shape: a shape kept under it is the keyframe's shape",
            max_length=MAX_KEYFRAMES,
        ),
    )
    format: Choice = field(default="glb", metadata=wire("file format (gif, webp, zip: pictures only)",
                                                     choices=ANIMATION_FORMATS))


@dataclass(frozen=True)
class GetDistortion(ClientMessage):
    type: ClassVar[str] = "get_distortion"
    doc: ClassVar[str] = "ask for the per-vertex distortion of the current shape (the heat map)"


CLIENT_MESSAGE_CLASSES: dict[str, type[ClientMessage]] = {
    cls.type: cls
    for cls in (
        LoadBuiltin,
        Upload,
        SetConstraints,
        Drag,
        EndDrag,
        SetParams,
        Undo,
        Redo,
        Reset,
        Apply,
        Export,
        GetConstraints,
        ExportAnimation,
        GetDistortion,
        KeepShape,
        SetPinDepth,
        SetPinAngle,
        Remesh,
    )
}
"""The class of each message a client may send, by type."""

CLIENT_MESSAGES: dict[str, MessageSpec] = {t: message_spec(cls) for t, cls in CLIENT_MESSAGE_CLASSES.items()}
"""Messages a client may send, by type (derived from their classes)."""
