"""The studio's keyframes: in the constraints document (as ``arap animate`` reads it) and exported as an animated GLB.

The page keeps the keyframes of its timeline: at a few times, one transform per handle group (those a ``drag``
sends for the groups; point handles are not animated and hold where they are). They travel as ``times_ms`` (the
keyframes' times, in milliseconds, increasing) and ``transforms`` (column-major 4×4 matrices, keyframe after
keyframe, one per handle group each).

In the document they become the ``"keyframes"`` of :mod:`arap.constraints.keyframes`, one transform per handle group,
plus an identity for the group of handles in no group when the document has such handles (fixed vertices the pose moved,
vertices outside the region of interest that it holds away from rest); ``"keyframe_base"`` gives the handles' pose
positions when those are not their rest positions (the transforms of the studio apply to the pose). The interpolation
between keyframes is that of :meth:`arap.constraints.keyframes.Keyframes.handle_targets` (the page's timeline implements
the same rule), and the export solves the frames of :func:`arap.animation.frame_times` as
:func:`arap.animation.iter_frames` does, each from the previous one, with the session's solver and parameters.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

import arap.io.formats as formats
from arap.constraints.keyframes import Keyframes
from arap.errors import ArapError
from arap.io.animated_gltf import animation_glb
from arap.options import DEFAULT_TOLERANCE
from arap.server.constraints import identity_transforms, matrices_from_json
from arap.server.numbering import document_in_file_numbering
from arap.server.protocol import MAX_FPS, RequestError

if TYPE_CHECKING:
    from arap.server.session import Session

__all__ = ["EXPORT_MIME", "MAX_EXPORT_FRAMES", "MAX_FPS", "AnimationCancelled", "ProgressCallback",
           "export_animation", "keyframes_document"]

MAX_EXPORT_FRAMES = 600
"""Most frames an animation export solves (20 s at 30 frames per second)."""
EXPORT_MIME = formats.get("glb").mime

ProgressCallback = Callable[[int, int], None]
"""``progress(frames_done, frames)``."""


class AnimationCancelled(Exception):
    """A new request arrived while the animation was being solved; nothing was exported."""


def _keyframe_matrices(session: Session, times_ms: Sequence[int] | np.ndarray,
                       transforms: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray]:
    """Times (seconds) and ``(k, g, 4, 4)`` row-major transforms of the keyframes, checked against the session."""
    times = np.asarray(times_ms, dtype=np.float64).reshape(-1) / 1000.0
    n_groups = len(session.constraints.groups)
    if n_groups == 0:
        raise RequestError("bad_constraints", "keyframes move handle groups: select a handle group first")
    if len(times) == 0:
        raise RequestError("bad_message", "no keyframes: add at least one")
    if len(transforms) != len(times) * n_groups:
        raise RequestError("bad_message", f"{len(times)} keyframes of {n_groups} handle groups need "
                           f"{len(times) * n_groups} transforms, got {len(transforms)}")
    if (np.diff(times) <= 0).any():
        raise RequestError("bad_message", "keyframe times must increase")
    T = matrices_from_json(transforms).reshape(len(times), n_groups, 4, 4)
    det = np.linalg.det(T[:, :, :3, :3])
    if (det <= 1e-12).any():
        raise RequestError("bad_message", "a keyframe's transform mirrors or flattens its handle group")
    return times, T


def _document(session: Session, times: np.ndarray, T: np.ndarray) -> tuple[dict[str, Any], dict[str, Any]]:
    """The constraints document with keyframes, in the session's mesh numbering and in the file's."""
    cs = session.constraints
    V = session.V
    mine = cs.document(V, session.transforms)
    grouped = sum(len(g) for g in cs.groups)
    extra = len(mine["handles"]) > grouped  # handles in no group: one more keyframes group, held at its pose
    handles = np.asarray(mine["handles"], dtype=np.int64)
    base = cs.document(V, identity_transforms(cs.n_groups))["targets"]  # the pose positions transforms apply to
    needs_base = extra or not np.array_equal(np.asarray(base, dtype=np.float64).reshape(-1, 3), V[handles])
    keys = []
    for t, Tk in zip(times, T, strict=True):
        mats = [m.tolist() for m in Tk] + ([np.eye(4).tolist()] if extra else [])
        keys.append({"time": float(t), "transforms": mats})
    mesh = session.mesh
    assert mesh is not None
    file_doc = dict(document_in_file_numbering(mine, mesh))
    mine = dict(mine)
    if needs_base:
        mine["keyframe_base"] = base
        base_doc = document_in_file_numbering({**cs.document(V, session.transforms), "targets": base}, mesh)
        file_doc["keyframe_base"] = base_doc["targets"]
    mine["keyframes"] = keys
    file_doc["keyframes"] = keys
    return mine, file_doc


def keyframes_document(session: Session, times_ms: Sequence[int] | np.ndarray,
                       transforms: Sequence[Sequence[float]]) -> dict[str, Any]:
    """The session's constraints document (in the mesh file's numbering) with the keyframes, as ``arap animate``
    reads it.

    Raises
    ------
    RequestError
        ``bad_message`` for keyframes that do not fit the constraint set, ``bad_constraints`` without handle groups.
    """
    times, T = _keyframe_matrices(session, times_ms, transforms)
    return _document(session, times, T)[1]


def _export(session: Session, times_ms: Sequence[int] | np.ndarray, transforms: Sequence[Sequence[float]],
                     fps: float, interrupted: Callable[[], bool],
                     progress: ProgressCallback | None = None) -> tuple[str, str, bytes, int, float]:
    """Solve the keyframed animation at ``fps`` with the session's solver and return it as an animated GLB.

    Every frame is solved to convergence (the solver's default tolerance), the first from the ``"auto"`` start and
    each other from the previous frame, as :func:`arap.animation.animate` does; point handles hold at their
    current targets. The session's shape and history are untouched; its next solve starts from the shape shown.

    Parameters
    ----------
    session : Session
    times_ms, transforms
        The keyframes (see the module description).
    fps : float
        Frames per second.
    interrupted : callable
        Polled after every iteration; True cancels the export (raises :class:`AnimationCancelled`).
    progress : callable or None
        ``progress(done, frames)`` after every frame (and with 0 before the first).

    Returns
    -------
    (filename, mime, data, frames, seconds)

    Raises
    ------
    RequestError
        ``bad_message`` for bad keyframes, more than :data:`MAX_EXPORT_FRAMES` frames or an fps out of range;
        ``bad_constraints`` when nothing can be solved.
    AnimationCancelled
        ``interrupted`` said so.
    """
    from arap.animation import frame_times

    mesh = session._require_mesh()
    solver = session.solver
    if solver is None:
        raise RequestError("bad_constraints", "nothing to solve: select fixed vertices or handles first")
    if not (0 < fps <= MAX_FPS):
        raise RequestError("bad_message", f"fps must be in (0, {MAX_FPS}], got {fps:g}")
    times, T = _keyframe_matrices(session, times_ms, transforms)
    mine, _ = _document(session, times, T)
    try:
        keys = Keyframes.from_json(mine, session.V, mesh.n_faces)
    except ArapError as exc:
        raise RequestError("bad_message", f"keyframes: {exc}") from exc
    span = keys.end - keys.start
    count = int(np.floor(span * fps + 1e-9)) + 1
    if count > MAX_EXPORT_FRAMES:
        raise RequestError("bad_message", f"{span:g} s at {fps:g} frames per second is {count:,} frames; an export "
                           f"holds at most {MAX_EXPORT_FRAMES}: lower the frame rate or shorten the animation")
    frame_t = frame_times(keys, fps)
    if len(frame_t) > MAX_EXPORT_FRAMES:
        raise RequestError("bad_message", f"{len(frame_t)} frames; an export holds at most {MAX_EXPORT_FRAMES}")
    cs = session.constraints
    handles = np.asarray(mine["handles"], dtype=np.int64)
    point_targets = cs.point_targets(session.transforms)
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
    for k, t in enumerate(frame_t):
        X[handles] = keys.handle_targets(float(t))
        try:
            result = solver.solve(X[cs.constrained], initial="auto" if k == 0 else None, tolerance=DEFAULT_TOLERANCE,
                                  point_targets=point_targets, callback=callback)
        except ArapError as exc:
            raise RequestError("bad_message", f"frame {k} at {t:g} s: {exc}") from exc
        if stopped or interrupted():
            raise AnimationCancelled
        if not np.all(np.isfinite(result.vertices)):
            raise RequestError("internal", f"frame {k} at {t:g} s has non-finite positions")
        frames[k] = result.vertices
        if progress is not None:
            progress(k + 1, len(frame_t))
    data = animation_glb(mesh.F, frame_t, frames, name=f"{mesh.name} animation")
    return f"{mesh.name}_animation.glb", EXPORT_MIME, data, len(frame_t), time.perf_counter() - t0


def export_animation(session: Session, times_ms: Sequence[int] | np.ndarray, transforms: Sequence[Sequence[float]],
                     fps: float, interrupted: Callable[[], bool],
                     progress: ProgressCallback | None = None) -> tuple[str, str, bytes, int, float]:
    """:func:`_export`, after which the session's next solve starts from the shape shown (its solver's last
    solution is an animation frame)."""
    try:
        return _export(session, times_ms, transforms, fps, interrupted, progress)
    finally:
        session.solver_moved_on()
