"""The studio's keyframes: in the constraints document (as ``arap animate`` reads it) and exported as an animated GLB.

The page keeps the keyframes of its timeline: at a few times, one transform per handle group and per point handle
(those a ``drag`` sends). They travel as ``times_ms`` (the keyframes' times, in milliseconds, increasing),
``transforms`` (column-major 4×4 matrices, keyframe after keyframe, one per handle group each, then optionally one
per point handle: without them the point handles hold where they are), ``easings`` (per keyframe, the number in
:data:`~arap.server.messages.EASINGS` of how the handles move to the next keyframe) and ``keys`` (per keyframe, the
number under which :meth:`~arap.server.session.Session.keep_shape` kept the shape shown when it was made: that shape
is the keyframe's, given back as the frame at its time and the start of the next frame, instead of a pose solved
again, which could be another shape).

In the document they become the ``"keyframes"`` of :mod:`arap.constraints.keyframes`, one transform per handle group,
plus an identity for the group of handles in no group when the document has such handles (fixed vertices the pose moved,
vertices outside the region of interest that it holds away from rest); ``"keyframe_base"`` gives the handles' pose
positions when those are not their rest positions (the transforms of the studio apply to the pose); each keyframe
has its ``"easing"``, the point handles' ``"point_targets"``, the angles a picture's pins hold then
(``"point_angles"``, when some pin holds one; the pins' entries carry their ``"angle"`` and ``"depth"``) and its kept
``"shape"`` (in the saved document only when mesh repair kept the file's numbering). The interpolation
between keyframes is that of :meth:`arap.constraints.keyframes.Keyframes.handle_targets` (the page's timeline implements
the same rule), and the export solves the frames of :func:`arap.animation.frame_times` as
:func:`arap.animation.iter_frames` does, each from the previous one, with the session's solver and parameters.

The export is an animated GLB (:mod:`arap.io.animated_gltf`), or for a picture (a flat textured mesh, see
:mod:`arap.server.pictures`) the warped picture of every frame: an animated GIF, an animated WebP (lossless) or a
zip of PNG frames. Those need Pillow (the ``image`` extra).
"""

from __future__ import annotations

import io
import time
import zipfile
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

import arap.io.formats as formats
from arap.animation import ring_targets
from arap.constraints.keyframes import Keyframes
from arap.errors import ArapError
from arap.io.animated_gltf import animation_glb
from arap.options import DEFAULT_TOLERANCE
from arap.server.budget import MemoryBudget
from arap.server.constraints import identity_transforms, matrices_from_json
from arap.server.errors import RequestError
from arap.server.messages import ANIMATION_FORMATS, EASINGS, MAX_FPS
from arap.server.numbering import document_in_file_numbering

if TYPE_CHECKING:
    from arap.server.session import Session

__all__ = ["ANIMATION_MIMES", "EXPORT_MIME", "MAX_EXPORT_FRAMES", "AnimationCancelled", "ProgressCallback",
           "export_animation", "export_bytes", "keyframes_document"]

MAX_EXPORT_FRAMES = 600
"""Most frames an animation export solves (20 s at 30 frames per second)."""
EXPORT_MIME = formats.get("glb").mime
ANIMATION_MIMES = {"glb": EXPORT_MIME, "gif": "image/gif", "webp": formats.get("webp").mime,
                   "zip": formats.get("zip").mime}
"""The file type of each export format."""

ProgressCallback = Callable[[int, int], None]
"""``progress(frames_done, frames)``."""

SOLVED_BYTES_PER_VERTEX = 24
"""Bytes per vertex of a solved frame held until the file is written (three float64)."""
ENCODED_BYTES_PER_VERTEX = 24
"""Bytes per vertex of a frame in the GLB file (a morph target: position and normal, three float32 each)."""


def export_bytes(frames: int, n_vertices: int, n_faces: int, picture_pixels: int = 0) -> int:
    """Estimated memory of an animation export: its solved frames, and the file's bytes (a GLB: the frames, the
    mesh, a weight per frame and keyframe; a picture's animation: the frames drawn, RGBA, and as much again for their
    encoding), which are held together while the file is encoded.

    Parameters
    ----------
    frames, n_vertices, n_faces : int
    picture_pixels : int
        Pixels of the picture each frame is drawn as (0 for a GLB).

    Returns
    -------
    int
        Bytes.
    """
    solved = frames * n_vertices * SOLVED_BYTES_PER_VERTEX
    if picture_pixels:
        encoded = 2 * frames * picture_pixels * 4
    else:
        encoded = (frames + 1) * n_vertices * ENCODED_BYTES_PER_VERTEX + 12 * n_faces + 4 * frames * (frames + 1)
    return solved + encoded + 2**16  # and the file's JSON part


def _megabytes(nbytes: int) -> str:
    return f"{nbytes / 2**20:,.0f} MB"


class AnimationCancelled(Exception):
    """A new request arrived while the animation was being solved; nothing was exported."""


class _Keys:
    """The keyframes of a message, checked against the session: times (seconds), ``(k, g, 4, 4)`` row-major transforms
    of every group of the constraint set (handle groups, then point handles), easings and kept shapes (or None)."""

    def __init__(self, session: Session, times_ms: Sequence[int] | np.ndarray, transforms: Sequence[Sequence[float]],
                 easings: Sequence[int] | np.ndarray | None = None, keys: Sequence[int] | np.ndarray | None = None):
        times = np.asarray(times_ms, dtype=np.float64).reshape(-1) / 1000.0
        cs = session.constraints
        n_handles, n_all = len(cs.groups), cs.n_groups
        if n_all == 0:
            raise RequestError("bad_constraints", "keyframes move handle groups: select a handle group first")
        if len(times) == 0:
            raise RequestError("bad_message", "no keyframes: add at least one")
        per_key = len(transforms) / len(times)
        if per_key not in (n_handles, n_all) or per_key == 0:
            raise RequestError("bad_message", f"{len(times)} keyframes of {n_handles} handle groups and "
                               f"{cs.n_points} point handles need {len(times) * n_handles} or {len(times) * n_all} "
                               f"transforms, got {len(transforms)}")
        if (np.diff(times) <= 0).any():
            raise RequestError("bad_message", "keyframe times must increase")
        T = matrices_from_json(transforms).reshape(len(times), int(per_key), 4, 4)
        if per_key < n_all:  # the point handles hold where they are
            T = np.concatenate([T, np.broadcast_to(session.transforms[n_handles:], (len(times), n_all - n_handles, 4,
                                                                                   4))], axis=1)
        det = np.linalg.det(T[:, :, :3, :3])
        if (det <= 1e-12).any():
            raise RequestError("bad_message", "a keyframe's transform mirrors or flattens its handle group")
        for name, given in (("easings", easings), ("keys", keys)):
            if given is not None and len(given) != len(times):
                raise RequestError("bad_message", f"{len(times)} keyframes need {len(times)} {name}, got {len(given)}")
        codes = [0] * len(times) if easings is None else [int(e) for e in easings]
        if any(not 0 <= e < len(EASINGS) for e in codes):
            raise RequestError("bad_message", f"easings are numbers 0..{len(EASINGS) - 1} ({', '.join(EASINGS)})")
        self.times = times
        self.T = T
        self.easings = [EASINGS[e] for e in codes]
        self.shapes = [None if keys is None else session.kept_shape(int(k), cs.targets(Tk))
                       for k, Tk in zip(keys if keys is not None else [None] * len(times), T, strict=True)]


def _keyframe_matrices(session: Session, times_ms: Sequence[int] | np.ndarray,
                       transforms: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray]:
    """Times (seconds) and ``(k, g, 4, 4)`` row-major transforms of the keyframes (every group of the constraint
    set), checked against the session."""
    keys = _Keys(session, times_ms, transforms)
    return keys.times, keys.T


def _document(session: Session, keyed: _Keys, in_file: bool = True) -> tuple[dict[str, Any], dict[str, Any]]:
    """The constraints document with keyframes, in the session's mesh numbering and (``in_file``; else an empty
    dict) in the file's."""
    from arap.constraints.entries import pin_entries

    cs = session.constraints
    V = session.V
    mine = cs.document(V, session.transforms)
    if mine.get("points"):  # a picture's pins: the angles they hold now and their depths
        mine["points"] = pin_entries(mine["points"], session.pin_angles(), session.pin_depth)
    grouped = sum(len(g) for g in cs.groups)
    extra = len(mine["handles"]) > grouped  # handles in no group: one more keyframes group, held at its pose
    handles = np.asarray(mine["handles"], dtype=np.int64)
    base = cs.document(V, identity_transforms(cs.n_groups))["targets"]  # the pose positions transforms apply to
    needs_base = extra or not np.array_equal(np.asarray(base, dtype=np.float64).reshape(-1, 3), V[handles])
    mesh = session.mesh
    assert mesh is not None
    file_doc = dict(document_in_file_numbering(mine, mesh)) if in_file else {}
    same_numbering = mesh.vertex_map is None  # (an identity map is None)
    keys, file_keys = [], []
    n_handles = len(cs.groups)
    for t, Tk, easing, shape in zip(keyed.times, keyed.T, keyed.easings, keyed.shapes, strict=True):
        mats = [m.tolist() for m in Tk[:n_handles]] + ([np.eye(4).tolist()] if extra else [])
        key: dict[str, Any] = {"time": float(t), "transforms": mats}
        if easing != "linear":
            key["easing"] = easing
        points = cs.point_targets(Tk)
        if points is not None:
            key["point_targets"] = points.tolist()
        if cs.rings is not None:
            key["point_angles"] = [None if a is None else float(np.degrees(a)) for a in cs.pin_angles(Tk)]
        file_keys.append(dict(key))
        if shape is not None:
            key["shape"] = shape
            if same_numbering:
                file_keys[-1]["shape"] = shape.tolist()
        keys.append(key)
    mine = dict(mine)
    if needs_base:
        mine["keyframe_base"] = base
        if in_file:
            base_doc = document_in_file_numbering({**cs.document(V, session.transforms), "targets": base}, mesh)
            file_doc["keyframe_base"] = base_doc["targets"]
    mine["keyframes"] = keys
    file_doc["keyframes"] = file_keys
    return mine, file_doc


def keyframes_document(session: Session, times_ms: Sequence[int] | np.ndarray,
                       transforms: Sequence[Sequence[float]], easings: Sequence[int] | np.ndarray | None = None,
                       keys: Sequence[int] | np.ndarray | None = None) -> dict[str, Any]:
    """The session's constraints document (in the mesh file's numbering) with the keyframes, as ``arap animate``
    reads it.

    Raises
    ------
    RequestError
        ``bad_message`` for keyframes that do not fit the constraint set, ``bad_constraints`` without handle groups.
    """
    return _document(session, _Keys(session, times_ms, transforms, easings, keys))[1]


def _picture_encoder(mesh: Any, fmt: str) -> Callable[[np.ndarray, float], bytes] | None:
    """The encoder of the frames of a picture in ``fmt`` (None for a GLB), checked before any frame is solved.

    Raises
    ------
    RequestError
        ``bad_message``: a picture format for a mesh that is not a picture, or Pillow missing.
    """
    if fmt not in ANIMATION_FORMATS:
        raise RequestError("bad_message", f"animation format must be one of {list(ANIMATION_FORMATS)}, got {fmt!r}")
    if fmt == "glb":
        return None
    if mesh.picture is None:
        raise RequestError("bad_message", f"a {fmt} animation draws a picture: open a PNG, JPEG or WebP picture, or "
                           "export the animation as GLB")
    try:
        from PIL import Image
    except ImportError:
        raise RequestError("bad_message", f"a {fmt} animation needs Pillow, which is not installed: pip install "
                           "'arap[image]'") from None

    def encode(pictures: np.ndarray, fps: float) -> bytes:
        out = io.BytesIO()
        if fmt == "zip":
            with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as z:
                for k, pixels in enumerate(pictures):
                    png = io.BytesIO()
                    Image.fromarray(pixels, "RGBA").save(png, format="PNG")
                    z.writestr(f"frame_{k:04d}.png", png.getvalue())
            return out.getvalue()
        images = [Image.fromarray(pixels, "RGBA") for pixels in pictures]
        duration = max(round(1000.0 / fps), 1)
        options: dict[str, Any] = {"lossless": True} if fmt == "webp" else {"disposal": 2, "optimize": False}
        images[0].save(out, format=fmt.upper(), save_all=True, append_images=images[1:], duration=duration, loop=0,
                       **options)
        return out.getvalue()

    return encode


def _pictures(mesh: Any, frames: np.ndarray) -> np.ndarray:
    """The picture of ``mesh`` drawn on each frame's positions (the studio's ``(x, h − y, 0)``), ``(N, h, w, 4)``."""
    from arap.puppet.raster import draw_textured

    h, w = mesh.picture.shape[:2]
    rest = np.column_stack([mesh.V[:, 0], h - mesh.V[:, 1]])
    F = np.asarray(mesh.F, dtype=np.int64)
    return np.stack([draw_textured(mesh.picture, rest, np.column_stack([U[:, 0], h - U[:, 1]]), F, (w, h), (0, 0),
                                   None) for U in frames])


def _export(session: Session, times_ms: Sequence[int] | np.ndarray, transforms: Sequence[Sequence[float]],
            fps: float, interrupted: Callable[[], bool], progress: ProgressCallback | None = None,
            easings: Sequence[int] | np.ndarray | None = None, keys: Sequence[int] | np.ndarray | None = None,
            fmt: str = "glb", budget: MemoryBudget | None = None) -> tuple[str, str, bytes, int, float]:
    """Solve the keyframed animation at ``fps`` with the session's solver and return it as a file.

    Every frame is solved to convergence (the solver's default tolerance), the first from the ``"auto"`` start and
    each other from the previous frame, as :func:`arap.animation.animate` does, except the frames at keyframes with a
    kept shape: those are the kept shapes, and the next frame starts from them. The session's shape and history are
    untouched; its next solve starts from the shape shown.

    Parameters
    ----------
    session : Session
    times_ms, transforms, easings, keys
        The keyframes (see the module description).
    fps : float
        Frames per second.
    interrupted : callable
        Polled after every iteration; True cancels the export (raises :class:`AnimationCancelled`).
    progress : callable or None
        ``progress(done, frames)`` after every frame (and with 0 before the first, or before waiting for room in
        ``budget``).
    fmt : {"glb", "gif", "webp", "zip"}
        An animated GLB, or for a picture an animated GIF or WebP or a zip of PNG frames.
    budget : MemoryBudget or None
        The server's budget of the memory exports take at once: the export's estimate (:func:`export_bytes`) is
        held in it from the first frame until the file is encoded, after waiting for the other exports to leave
        room. None: no limit.

    Returns
    -------
    (filename, mime, data, frames, seconds)

    Raises
    ------
    RequestError
        ``bad_message`` for bad keyframes, more than :data:`MAX_EXPORT_FRAMES` frames, an fps out of range, a
        picture format for a mesh or without Pillow; ``bad_constraints`` when nothing can be solved; ``too_large``
        for an export whose estimate exceeds the whole of ``budget``.
    AnimationCancelled
        ``interrupted`` said so.
    """
    from arap.animation import frame_times

    mesh = session.require_mesh()
    solver = session.solver
    if solver is None:
        raise RequestError("bad_constraints", "nothing to solve: select fixed vertices or handles first")
    if not (0 < fps <= MAX_FPS):
        raise RequestError("bad_message", f"fps must be in (0, {MAX_FPS}], got {fps:g}")
    encoder = _picture_encoder(mesh, fmt)
    keyed = _Keys(session, times_ms, transforms, easings, keys)
    mine, _ = _document(session, keyed, in_file=False)
    try:
        frames_keys = Keyframes.from_json(mine, session.V, mesh.n_faces)
    except ArapError as exc:
        raise RequestError("bad_message", f"keyframes: {exc}") from exc
    span = frames_keys.end - frames_keys.start
    count = int(np.floor(span * fps + 1e-9)) + 1
    if count > MAX_EXPORT_FRAMES:
        raise RequestError("bad_message", f"{span:g} s at {fps:g} frames per second is {count:,} frames; an export "
                           f"holds at most {MAX_EXPORT_FRAMES}: lower the frame rate or shorten the animation")
    frame_t = frame_times(frames_keys, fps)
    if len(frame_t) > MAX_EXPORT_FRAMES:
        raise RequestError("bad_message", f"{len(frame_t)} frames; an export holds at most {MAX_EXPORT_FRAMES}")
    pixels = 0 if encoder is None or mesh.picture is None else int(mesh.picture.shape[0] * mesh.picture.shape[1])
    needed = export_bytes(len(frame_t), session.n_vertices, mesh.n_faces, pixels)
    if budget is not None and needed > budget.limit:
        raise RequestError("too_large", f"an export of {len(frame_t)} frames of {session.n_vertices:,} vertices needs "
                           f"about {_megabytes(needed)}, more than the server's limit of {_megabytes(budget.limit)} "
                           "for animation exports (arap studio --max-export-mb): lower the frame rate or shorten the "
                           "animation")
    if budget is None:
        return _solve_and_encode(session, mine, frames_keys, frame_t, fps, interrupted, progress, encoder, fmt,
                                 _rings_of(session, frames_keys))
    if progress is not None:
        progress(0, len(frame_t))  # while waiting for room
    with budget.reserve(needed, interrupted) as reserved:
        if not reserved:
            raise AnimationCancelled
        return _solve_and_encode(session, mine, frames_keys, frame_t, fps, interrupted, progress, encoder, fmt,
                                 _rings_of(session, frames_keys))


def _rings_of(session: Session, keys: Keyframes) -> Callable[[float], np.ndarray] | None:
    """:func:`arap.animation.ring_targets` of the session's pins that hold an angle, or None without any."""
    rings = session.constraints.rings
    return None if rings is None or not len(rings.pin) else ring_targets(keys, rings)


def _solve_and_encode(session: Session, mine: dict[str, Any], frames_keys: Keyframes, frame_t: np.ndarray, fps: float,
                      interrupted: Callable[[], bool], progress: ProgressCallback | None,
                      encoder: Callable[[np.ndarray, float], bytes] | None,
                      fmt: str, rings: Callable[[float], np.ndarray] | None = None
                      ) -> tuple[str, str, bytes, int, float]:
    """Solve the frames at times ``frame_t`` and encode them (see :func:`_export`); ``rings``: the targets at a time
    of the hidden rings of the pins that hold an angle (:func:`arap.animation.ring_targets`)."""
    mesh = session.require_mesh()
    solver = session.solver
    assert solver is not None
    cs = session.constraints
    handles = np.asarray(mine["handles"], dtype=np.int64)
    X = np.array(session.V, dtype=np.float64)
    X[cs.fixed] = cs.pose[cs.fixed]  # all fixed vertices; those moved away from rest are handles too
    frames = np.empty((len(frame_t), session.n_vertices, 3), dtype=np.float64)
    stopped = False

    def callback(iteration: int, energy: float) -> bool:
        nonlocal stopped
        if interrupted():
            stopped = True
            return False
        return True

    t0 = time.perf_counter()
    if progress is not None:
        progress(0, len(frame_t))
    start: Any = "auto"
    for k, t in enumerate(frame_t):
        X[handles] = frames_keys.handle_targets(float(t))
        point_targets = frames_keys.point_targets(float(t))
        if rings is not None and point_targets is not None:
            point_targets = np.concatenate([point_targets, rings(float(t))])
        key = frames_keys.key_at(float(t))
        shape = None if key is None else key.shape
        try:
            result = solver.solve(X[cs.constrained], initial=start if shape is None else shape,
                                  max_iterations=0 if shape is not None else None, tolerance=DEFAULT_TOLERANCE,
                                  point_targets=point_targets, callback=callback)
        except ArapError as exc:
            raise RequestError("bad_message", f"frame {k} at {t:g} s: {exc}") from exc
        start = None  # each next frame from this one
        if stopped or interrupted():
            raise AnimationCancelled
        frames[k] = result.vertices if shape is None else shape
        if not np.all(np.isfinite(frames[k])):
            raise RequestError("internal", f"frame {k} at {t:g} s has non-finite positions")
        if progress is not None:
            progress(k + 1, len(frame_t))
    if encoder is None:
        data = animation_glb(mesh.F, frame_t, frames, name=f"{mesh.name} animation")
    else:
        data = encoder(_pictures(mesh, frames), fps)
    return (f"{mesh.name}_animation.{fmt}", ANIMATION_MIMES[fmt], data, len(frame_t), time.perf_counter() - t0)


def export_animation(session: Session, times_ms: Sequence[int] | np.ndarray, transforms: Sequence[Sequence[float]],
                     fps: float, interrupted: Callable[[], bool], progress: ProgressCallback | None = None,
                     easings: Sequence[int] | np.ndarray | None = None, keys: Sequence[int] | np.ndarray | None = None,
                     fmt: str = "glb", budget: MemoryBudget | None = None) -> tuple[str, str, bytes, int, float]:
    """:func:`_export`, after which the session's next solve starts from the shape shown (its solver's last
    solution is an animation frame)."""
    try:
        return _export(session, times_ms, transforms, fps, interrupted, progress, easings, keys, fmt, budget)
    finally:
        session.solver_moved_on()
