"""Keyframes in the studio: the constraints document with keyframes and the animated GLB export."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from arap.animation import animate
from arap.io import load_mesh_bytes
from arap.server.animation_export import MAX_EXPORT_FRAMES, AnimationCancelled, export_animation, keyframes_document
from arap.server.meshdata import MeshData
from arap.server.protocol import RequestError
from arap.server.session import Session
from tests.animated_glb import glb_frames
from tests.server.helpers import StudioClient, column_major, rotation_z, translation


def _posed(session: Session) -> tuple[list[int], list[int], list[list[float]]]:
    """Anchors at the bottom, a handle group at the top, and keyframes at 0 s (rest) and 0.5 s (turned)."""
    V = session.V
    y = V[:, 1]
    fixed = np.flatnonzero(y < 0.2).tolist()
    top = np.flatnonzero(y > 4.8).tolist()
    session.set_constraints(None, fixed, [top])
    M = rotation_z(0.6, V[top].mean(axis=0), shift=(0.8, -0.2, 0.0))
    return fixed, top, [translation(0.0), column_major(M)]


def test_the_export_matches_arap_animate_on_the_saved_document(bar_session: Session, bar: MeshData,
                                                               tmp_path: Path) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    s.drag([transforms[1]])  # the shape shown is not where the animation starts
    seen: list[tuple[int, int]] = []
    name, mime, data, count, _ = export_animation(s, [0, 500], transforms, 10.0, lambda: False,
                                                    lambda done, total: seen.append((done, total)))
    assert name.endswith(".glb") and mime == "model/gltf-binary"
    assert count == 6 and seen[0] == (0, 6) and seen[-1] == (6, 6)
    times, frames = glb_frames(data)
    np.testing.assert_allclose(times, np.arange(6) / 10.0, atol=1e-6)

    document = keyframes_document(s, [0, 500], transforms)
    assert [k["time"] for k in document["keyframes"]] == [0.0, 0.5]
    assert "keyframe_base" not in document  # the handles' pose is their rest pose
    path = tmp_path / "keys.json"
    path.write_text(json.dumps(document))
    reference = animate(bar.V, bar.F, str(path), fps=10.0, energy=s.params.energy, weights=s.params.weights,
                        alpha=s.params.alpha)
    assert reference.converged.all()
    assert frames.shape == reference.vertices.shape
    np.testing.assert_allclose(frames, reference.vertices, atol=1e-5)
    # the keyframes turn the handles: the middle frame is a turn, not a cut across
    assert np.abs(frames[3] - frames[0]).max() > 0.1 and np.abs(frames[5] - frames[3]).max() > 0.1

    # the session kept its shape, and its next drag starts from it, as in a session that exported nothing
    twin = Session()
    twin.load(bar)
    _posed(twin)
    twin.drag([transforms[1]])
    twin.end_drag()
    twin.undo()
    twin.redo()  # the same shape, with the solver's last solution no longer the shape shown
    np.testing.assert_array_equal(s.U, twin.U)
    s.drag([transforms[0]])
    twin.drag([transforms[0]])
    np.testing.assert_allclose(s.U, twin.U, atol=1e-12)


def test_keyframes_of_a_selection_made_on_a_deformed_shape(bar_session: Session, bar: MeshData) -> None:
    s = bar_session
    fixed, top, transforms = _posed(s)
    s.drag([translation(0.5)])
    s.end_drag()
    s.set_constraints(None, fixed, [top])  # the pose of the new set is the deformed shape
    document = keyframes_document(s, [0, 500], transforms)
    assert "keyframe_base" in document
    _, _, data, _, _ = export_animation(s, [0, 500], transforms, 10.0, lambda: False)
    _, frames = glb_frames(data)
    reference = animate(bar.V, bar.F, document, fps=10.0)
    np.testing.assert_allclose(frames, reference.vertices, atol=1e-5)
    np.testing.assert_allclose(frames[0][top], s.constraints.pose[top], atol=1e-6)


def test_a_new_request_cancels_the_export(bar_session: Session) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    polls = 0

    def interrupted() -> bool:
        nonlocal polls
        polls += 1
        return polls > 5

    U = s.U.copy()
    with pytest.raises(AnimationCancelled):
        export_animation(s, [0, 2000], transforms, 24.0, interrupted)
    assert polls <= 7
    np.testing.assert_array_equal(s.U, U)


def test_too_many_frames_are_refused(bar_session: Session) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    seconds = (MAX_EXPORT_FRAMES + 1) / 30.0
    with pytest.raises(RequestError, match="at most 600"):
        export_animation(s, [0, round(1000 * seconds)], transforms, 30.0, lambda: False)
    with pytest.raises(RequestError, match="transforms"):
        export_animation(s, [0, 500], transforms[:1], 30.0, lambda: False)
    with pytest.raises(RequestError, match="increase"):
        export_animation(s, [500, 500], transforms, 30.0, lambda: False)


def test_export_over_the_socket_with_progress_and_cancel(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])
    M = rotation_z(0.5, studio.V[top].mean(axis=0))
    keys = {"times_ms": [0, 300], "transforms": [translation(0.0), column_major(M)]}
    studio.send({"type": "export_animation", "fps": 10, **keys})
    first = studio.expect("animation_progress").data
    assert first["status"] == "solving" and first["frame"] == 0 and first["frames"] == 4
    reply = studio.recv()
    while reply.type in ("animation_progress", "settle", "vertices"):
        reply = studio.recv()
    assert reply.type == "animation" and reply.data["frames"] == 4 and reply.payload is not None
    mesh = load_mesh_bytes(reply.payload, "animation.glb")
    assert len(mesh[0]) == len(studio.V)

    # a request right behind a long export cancels it, and is answered
    studio.send({"type": "export_animation", "fps": 120, "times_ms": [0, 4000], **{
        "transforms": keys["transforms"]}})
    studio.send({"type": "get_constraints", **keys})
    statuses = []
    reply = studio.recv()
    while reply.type in ("animation_progress", "settle", "vertices"):  # settling before it, interrupted
        if reply.type == "animation_progress":
            statuses.append(reply.data["status"])
        reply = studio.recv()
    assert statuses and statuses[-1] == "cancelled", (statuses, reply.data)
    assert reply.type == "constraints" and len(reply.data["document"]["keyframes"]) == 2
