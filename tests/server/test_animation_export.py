"""Keyframes in the studio: the constraints document with keyframes and the animated GLB export."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from starlette.testclient import TestClient

from arap.animation import animate
from arap.io import load_mesh_bytes
from arap.server import create_app
from arap.server.animation_export import (
    MAX_EXPORT_FRAMES,
    AnimationCancelled,
    export_animation,
    export_bytes,
    keyframes_document,
)
from arap.server.budget import MemoryBudget
from arap.server.errors import RequestError
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_builtin
from arap.server.session import Session
from tests.animated_glb import glb_frames
from tests.server.helpers import StudioClient, column_major, rotation_z, translation
from tests.waiting import wait_until


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


def _turned_in_steps(s: Session, top: list[int], angle: float, steps: int = 10) -> list[float]:
    """Turn the handle group about z by ``angle`` in drags of equal steps, settle; the last transform."""
    pivot = s.V[top].mean(axis=0)
    for a in np.linspace(0.0, angle, steps + 1)[1:]:
        s.drag([column_major(rotation_z(float(a), pivot))])
    s.end_drag()
    s.settle(lambda: False)
    return column_major(rotation_z(angle, pivot))


def test_a_keyframe_gives_back_the_shape_that_was_keyed(bar_session: Session, bar: MeshData) -> None:
    s = bar_session
    diag = float(np.linalg.norm(np.ptp(bar.V, axis=0)))
    y = s.V[:, 1]
    fixed, top = np.flatnonzero(y < 0.2).tolist(), np.flatnonzero(y > 4.8).tolist()
    s.set_constraints(None, fixed, [top])
    s.keep_shape(7)
    turned = _turned_in_steps(s, top, 0.75 * np.pi)
    s.keep_shape(8)
    keyed = s.U.copy()
    rest = translation(0.0)
    # scrubbing back to the start and onto the key: the kept shape, exactly
    s.drag([rest], key=7)
    np.testing.assert_array_equal(s.U, bar.V)
    s.drag([turned], key=8)
    np.testing.assert_array_equal(s.U, keyed)
    s.drag([translation(0.1)], key=8)  # not the key's pose: solved
    assert np.abs(s.U[top] - (keyed[top] + [0.1, 0, 0])).max() > 0.1
    s.end_drag()

    _, _, again, _, _ = export_animation(s, [0, 1000], [rest, turned], 5.0, lambda: False)
    assert np.abs(glb_frames(again)[1][-1] - keyed).max() > 0.01 * diag  # solved again: another shape
    _, _, data, _, _ = export_animation(s, [0, 1000], [rest, turned], 5.0, lambda: False, keys=[7, 8])
    frames = glb_frames(data)[1]
    assert np.abs(frames[-1] - keyed).max() <= 1e-6 * diag  # (float32 positions)
    document = keyframes_document(s, [0, 1000], [rest, turned], keys=[7, 8])
    np.testing.assert_array_equal(document["keyframes"][1]["shape"], keyed)
    reference = animate(bar.V, bar.F, document, fps=5.0, energy=s.params.energy, weights=s.params.weights,
                        alpha=s.params.alpha)
    assert np.abs(reference.vertices[-1] - keyed).max() <= 1e-9 * diag
    with pytest.raises(RequestError, match="keys"):
        export_animation(s, [0, 1000], [rest, turned], 5.0, lambda: False, keys=[7])


def test_point_handles_and_easing_in_the_export(bar_session: Session, bar: MeshData) -> None:
    s = bar_session
    y = s.V[:, 1]
    fixed, top = np.flatnonzero(y < 0.2).tolist(), np.flatnonzero(y > 4.8).tolist()
    face = int(np.flatnonzero(bar.V[bar.F].mean(axis=1)[:, 1] > 3.5)[0])
    third = np.full(3, 1 / 3)
    s.set_constraints(None, fixed, [top], points=[{"face": face, "barycentric": third.tolist()}])
    start = third @ bar.V[bar.F[face]]
    rest, moved = translation(0.0), translation(0.6)
    transforms = [rest, rest, rest, moved]  # per keyframe: the handle group, then the point handle
    _, _, data, count, _ = export_animation(s, [0, 400], transforms, 10.0, lambda: False, easings=[1, 0])
    frames = glb_frames(data)[1]
    assert count == 5
    where = np.einsum("j,fjk->fk", third, frames[:, bar.F[face]])
    eased = np.array([0.0, 0.15625, 0.5, 0.84375, 1.0]) * 0.6  # s² (3 - 2 s) at 0, 1/4, ... of the way
    np.testing.assert_allclose(where[:, 0] - start[0], eased, atol=2e-5)
    document = keyframes_document(s, [0, 400], transforms, easings=[1, 0])
    assert document["keyframes"][0]["easing"] == "ease-in-out" and "easing" not in document["keyframes"][1]
    lifted = start + np.array([0.6, 0.0, 0.0])
    np.testing.assert_allclose(document["keyframes"][1]["point_targets"], [lifted], atol=1e-12)
    with pytest.raises(RequestError, match="easings"):
        export_animation(s, [0, 400], transforms, 10.0, lambda: False, easings=[9, 0])


def test_a_picture_animation_as_gif_webp_and_png_frames() -> None:
    import io
    import zipfile

    from PIL import Image

    from arap.server.pictures import warped_picture_png
    from tests.server.test_pictures import _loaded

    s = _loaded()
    mesh = s.mesh
    assert mesh is not None
    centre = mesh.V[mesh.F].mean(axis=1)
    left, right = int(np.argmin(centre[:, 0])), int(np.argmax(centre[:, 0]))
    third = [1 / 3, 1 / 3, 1 / 3]
    s.set_constraints(None, [], [], points=[{"face": left, "barycentric": third},
                                             {"face": right, "barycentric": third}])
    rest, lifted = translation(0.0), translation(0.0, 25.0)
    s.keep_shape(1)
    shown = [np.asarray(Image.open(io.BytesIO(warped_picture_png(mesh, s.U))).convert("RGBA"))]
    s.drag([rest, lifted])
    s.end_drag()
    s.settle(lambda: False)
    s.keep_shape(2)
    shown.append(np.asarray(Image.open(io.BytesIO(warped_picture_png(mesh, s.U))).convert("RGBA")))
    assert np.abs(shown[0].astype(int) - shown[1]).max() > 100  # the picture moved
    keys = {"times_ms": [0, 500], "transforms": [rest, rest, rest, lifted], "keys": [1, 2]}

    def export(fmt: str) -> tuple[str, list[np.ndarray]]:
        name, mime, data, count, _ = export_animation(s, keys["times_ms"], keys["transforms"], 10.0, lambda: False,
                                                      keys=keys["keys"], fmt=fmt)
        assert count == 6 and name.endswith(f".{fmt}") and mime.endswith(fmt)
        if fmt == "zip":
            with zipfile.ZipFile(io.BytesIO(data)) as z:
                names = sorted(z.namelist())
                return name, [np.asarray(Image.open(io.BytesIO(z.read(n))).convert("RGBA")) for n in names]
        image = Image.open(io.BytesIO(data))
        assert image.format == fmt.upper() and image.n_frames == 6
        pictures = []
        for k in range(image.n_frames):
            image.seek(k)
            pictures.append(np.asarray(image.convert("RGBA")))
        return name, pictures

    for fmt in ("webp", "zip"):  # lossless: the keyed poses' pictures exactly
        _, pictures = export(fmt)
        assert len(pictures) == 6
        np.testing.assert_array_equal(pictures[0], shown[0])
        np.testing.assert_array_equal(pictures[-1], shown[1])
    _, pictures = export("gif")  # a palette and one level of transparency: close
    for got, want in ((pictures[0], shown[0]), (pictures[-1], shown[1])):
        drawn, opaque = want[..., 3] > 0, want[..., 3] == 255
        assert ((got[..., 3] > 0) == drawn).mean() > 0.99
        assert np.abs(got[opaque][:, :3].astype(int) - want[opaque][:, :3]).mean() < 8
    with pytest.raises(RequestError, match="picture"):
        export_animation(bar_like(), [0, 500], [translation(0.0), translation(0.5)], 10.0, lambda: False, fmt="gif")


def bar_like(picture: bool = False) -> Session:
    """The bar, its bottom fixed and its top a handle; with ``picture``, its mesh given a picture (what the export
    checks before it draws)."""
    import dataclasses

    from arap.server.meshdata import load_builtin

    s = Session()
    mesh = load_builtin("bar")
    s.load(dataclasses.replace(mesh, picture=np.zeros((4, 4, 4), dtype=np.uint8)) if picture else mesh)
    y = s.V[:, 1]
    s.set_constraints(None, np.flatnonzero(y < 0.2).tolist(), [np.flatnonzero(y > 4.8).tolist()])
    return s


def test_a_picture_animation_without_pillow_says_what_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    s = bar_like(picture=True)
    monkeypatch.setitem(sys.modules, "PIL", None)
    for fmt in ("gif", "webp", "zip"):
        with pytest.raises(RequestError, match=r"needs Pillow.*arap\[image\]"):
            export_animation(s, [0, 500], [translation(0.0), translation(0.5)], 10.0, lambda: False, fmt=fmt)


def test_keep_shape_over_the_socket_is_not_answered_and_a_drag_gives_the_shape_back(studio: StudioClient) -> None:
    fixed, top = studio.bottom_top()
    studio.set_constraints(fixed, [top])

    def dragged(seq: int, dx: float) -> dict:
        studio.send({"type": "drag", "seq": seq, "transforms": [translation(dx)], "key": 5})
        reply = studio.recv()
        while reply.type != "vertices" or reply.data.get("seq") != seq:
            assert reply.type in ("settle", "state", "vertices"), reply.data  # nothing answers keep_shape
            reply = studio.recv()
        return reply.data

    studio.send({"type": "keep_shape", "key": 5})
    assert dragged(1, 0.3)["iterations"] > 0  # not the pose of keyframe 5: solved
    assert dragged(2, 0.0)["iterations"] == 0  # keyframe 5's pose: its kept shape


def test_the_estimate_covers_the_file_and_the_solved_frames(bar_session: Session) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    _, _, data, count, _ = export_animation(s, [0, 500], transforms, 10.0, lambda: False)
    solved = count * s.n_vertices * 24  # float64 frames
    estimate = export_bytes(count, s.n_vertices, s.mesh.n_faces)
    assert solved + len(data) <= estimate <= 1.5 * (solved + len(data)) + 2**16


def test_an_export_larger_than_the_servers_budget_is_refused_before_solving(bar_session: Session) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    budget = MemoryBudget(2**20)
    seen: list[tuple[int, int]] = []
    with pytest.raises(RequestError, match=r"needs about \d+ MB, more than the server's limit of 1 MB") as info:
        export_animation(s, [0, 10_000], transforms, 30.0, lambda: False, lambda *p: seen.append(p), budget=budget)
    assert info.value.code == "too_large" and seen == [] and budget.used == 0


def test_exports_beyond_the_budget_wait_for_room(bar_session: Session) -> None:
    """Another session's export holds most of the budget: this one waits (solving nothing) until it is done."""
    s = bar_session
    _, _, transforms = _posed(s)
    needed = export_bytes(6, s.n_vertices, s.mesh.n_faces)
    budget = MemoryBudget(needed + needed // 2)
    seen: list[tuple[int, int]] = []
    result: list[Any] = []
    with budget.reserve(needed) as reserved:
        assert reserved
        worker = threading.Thread(target=lambda: result.append(export_animation(
            s, [0, 500], transforms, 10.0, lambda: False, lambda *p: seen.append(p), budget=budget)))
        worker.start()
        wait_until(lambda: budget.waiting == 1, what="the export to wait for room")
        assert seen == [(0, 6)] and not result and budget.used == needed
    worker.join(timeout=60)
    assert result and result[0][3] == 6 and seen[-1] == (6, 6)
    assert budget.used == 0 and budget.peak == needed


def test_a_new_request_cancels_an_export_waiting_for_room(bar_session: Session) -> None:
    s = bar_session
    _, _, transforms = _posed(s)
    budget = MemoryBudget(export_bytes(6, s.n_vertices, s.mesh.n_faces))
    stop = threading.Event()
    with budget.reserve(budget.limit):
        threading.Timer(0.3, stop.set).start()
        with pytest.raises(AnimationCancelled):
            export_animation(s, [0, 500], transforms, 10.0, stop.is_set, None, budget=budget)
    assert budget.used == 0 and budget.waiting == 0


def test_the_servers_export_budget_is_configurable(static_dir: Path) -> None:
    from starlette.testclient import TestClient

    app = create_app("cactus", static_dir=static_dir, allowed_hosts=["testserver"], max_export_bytes=2**20)
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        studio = StudioClient(ws)
        studio.greet()
        fixed, top = studio.bottom_top()
        studio.set_constraints(fixed, [top])
        studio.send({"type": "export_animation", "fps": 30, "times_ms": [0, 10_000],
                     "transforms": [translation(0.0), translation(0.5)]})
        error = studio.error("too_large")
        assert "more than the server's limit of 1 MB for animation exports" in error["message"], error
        assert error["request"] == "export_animation"


def test_concurrent_exports_of_two_sessions_stay_within_the_servers_budget(static_dir: Path) -> None:
    """Two sessions export at once under a budget that holds one export: one waits, both are answered, and the
    memory held at once never exceeded the budget."""
    from starlette.testclient import TestClient

    keys = {"fps": 10, "times_ms": [0, 900], "transforms": [translation(0.0), translation(0.4)]}
    cactus = load_builtin("cactus")
    one = export_bytes(10, cactus.n_vertices, cactus.n_faces)
    app = create_app(cactus, static_dir=static_dir, allowed_hosts=["testserver"], max_export_bytes=one + one // 2)
    with TestClient(app) as http:
        budget = http.app.state.studio.config.exports  # type: ignore[attr-defined]
        with http.websocket_connect("/ws") as ws_a, http.websocket_connect("/ws") as ws_b:
            a, b = StudioClient(ws_a), StudioClient(ws_b)
            a.greet()
            b.greet()
            for client in (a, b):
                fixed, top = client.bottom_top()
                client.set_constraints(fixed, [top])
            a.send({"type": "export_animation", **keys})
            b.send({"type": "export_animation", **keys})
            for client in (a, b):
                reply = client.recv()
                while reply.type in ("animation_progress", "settle", "vertices"):
                    reply = client.recv()
                assert reply.type == "animation" and reply.data["frames"] == 10, reply.data
    assert budget.used == 0 and budget.peak == one


def test_a_keyframes_shape_given_back_to_a_new_session_is_its_shape_again(http: TestClient) -> None:
    # the page keeps the shape of each keyframe (as float32 frames): after the connection was lost, the new session
    # is given it back, and a drag to that keyframe's pose shows it instead of solving again
    with http.websocket_connect("/ws") as ws:
        first = StudioClient(ws)
        first.greet()
        fixed, top = first.bottom_top()
        first.set_constraints(fixed, [top])
        first.drag(1, [translation(0.4)])
        first.send({"type": "end_drag"})
        first.expect("state")
        first.settled()
        first.send({"type": "keep_shape", "key": 5})
        first.ping()
        kept = first.held.copy()
    with http.websocket_connect("/ws") as ws:
        second = StudioClient(ws)
        second.greet()
        second.set_constraints(fixed, [top])
        second.send({"type": "keep_shape", "key": 5, "shape": kept.tolist()})
        second.ping()
        second.send({"type": "drag", "seq": 2, "transforms": [translation(0.4)], "key": 5})
        again = second.expect("vertices")
        assert again.data["seq"] == 2 and again.data["iterations"] == 0
        np.testing.assert_allclose(again.positions, kept, rtol=0, atol=1e-6)
        # another pose is solved
        assert second.drag(3, [translation(0.1)]).data["iterations"] > 0
        second.send({"type": "keep_shape", "key": 6, "shape": kept[:-1].tolist()})
        assert "one per vertex" in second.error("bad_message")["message"]
