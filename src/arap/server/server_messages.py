"""The messages the server sends, one frozen dataclass each, with their fields declared by
:func:`arap.server.messages.wire`: the server builds every message as an instance (so a message cannot miss or add a
field) and sends :meth:`~arap.server.messages.ServerMessage.to_wire`; the client module's typedefs and the
protocol document take their field lists from the same classes (:data:`SERVER_MESSAGES`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, ClassVar

from arap.server.errors import ERROR_CODES
from arap.server.messages import (
    ANIMATION_STATUSES,
    ENERGIES,
    PARAMS,
    SETTLE_STATUSES,
    WEIGHTS,
    MessageSpec,
    ServerMessage,
    message_spec,
    wire,
)

__all__ = [
    "SERVER_MESSAGES",
    "SERVER_MESSAGE_CLASSES",
    "Animation",
    "AnimationProgress",
    "Appearance",
    "Constraints",
    "Distortion",
    "Error",
    "Export",
    "Mesh",
    "Preparing",
    "Settle",
    "State",
    "Vertices",
    "Welcome",
]


def _union(values: tuple[str, ...] | list[str]) -> str:
    return "|".join(json.dumps(v) for v in values)


_PARAMS_JS = (f"{{iterations: number, energy: {_union(ENERGIES)}, weights: {_union(WEIGHTS)}, alpha: number, "
              f"loose: {_union(tuple(PARAMS['loose']['choices']))}, warp: {_union(tuple(PARAMS['warp']['choices']))}}}")
_STIFFNESS_JS = 'Array<{vertices: number[], value: number|"rigid"}>'
_POINTS_JS = "Array<{face: number, barycentric: number[], weight?: number}>"


@dataclass(frozen=True)
class Welcome(ServerMessage):
    type: ClassVar[str] = "welcome"
    doc: ClassVar[str] = "sent once on connect, followed by a mesh frame"
    version: str = field(metadata=wire("string", "server package version"))
    protocol: int = field(metadata=wire("int", "PROTOCOL_VERSION"))
    builtin_meshes: list[str] = field(metadata=wire("list", "names accepted by load_builtin", js_type="string[]"))
    limits: dict[str, int] = field(
        metadata=wire(
            "object",
            "max_upload_bytes, max_vertices, max_frame_bytes, max_handle_groups",
            js_type="{max_upload_bytes: number, max_vertices: number, max_frame_bytes: "
            "number, max_handle_groups: number}",
        )
    )
    params: dict[str, Any] = field(metadata=wire("object", "current solver parameters", js_type=_PARAMS_JS))


@dataclass(frozen=True)
class Mesh(ServerMessage):
    type: ClassVar[str] = "mesh"
    doc: ClassVar[str] = (
        "a new mesh (payload: float32[n_vertices*3], uint32[n_faces*3], then int32[file_vertices]); history is cleared"
    )
    binary: ClassVar[bool] = True
    name: str = field(metadata=wire("string", "model name"))
    n_vertices: int = field(metadata=wire("int", "number of vertices"))
    n_faces: int = field(metadata=wire("int", "number of triangles"))
    report: list[str] = field(metadata=wire("list", "repairs made while loading, one line each", js_type="string[]"))
    file_vertices: int = field(
        metadata=wire(
            "int",
            "vertices of the mesh file when repair renumbered them (the payload then ends "
            "with the mesh vertex each file vertex became, -1 for one dropped), else 0: "
            "constraints documents use the file's numbering",
        )
    )
    n_tetrahedra: int = field(metadata=wire("int", "tetrahedra of a solid, which the solver deforms (0 for a surface)"))
    picture: list[int] | None = field(default=None, metadata=wire(
        "list", "[width, height] of the picture this mesh is (the puppet warp), else null", nullable=True,
        js_type="number[]|null"))


@dataclass(frozen=True)
class Appearance(ServerMessage):
    type: ClassVar[str] = "appearance"
    doc: ClassVar[str] = (
        "how the mesh just sent is drawn, right after its mesh frame when its file has vertex colours or a texture "
        "(none for a plain mesh); payload: uint32[render_vertices] (the mesh vertex each render vertex follows), "
        "float32[render_vertices*2] (UVs, v down from the image's top row), uint32[render_faces*3] (render "
        "triangles), uint8[n_vertices*3] (sRGB vertex colours) when colors, then the texture image's texture_bytes "
        "bytes"
    )
    binary: ClassVar[bool] = True
    colors: bool = field(metadata=wire("bool", "the payload holds a colour per mesh vertex"))
    render_vertices: int = field(metadata=wire("int", "vertices of the render mesh (0: no texture shown)"))
    render_faces: int = field(metadata=wire("int", "triangles of the render mesh"))
    texture_bytes: int = field(
        metadata=wire("int", "size of the base-colour image at the end of the payload (0: none)")
    )
    texture_mime: str = field(metadata=wire("string", "its type: image/png or image/jpeg (empty without one)"))
    notes: list[str] = field(
        metadata=wire(
            "list", "what is not shown and why (a texture over the size limit), one line each", js_type="string[]"
        )
    )


@dataclass(frozen=True)
class Vertices(ServerMessage):
    type: ClassVar[str] = "vertices"
    doc: ClassVar[str] = (
        "current deformed positions (payload: float32[n_vertices*3] then uint32[movable] in a full "
        "frame, float32[subset*3] in a subset frame)"
    )
    binary: ClassVar[bool] = True
    seq: int = field(metadata=wire("int", "seq of the drag answered, or -1"))
    skipped: int = field(metadata=wire("int", "stale drags dropped since the previous answer"))
    iterations: int = field(metadata=wire("int", "iterations run"))
    energies: list[float | None] = field(
        metadata=wire("list", "energy after each iteration", js_type="Array<number|null>")
    )
    solve_ms: float = field(metadata=wire("number", "solve time"))
    ms_per_iteration: float = field(metadata=wire("number", "solve time per iteration"))
    subset: int = field(
        metadata=wire(
            "int",
            "-1: a full frame, the positions of all vertices; k >= 0: a subset frame, the "
            "positions of the k movable vertices listed by the last full frame, in its order (the others "
            "keep their positions)",
        )
    )
    movable: int = field(
        metadata=wire(
            "int",
            "in a full frame, length of the list of movable vertices appended to the positions "
            "(0: none, and no subset frame follows until the next full frame); 0 in a subset frame",
        )
    )


@dataclass(frozen=True)
class Settle(ServerMessage):
    type: ClassVar[str] = "settle"
    doc: ClassVar[str] = (
        "progress of settling: after a drag ends (and after loading, undo, redo, reset, apply or a parameter "
        "change) the server iterates until converged, streaming vertices frames (seq -1, at most 30 per second); "
        "any new request stops it at once"
    )
    status: str = field(
        metadata=wire(
            "enum",
            "settling, settled (converged; also sent after undo, redo, apply and loading when "
            "the shape shown is already settled), stopped (a request interrupted it; it resumes once the "
            "requests are answered) or unconverged (the iteration cap was reached)",
            choices=SETTLE_STATUSES,
        )
    )
    iterations: int = field(
        metadata=wire("int", "iterations run so far in this settling run (0: the shape was settled already)")
    )
    energy: float | None = field(
        metadata=wire("number", "current energy, or null before the first iteration", nullable=True)
    )
    seconds: float | None = field(metadata=wire("number", "time since settling started", nullable=True))


@dataclass(frozen=True)
class State(ServerMessage):
    type: ClassVar[str] = "state"
    doc: ClassVar[str] = "session state after any change"
    can_undo: bool = field(metadata=wire("bool", ""))
    can_redo: bool = field(metadata=wire("bool", ""))
    params: dict[str, Any] = field(metadata=wire("object", "solver parameters", js_type=_PARAMS_JS))
    constraints: dict[str, Any] = field(
        metadata=wire(
            "object",
            "roi, fixed, handle_groups, stiffness, points as last accepted",
            js_type=f"{{roi: number[]|null, fixed: number[], handle_groups: number[][], "
            f"stiffness: {_STIFFNESS_JS}|null, points: {_POINTS_JS}}}",
        )
    )
    transforms: list[list[float]] = field(metadata=wire("matrices", "current transform of each handle group"))
    rest_id: int = field(
        metadata=wire(
            "int", "the rest pose: a new value after apply, the earlier one again when an undo or redo goes back to it"
        )
    )
    stats: dict[str, Any] = field(
        metadata=wire(
            "object",
            "n_vertices, n_faces, roi_size, n_free, factor_ms",
            js_type="{n_vertices: number, n_faces: number, roi_size: number, n_free: number, factor_ms: number}",
        )
    )


@dataclass(frozen=True)
class Constraints(ServerMessage):
    type: ClassVar[str] = "constraints"
    doc: ClassVar[str] = "answer to get_constraints"
    document: dict[str, Any] = field(metadata=wire("object", "constraints document (command-line format)"))


@dataclass(frozen=True)
class Export(ServerMessage):
    type: ClassVar[str] = "export"
    doc: ClassVar[str] = "answer to export (payload: the file's bytes)"
    binary: ClassVar[bool] = True
    filename: str = field(metadata=wire("string", "suggested file name"))
    mime: str = field(metadata=wire("string", "media type"))


@dataclass(frozen=True)
class AnimationProgress(ServerMessage):
    type: ClassVar[str] = "animation_progress"
    doc: ClassVar[str] = (
        "progress of export_animation: sent before the first frame, then at most 10 times per "
        "second while frames are solved, and once more when a new request cancelled it"
    )
    status: str = field(
        metadata=wire(
            "enum", "solving, or cancelled (a request arrived; nothing is exported)", choices=ANIMATION_STATUSES
        )
    )
    frame: int = field(metadata=wire("int", "frames solved so far"))
    frames: int = field(metadata=wire("int", "frames of the animation"))
    seconds: float = field(metadata=wire("number", "time since the export started"))


@dataclass(frozen=True)
class Animation(ServerMessage):
    type: ClassVar[str] = "animation"
    doc: ClassVar[str] = (
        "answer to export_animation (payload: the file's bytes: a GLB with the first frame as the mesh, "
        "every frame a morph target, and an animation of the morph weights; or a picture's animated GIF or WebP, "
        "or zip of PNG frames)"
    )
    binary: ClassVar[bool] = True
    filename: str = field(metadata=wire("string", "suggested file name"))
    mime: str = field(metadata=wire("string", "media type"))
    frames: int = field(metadata=wire("int", "frames in the file"))
    seconds: float = field(metadata=wire("number", "time spent solving and encoding"))


@dataclass(frozen=True)
class Distortion(ServerMessage):
    type: ClassVar[str] = "distortion"
    doc: ClassVar[str] = (
        "answer to get_distortion: how far each cell is from rigid, its energy over its weighted "
        "rest size (payload: float32[n_vertices])"
    )
    binary: ClassVar[bool] = True
    high: float = field(metadata=wire("number", "98th percentile of the values: the top of the colour scale"))
    max: float = field(metadata=wire("number", "largest value"))


@dataclass(frozen=True)
class Preparing(ServerMessage):
    type: ClassVar[str] = "preparing"
    doc: ClassVar[str] = (
        "sent before the welcome, about once a second, while the server compiles the solver's kernels (the first "
        "run in a new environment); the welcome follows once the kernels a session needs first are ready"
    )
    done: int = field(metadata=wire("int", "kernels ready (compiled or loaded from the cache)"))
    total: int = field(metadata=wire("int", "kernels to prepare"))
    kernel: str | None = field(
        metadata=wire("string", "the kernel being compiled now (compiling), else the one compiled last, or null",
                      nullable=True)
    )
    compiling: bool = field(metadata=wire("bool", "whether kernel is being compiled now"))
    seconds: float = field(metadata=wire("number", "time since the compilation started"))


@dataclass(frozen=True)
class Error(ServerMessage):
    type: ClassVar[str] = "error"
    doc: ClassVar[str] = "a request was rejected; the session continues unchanged"
    code: str = field(metadata=wire("enum", "error code", choices=tuple(ERROR_CODES)))
    message: str = field(metadata=wire("string", "explanation"))
    request: str | None = field(metadata=wire("string", "type of the rejected message, or null", nullable=True))


SERVER_MESSAGE_CLASSES: dict[str, type[ServerMessage]] = {
    cls.type: cls
    for cls in (
        Welcome,
        Mesh,
        Appearance,
        Vertices,
        Settle,
        State,
        Constraints,
        Export,
        AnimationProgress,
        Animation,
        Distortion,
        Preparing,
        Error,
    )
}
"""The class of each message the server sends, by type."""

SERVER_MESSAGES: dict[str, MessageSpec] = {t: message_spec(cls) for t, cls in SERVER_MESSAGE_CLASSES.items()}
"""Messages the server sends, by type (derived from their classes)."""
