"""The messages the server sends, one frozen dataclass each, each field declared once: its kind by its annotation
(:class:`arap.server.messages.Wire`; one that admits None may be null), its meaning by
:func:`arap.server.messages.wire`. The server builds every message as an instance (so a message cannot miss or add a
field) and sends :meth:`~arap.server.messages.ServerMessage.to_wire`; the client module's typedefs and the
protocol document take their field lists from the same classes (:data:`SERVER_MESSAGES`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Annotated, ClassVar

from arap.server.errors import ERROR_CODES
from arap.server.messages import (
    ANIMATION_STATUSES,
    ENERGIES,
    PARAMS,
    SETTLE_STATUSES,
    WEIGHTS,
    Choice,
    Flag,
    Int,
    JsonObject,
    Matrices,
    MessageSpec,
    Number,
    ServerMessage,
    Text,
    Wire,
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

_Strings = Annotated[list[str], Wire.LIST]


@dataclass(frozen=True)
class Welcome(ServerMessage):
    type: ClassVar[str] = "welcome"
    doc: ClassVar[str] = "sent once on connect, followed by a mesh frame"
    version: Text = field(metadata=wire("server package version"))
    protocol: Int = field(metadata=wire("PROTOCOL_VERSION"))
    builtin_meshes: _Strings = field(metadata=wire("names accepted by load_builtin", js_type="string[]"))
    limits: JsonObject = field(
        metadata=wire(
            "max_upload_bytes, max_vertices, max_frame_bytes, max_handle_groups",
            js_type="{max_upload_bytes: number, max_vertices: number, max_frame_bytes: "
            "number, max_handle_groups: number}",
        )
    )
    params: JsonObject = field(metadata=wire("current solver parameters", js_type=_PARAMS_JS))


@dataclass(frozen=True)
class Mesh(ServerMessage):
    type: ClassVar[str] = "mesh"
    doc: ClassVar[str] = (
        "a new mesh (payload: float32[n_vertices*3], uint32[n_faces*3], then int32[file_vertices]); history is cleared"
    )
    binary: ClassVar[bool] = True
    name: Text = field(metadata=wire("model name"))
    n_vertices: Int = field(metadata=wire("number of vertices"))
    n_faces: Int = field(metadata=wire("number of triangles"))
    report: _Strings = field(metadata=wire("repairs made while loading, one line each", js_type="string[]"))
    file_vertices: Int = field(
        metadata=wire(
            "vertices of the mesh file when repair renumbered them (the payload then ends "
            "with the mesh vertex each file vertex became, -1 for one dropped), else 0: "
            "constraints documents use the file's numbering",
        )
    )
    n_tetrahedra: Int = field(metadata=wire("tetrahedra of a solid, which the solver deforms (0 for a surface)"))
    picture: Annotated[list[int], Wire.LIST] | None = field(default=None, metadata=wire(
        "[width, height] of the picture this mesh is (the puppet warp), else null", js_type="number[]"))
    builtin: Flag = field(default=False, metadata=wire(
        "the mesh is the built-in model of that name (load_builtin, or the server's default), not a file, upload or "
        "picture that shares its name"))


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
    colors: Flag = field(metadata=wire("the payload holds a colour per mesh vertex"))
    render_vertices: Int = field(metadata=wire("vertices of the render mesh (0: no texture shown)"))
    render_faces: Int = field(metadata=wire("triangles of the render mesh"))
    texture_bytes: Int = field(
        metadata=wire("size of the base-colour image at the end of the payload (0: none)")
    )
    texture_mime: Text = field(metadata=wire("its type: image/png or image/jpeg (empty without one)"))
    file_format: Text = field(metadata=wire(
        "format of the mesh file the look comes from (obj, ply, glb or gltf): what an export keeps it in"))
    notes: _Strings = field(
        metadata=wire(
            "what is not shown and why (a texture over the size limit), one line each", js_type="string[]"
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
    seq: Int = field(metadata=wire("seq of the drag answered, or -1"))
    skipped: Int = field(metadata=wire("stale drags dropped since the previous answer"))
    iterations: Int = field(metadata=wire("iterations run"))
    energies: Annotated[list[float | None], Wire.LIST] = field(
        metadata=wire("energy after each iteration", js_type="Array<number|null>")
    )
    solve_ms: Number = field(metadata=wire("solve time"))
    ms_per_iteration: Number = field(metadata=wire("solve time per iteration"))
    subset: Int = field(
        metadata=wire(
            "-1: a full frame, the positions of all vertices; k >= 0: a subset frame, the "
            "positions of the k movable vertices listed by the last full frame, in its order (the others "
            "keep their positions)",
        )
    )
    movable: Int = field(
        metadata=wire(
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
    status: Choice = field(
        metadata=wire(
            "settling, settled (converged; also sent after undo, redo, apply and loading when "
            "the shape shown is already settled), stopped (a request interrupted it; it resumes once the "
            "requests are answered) or unconverged (the iteration cap was reached)",
            choices=SETTLE_STATUSES,
        )
    )
    iterations: Int = field(
        metadata=wire("iterations run so far in this settling run (0: the shape was settled already)")
    )
    energy: Number | None = field(
        metadata=wire("current energy, or null before the first iteration")
    )
    seconds: Number | None = field(metadata=wire("time since settling started"))


@dataclass(frozen=True)
class State(ServerMessage):
    type: ClassVar[str] = "state"
    doc: ClassVar[str] = "session state after any change"
    can_undo: Flag = field(metadata=wire(""))
    can_redo: Flag = field(metadata=wire(""))
    params: JsonObject = field(metadata=wire("solver parameters", js_type=_PARAMS_JS))
    constraints: JsonObject = field(
        metadata=wire(
            "roi, fixed, handle_groups, stiffness, points as last accepted (a picture's pin that holds an angle: "
            "with it, in degrees)",
            js_type=f"{{roi: number[]|null, fixed: number[], handle_groups: number[][], "
            f"stiffness: {_STIFFNESS_JS}|null, points: Array<{{face: number, barycentric: number[], weight?: number, "
            "angle?: number}>}",
        )
    )
    transforms: Matrices = field(metadata=wire("current transform of each handle group"))
    rest_id: Int = field(
        metadata=wire(
            "the rest pose: a new value after apply, the earlier one again when an undo or redo goes back to it"
        )
    )
    stats: JsonObject = field(
        metadata=wire(
            "n_vertices, n_faces, roi_size, n_free, factor_ms",
            js_type="{n_vertices: number, n_faces: number, roi_size: number, n_free: number, factor_ms: number}",
        )
    )
    draw_order: Annotated[list[int], Wire.LIST] | None = field(default=None, metadata=wire(
        "a picture whose pins have depths (set_pin_depth): the order in which to draw the triangles of its textured "
        "mesh (appearance's render triangles), later over earlier where the warp overlaps them; else null",
        js_type="number[]"))
    draw_layers: Annotated[list[int], Wire.LIST] | None = field(default=None, metadata=wire(
        "with draw_order: how many of its triangles share each depth, back to front (the page draws each such "
        "layer's wireframe right after its triangles, so a layer drawn over another hides its edges); else null",
        js_type="number[]"))


@dataclass(frozen=True)
class Constraints(ServerMessage):
    type: ClassVar[str] = "constraints"
    doc: ClassVar[str] = "answer to get_constraints"
    document: JsonObject = field(metadata=wire("constraints document (command-line format)"))


@dataclass(frozen=True)
class Export(ServerMessage):
    type: ClassVar[str] = "export"
    doc: ClassVar[str] = "answer to export (payload: the file's bytes)"
    binary: ClassVar[bool] = True
    filename: Text = field(metadata=wire("suggested file name"))
    mime: Text = field(metadata=wire("media type"))


@dataclass(frozen=True)
class AnimationProgress(ServerMessage):
    type: ClassVar[str] = "animation_progress"
    doc: ClassVar[str] = (
        "progress of export_animation: sent before the first frame, then at most 10 times per "
        "second while frames are solved, and once more when a new request cancelled it"
    )
    status: Choice = field(
        metadata=wire(
            "solving, or cancelled (a request arrived; nothing is exported)", choices=ANIMATION_STATUSES
        )
    )
    frame: Int = field(metadata=wire("frames solved so far"))
    frames: Int = field(metadata=wire("frames of the animation"))
    seconds: Number = field(metadata=wire("time since the export started"))


@dataclass(frozen=True)
class Animation(ServerMessage):
    type: ClassVar[str] = "animation"
    doc: ClassVar[str] = (
        "answer to export_animation (payload: the file's bytes: a GLB with the first frame as the mesh, "
        "every frame a morph target, and an animation of the morph weights; or a picture's animated GIF or WebP, "
        "or zip of PNG frames)"
    )
    binary: ClassVar[bool] = True
    filename: Text = field(metadata=wire("suggested file name"))
    mime: Text = field(metadata=wire("media type"))
    frames: Int = field(metadata=wire("frames in the file"))
    seconds: Number = field(metadata=wire("time spent solving and encoding"))


@dataclass(frozen=True)
class Distortion(ServerMessage):
    type: ClassVar[str] = "distortion"
    doc: ClassVar[str] = (
        "answer to get_distortion: how far each cell is from rigid, its energy over its weighted "
        "rest size (payload: float32[n_vertices])"
    )
    binary: ClassVar[bool] = True
    high: Number = field(metadata=wire("98th percentile of the values: the top of the colour scale"))
    max: Number = field(metadata=wire("largest value"))


@dataclass(frozen=True)
class Preparing(ServerMessage):
    type: ClassVar[str] = "preparing"
    doc: ClassVar[str] = (
        "sent before the welcome, about once a second, while the server compiles the solver's kernels (the first "
        "run in a new environment); the welcome follows once the kernels a session needs first are ready"
    )
    done: Int = field(metadata=wire("kernels ready (compiled or loaded from the cache)"))
    total: Int = field(metadata=wire("kernels to prepare"))
    kernel: Text | None = field(
        metadata=wire("the kernel being compiled now (compiling), else the one compiled last, or null")
    )
    compiling: Flag = field(metadata=wire("whether kernel is being compiled now"))
    seconds: Number = field(metadata=wire("time since the compilation started"))


@dataclass(frozen=True)
class Error(ServerMessage):
    type: ClassVar[str] = "error"
    doc: ClassVar[str] = "a request was rejected; the session continues unchanged"
    code: Choice = field(metadata=wire("error code", choices=tuple(ERROR_CODES)))
    message: Text = field(metadata=wire("explanation"))
    request: Text | None = field(metadata=wire("type of the rejected message, or null"))


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
