"""``arap.widget``: the studio's session driven through the widget's comm messages (as a view would send them), its
answers captured as the comm would carry them, the results read back as arrays, and the picture a saved notebook
keeps."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip("anywidget")

import arap
from arap.jupyter_widget import OPEN_MESSAGE, StudioWidget
from arap.server.session import Session

pytestmark = pytest.mark.timeout(120)

PNG = b"\x89PNG\r\n\x1a\n"


class Comm:
    """What the widget sends, as (content, buffers), with waiting for a message: the studio's messages in ``sent``,
    the widget's own (``{"widget": ...}``) in ``notes``."""

    def __init__(self, w: StudioWidget) -> None:
        self.w = w
        self.sent: list[tuple[dict[str, Any], list[bytes]]] = []
        self.notes: list[tuple[dict[str, Any], list[bytes]]] = []
        self._cond = threading.Condition()
        w.send = self._send  # type: ignore[attr-defined]

    def _send(self, content: dict[str, Any], buffers: list[Any] | None = None) -> None:
        with self._cond:
            kept = self.notes if "widget" in content else self.sent  # the widget's own messages, or the studio's
            kept.append((content, [bytes(b) for b in buffers or []]))
            self._cond.notify_all()

    def request(self, content: Any, buffers: list[bytes] | None = None) -> None:
        self.w._receive(content, buffers)

    def wait_for(self, match: Callable[[dict[str, Any]], bool], start: int = 0,
                 timeout: float = 60.0) -> tuple[int, dict[str, Any], list[bytes]]:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for i in range(start, len(self.sent)):
                    content, buffers = self.sent[i]
                    if match(content):
                        return i, content, buffers
                left = deadline - time.monotonic()
                assert left > 0, f"no such message in {[c['type'] for c, _ in self.sent[start:]]}"
                self._cond.wait(left)

    def types(self, start: int = 0, stop: int | None = None) -> list[str]:
        return [c["type"] for c, _ in self.sent[start:stop]]


@pytest.fixture
def cactus() -> tuple[np.ndarray, np.ndarray]:
    return arap.builtin_mesh("cactus")


@pytest.fixture
def opened(cactus: tuple[np.ndarray, np.ndarray]) -> Iterator[tuple[StudioWidget, Comm]]:
    w = arap.widget(*cactus, name="cactus")
    comm = Comm(w)
    comm.request(OPEN_MESSAGE, [])
    comm.wait_for(lambda m: m["type"] == "state")
    try:
        yield w, comm
    finally:
        w.stop()


def _bottom_top(V: np.ndarray) -> tuple[list[int], list[int]]:
    y = V[:, 1]
    return np.flatnonzero(y <= np.quantile(y, 0.1)).tolist(), np.flatnonzero(y >= np.quantile(y, 0.9)).tolist()


def _translation(x: float, y: float = 0.0) -> list[float]:
    T = np.eye(4)
    T[:3, 3] = (x, y, 0.0)
    return T.T.ravel().tolist()  # column-major


def test_a_view_opening_gets_the_mesh(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    w = arap.widget(V, F, name="cactus")
    try:
        assert isinstance(w, StudioWidget) and w.url is None and w.running
        comm = Comm(w)
        comm.request(OPEN_MESSAGE, [])
        _, mesh, buffers = comm.wait_for(lambda m: m["type"] == "mesh")
        assert mesh["name"] == "cactus" and mesh["n_vertices"] == len(V) and mesh["n_faces"] == len(F)
        assert len(buffers) == 1
        positions = np.frombuffer(buffers[0][: 12 * len(V)], dtype="<f4").reshape(-1, 3)
        np.testing.assert_allclose(positions, V, rtol=1e-6, atol=1e-6)
        faces = np.frombuffer(buffers[0][12 * len(V): 12 * len(V) + 12 * len(F)], dtype="<u4").reshape(-1, 3)
        np.testing.assert_array_equal(faces, F)
        comm.wait_for(lambda m: m["type"] == "state")
        assert comm.types()[:3] == ["welcome", "mesh", "state"]
        assert comm.sent[0][1] == []  # a text message: no buffers
        np.testing.assert_array_equal(w.vertices, V)
        np.testing.assert_array_equal(w.faces, F)
        assert w.constraints.fixed.size == 0
    finally:
        w.stop()



def test_a_picture_opens_in_the_widget_for_the_puppet_warp() -> None:
    rgba = np.zeros((40, 70, 4), dtype=np.uint8)
    rgba[5:35, 5:65] = (30, 90, 220, 255)
    w = arap.widget(rgba, name="sprite")
    try:
        comm = Comm(w)
        comm.request(OPEN_MESSAGE, [])
        _, mesh, _ = comm.wait_for(lambda m: m["type"] == "mesh")
        assert mesh["picture"] == [70, 40] and mesh["name"] == "sprite"
        _, look, _ = comm.wait_for(lambda m: m["type"] == "appearance")
        assert look["texture_bytes"] > 0
        assert np.all(w.vertices[:, 2] == 0.0) and len(w.vertices) == mesh["n_vertices"]
    finally:
        w.stop()

def test_the_saved_notebook_keeps_a_picture_of_a_picture_warped_and_textured() -> None:
    """A picture opened in the widget is kept in the notebook as the warped picture (its own colours), made smaller to
    fit the kept picture's size, not as a grey drawing of its mesh."""
    from arap.jupyter_widget import PICTURE_SIZE

    rgba = np.zeros((300, 700, 4), dtype=np.uint8)
    rgba[50:250, 100:600] = (30, 90, 220, 255)
    w = arap.widget(rgba, name="sprite")
    try:
        assert w.wait(60)
        kept = w.picture()
        assert kept.width <= PICTURE_SIZE[0] and kept.height <= PICTURE_SIZE[1]
        assert abs(kept.width / kept.height - 700 / 300) < 0.05
        px = kept.pixels.astype(np.int64)
        blue = (px[..., 2] > 180) & (px[..., 0] < 80) & (px[..., 1] < 130)
        white = (px > 245).all(axis=2)
        assert 0.35 < blue.mean() < 0.6 and 0.35 < white.mean() < 0.65, (blue.mean(), white.mean())
    finally:
        w.stop()


def test_a_drag_is_answered_with_the_solved_positions(opened: tuple[StudioWidget, Comm],
                                                      cactus: tuple[np.ndarray, np.ndarray]) -> None:
    w, comm = opened
    V, _ = cactus
    fixed, top = _bottom_top(V)
    start = len(comm.sent)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    comm.wait_for(lambda m: m["type"] == "state", start)
    comm.request({"type": "drag", "seq": 7, "transforms": [_translation(0.5)]})
    _, header, buffers = comm.wait_for(lambda m: m["type"] == "vertices" and m["seq"] == 7, start)
    assert header["iterations"] >= 1 and header["subset"] == -1
    positions = np.frombuffer(buffers[0][: 12 * len(V)], dtype="<f4").reshape(-1, 3)
    np.testing.assert_allclose(positions[top], V[top] + [0.5, 0, 0], atol=1e-4)  # the handle is where it was dragged
    np.testing.assert_allclose(positions[fixed], V[fixed], atol=1e-5)
    comm.request({"type": "end_drag"})
    assert w.wait(60)
    _, done, _ = comm.wait_for(lambda m: m["type"] == "settle" and m["status"] != "settling", start)
    assert done["status"] == "settled"
    # the handle reads the settled shape and the selection
    U = w.vertices
    np.testing.assert_allclose(U[top], V[top] + [0.5, 0, 0], atol=1e-6)
    assert np.abs(U - V).max() > 0.1
    last = [b for c, b in comm.sent if c["type"] == "vertices"][-1]
    np.testing.assert_allclose(np.frombuffer(last[0][: 12 * len(V)], dtype="<f4").reshape(-1, 3), U, atol=1e-5)
    sel = w.constraints
    assert sorted(sel.fixed.tolist()) == sorted(fixed)
    assert [sorted(g.tolist()) for g in sel.handle_groups] == [sorted(top)]
    np.testing.assert_allclose(sel.targets, U[sel.handle_groups[0]], atol=1e-6)


def test_settling_stops_when_a_message_arrives(opened: tuple[StudioWidget, Comm],
                                               cactus: tuple[np.ndarray, np.ndarray],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    _, comm = opened
    V, _ = cactus
    settle = Session.settle

    def slow_settle(self: Session, interrupted: Any, on_frame: Any = None) -> Any:
        def polled() -> bool:
            time.sleep(0.01)  # iterations as slow as a large mesh's: the settle still runs when the request comes
            return bool(interrupted())
        return settle(self, polled, on_frame)

    monkeypatch.setattr(Session, "settle", slow_settle)
    fixed, top = _bottom_top(V)
    start = len(comm.sent)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    comm.request({"type": "drag", "seq": 1, "transforms": [_translation(1.0, 0.5)]})
    comm.request({"type": "end_drag"})
    i, _, _ = comm.wait_for(lambda m: m["type"] == "settle" and m["iterations"] > 0, start)
    comm.request({"type": "get_constraints"})
    j, answer, _ = comm.wait_for(lambda m: m["type"] == "constraints", i)
    assert sorted(answer["document"]["fixed"]) == sorted(fixed)
    # the run ended as stopped right before the answer: nothing of it came after
    k, stopped, _ = comm.wait_for(lambda m: m["type"] == "settle" and m["status"] != "settling", i)
    assert stopped["status"] == "stopped" and k < j
    assert "settle" not in comm.types(k + 1, j)
    # and it settles again afterwards, from where it stopped
    comm.wait_for(lambda m: m["type"] == "settle" and m["status"] == "settling", j)


def test_the_animation_export_is_answered_through_the_comm(opened: tuple[StudioWidget, Comm],
                                                           cactus: tuple[np.ndarray, np.ndarray]) -> None:
    _, comm = opened
    V, _ = cactus
    fixed, top = _bottom_top(V)
    start = len(comm.sent)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    comm.wait_for(lambda m: m["type"] == "state", start)
    comm.request({"type": "export_animation", "times_ms": [0, 400], "fps": 10,
                  "transforms": [_translation(0.0), _translation(0.5)]})  # one group, keyframe after keyframe
    _, header, buffers = comm.wait_for(lambda m: m["type"] in ("animation", "error"), start)
    assert header["type"] == "animation" and header["frames"] == 5, header
    assert buffers[0][:4] == b"glTF"
    assert "animation_progress" in comm.types(start)


def test_drags_waiting_in_the_queue_coalesce(opened: tuple[StudioWidget, Comm],
                                            cactus: tuple[np.ndarray, np.ndarray],
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    w, comm = opened
    V, _ = cactus
    fixed, top = _bottom_top(V)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    assert w.wait(60)
    drag = Session.drag
    gate, solving = threading.Event(), threading.Event()

    def held_drag(self: Session, transforms: Any, key: int | None = None) -> Any:
        solving.set()
        gate.wait(10)
        return drag(self, transforms, key)

    monkeypatch.setattr(Session, "drag", held_drag)
    start = len(comm.sent)
    comm.request({"type": "drag", "seq": 1, "transforms": [_translation(0.1)]})
    assert solving.wait(10)
    for seq in range(2, 6):  # they arrive while the first is being solved
        comm.request({"type": "drag", "seq": seq, "transforms": [_translation(0.1 * seq)]})
    gate.set()
    comm.wait_for(lambda m: m["type"] == "vertices" and m["seq"] == 5, start)
    seqs = [c["seq"] for c, _ in comm.sent[start:] if c["type"] == "vertices" and c["seq"] > 0]
    assert seqs == [1, 5]  # the drags queued behind the first were replaced by the newest


@pytest.mark.parametrize("content,buffers,code", [
    ({"type": "launch_rockets"}, None, "bad_message"),
    ("not an object", None, "bad_message"),
    ({"type": "drag", "seq": "one", "transforms": []}, None, "bad_message"),
    ({"type": "drag", "seq": 1, "transforms": []}, None, "bad_constraints"),  # nothing constrained yet
    ({"type": "set_constraints", "roi": None, "fixed": [10**9], "handle_groups": []}, None, "bad_constraints"),
    ({"type": "upload", "filename": "a.obj"}, [b"this is no mesh"], "bad_mesh"),
    ({"type": "undo"}, [b"\x00\x01"], "bad_message"),  # a text message sent with a payload
])
def test_bad_messages_get_an_error_message(opened: tuple[StudioWidget, Comm], content: Any,
                                           buffers: list[bytes] | None, code: str) -> None:
    w, comm = opened
    start = len(comm.sent)
    comm.request(content, buffers)  # never raises
    _, error, _ = comm.wait_for(lambda m: m["type"] == "error", start)
    assert error["code"] == code, error
    comm.request({"type": "get_constraints"})  # and the session goes on
    comm.wait_for(lambda m: m["type"] == "constraints", start)
    assert w.running


def test_a_second_view_gets_the_current_shape(opened: tuple[StudioWidget, Comm],
                                              cactus: tuple[np.ndarray, np.ndarray]) -> None:
    w, comm = opened
    V, _ = cactus
    fixed, top = _bottom_top(V)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    comm.request({"type": "drag", "seq": 1, "transforms": [_translation(0.4)]})
    comm.request({"type": "end_drag"})
    assert w.wait(60)
    start = len(comm.sent)
    comm.request(OPEN_MESSAGE, [])
    comm.wait_for(lambda m: m["type"] == "state", start)
    _, _, buffers = comm.wait_for(lambda m: m["type"] == "vertices", start)
    shown = np.frombuffer(buffers[0][: 12 * len(V)], dtype="<f4").reshape(-1, 3)
    np.testing.assert_allclose(shown, w.vertices, atol=1e-5)
    assert comm.types(start)[:2] == ["welcome", "mesh"]


def test_initial_constraints_and_the_stopped_widget(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    V, F = cactus
    fixed, top = _bottom_top(V)
    targets = (V[top] + [0.3, 0.0, 0.0]).tolist()
    w = arap.widget(V, F, constraints={"fixed": fixed, "handles": top, "targets": targets})
    comm = Comm(w)
    comm.request(OPEN_MESSAGE, [])
    assert w.wait(60)
    np.testing.assert_allclose(w.vertices[top], targets, atol=1e-6)
    assert sorted(w.constraints.fixed.tolist()) == sorted(fixed)
    w.stop()
    w.stop()  # idempotent
    assert not w.running
    n = len(comm.sent)
    comm.request({"type": "get_constraints"})
    time.sleep(0.2)
    assert len(comm.sent) == n  # no longer answered
    np.testing.assert_allclose(w.vertices[top], targets, atol=1e-6)  # still readable
    other = arap.widget(V, F)
    thread = other._worker._thread
    other.close()  # ipywidgets' close stops the session's thread too
    assert not other.running and not thread.is_alive()


def test_the_saved_notebook_keeps_a_picture_updated_after_edits(opened: tuple[StudioWidget, Comm],
                                                                cactus: tuple[np.ndarray, np.ndarray],
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    import IPython.display

    w, comm = opened
    V, _ = cactus
    shown: list[tuple[dict[str, Any], str | None]] = []
    updated: list[tuple[dict[str, Any], str | None]] = []
    monkeypatch.setattr(IPython.display, "display",
                        lambda obj, raw=False, display_id=None: shown.append((obj, display_id)))
    monkeypatch.setattr(IPython.display, "update_display",
                        lambda obj, raw=False, display_id=None: updated.append((obj, display_id)))
    w._ipython_display_()
    assert len(shown) == 2
    widget_bundle, picture = shown[0][0], shown[1]
    assert "application/vnd.jupyter.widget-view+json" in widget_bundle
    assert widget_bundle["application/vnd.jupyter.widget-view+json"]["model_id"] == w.model_id  # type: ignore[attr-defined]
    before = picture[0]["image/png"]
    assert before.startswith(PNG) and picture[1] is not None
    assert w.picture().png().startswith(PNG)

    def drawn() -> int:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not (w._picture_key == w._shape_key() or not w.session.settled):
            time.sleep(0.05)
        thread = w._picture_thread
        if thread is not None:
            thread.join(30)
        return len(updated)

    fixed, top = _bottom_top(V)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
    assert w.wait(60)
    painted = drawn()
    assert painted >= 1, "the picture was not replaced after the new selection"
    for seq in range(1, 4):  # a drag under way: its frames do not replace the picture
        comm.request({"type": "drag", "seq": seq, "transforms": [_translation(0.3 * seq)]})
        assert w.wait(60)
    assert drawn() == painted
    comm.request({"type": "end_drag"})
    assert w.wait(60)
    assert drawn() == painted + 1, "the picture was not replaced once the drag had ended and settled"
    bundle, display_id = updated[-1]
    assert display_id == picture[1]
    assert bundle["image/png"].startswith(PNG) and bundle["image/png"] != before


def test_studio_picks_the_transport() -> None:
    V, F = arap.builtin_mesh("bar")
    w = arap.studio(V, F, show=False, transport="widget")
    try:
        assert isinstance(w, StudioWidget)
    finally:
        w.stop()
    for transport in ("server", "auto"):  # auto: not in a Jupyter kernel, so the server
        s = arap.studio(V, F, show=False, transport=transport)
        try:
            assert isinstance(s, arap.Studio) and s.url is not None and s.url.startswith("http://127.0.0.1:")
        finally:
            s.stop()
    with pytest.raises(ValueError, match="transport"):
        arap.studio(V, F, show=False, transport="pigeon")


def test_a_real_kernel_round_trip() -> None:
    """The widget in an IPython kernel, driven through the kernel's comm as a notebook's widget manager would: the
    greeting, a drag answered with its positions, the result read back, and the picture replaced after the edit."""
    jupyter_client = pytest.importorskip("jupyter_client")
    km, kc = jupyter_client.manager.start_new_kernel(kernel_name="python3")
    try:
        t0 = time.perf_counter()
        setup = ("import numpy as np, arap\n"
                 "V, F = arap.builtin_mesh('bar')\n"
                 "w = arap.widget(V, F, name='bar')\n"
                 "display(w)\n")
        outputs: list[dict[str, Any]] = []
        reply = kc.execute_interactive(setup, timeout=60, output_hook=outputs.append)
        assert reply["content"]["status"] == "ok", reply["content"]
        opens = [m for m in outputs if m["msg_type"] == "comm_open"
                 and m["content"]["data"]["state"].get("_model_name") == "AnyModel"]
        assert len(opens) == 1
        comm_id = opens[0]["content"]["comm_id"]
        displays = [m["content"] for m in outputs if m["msg_type"] == "display_data"]
        assert "application/vnd.jupyter.widget-view+json" in displays[0]["data"]
        assert displays[1]["data"]["image/png"]  # the picture, base64 in the message
        picture_id = displays[1]["transient"]["display_id"]

        def request(content: dict[str, Any], buffers: list[bytes] | None = None) -> None:
            msg = kc.session.msg("comm_msg", {"comm_id": comm_id, "data": {"method": "custom", "content": content}})
            kc.session.send(kc.shell_channel.socket, msg, buffers=buffers or [])

        def answers(until: Callable[[dict[str, Any]], bool]) -> list[tuple[dict[str, Any], list[bytes]]]:
            got: list[tuple[dict[str, Any], list[bytes]]] = []
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                m = kc.get_iopub_msg(timeout=30)
                if m["msg_type"] == "comm_msg" and m["content"]["comm_id"] == comm_id:
                    content = m["content"]["data"]["content"]
                    if "widget" in content:  # the widget's own note (a picture while the session is prepared)
                        continue
                    got.append((content, [bytes(b) for b in m.get("buffers", [])]))
                    if until(content):
                        return got
                elif m["msg_type"] == "update_display_data":
                    got.append(({"type": "picture", "display_id": m["content"]["transient"]["display_id"]}, []))
                    if until(got[-1][0]):
                        return got
            raise AssertionError(f"timed out after {[c['type'] for c, _ in got]}")

        request(OPEN_MESSAGE)
        greeting = answers(lambda c: c["type"] == "state")
        assert [c["type"] for c, _ in greeting] == ["welcome", "mesh", "state"]
        V, _ = arap.builtin_mesh("bar")
        mesh_buffer = greeting[1][1][0]
        np.testing.assert_allclose(np.frombuffer(mesh_buffer[: 12 * len(V)], "<f4").reshape(-1, 3), V, atol=1e-6)

        fixed, top = _bottom_top(V)
        sent = time.perf_counter()
        request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top]})
        request({"type": "drag", "seq": 1, "transforms": [_translation(0.5)]})
        got = answers(lambda c: c["type"] == "vertices" and c["seq"] == 1)
        round_trip = time.perf_counter() - sent
        shown = np.frombuffer(got[-1][1][0][: 12 * len(V)], "<f4").reshape(-1, 3)
        np.testing.assert_allclose(shown[top], V[top] + [0.5, 0, 0], atol=1e-4)
        request({"type": "end_drag"})
        got = answers(lambda c: c["type"] == "picture")
        assert got[-1][0]["display_id"] == picture_id  # the kept picture was replaced after the edit
        reply = kc.execute_interactive("", user_expressions={
            "moved": f"float(np.abs(w.vertices[{top}] - V[{top}]).max())",
            "fixed": "len(w.constraints.fixed)"}, timeout=30)
        expressions = reply["content"]["user_expressions"]
        assert float(expressions["moved"]["data"]["text/plain"]) == pytest.approx(0.5, abs=1e-6)
        assert int(expressions["fixed"]["data"]["text/plain"]) == len(fixed)
        print(f"kernel: set-up {sent - t0:.2f} s, set_constraints + drag answered in {1000 * round_trip:.1f} ms")
    finally:
        kc.stop_channels()
        km.shutdown_kernel(now=True)


def test_replies_go_to_the_view_that_asked(opened: tuple[StudioWidget, Comm],
                                           cactus: tuple[np.ndarray, np.ndarray]) -> None:
    """Two views of one widget: a view opening gets its greeting alone, an export answers the view that asked, an
    error too, while what changes the shared session (state, positions, settling) goes to both."""
    w, comm = opened
    V, _ = cactus
    assert w.wait(60)
    start = len(comm.sent)
    comm.request({**OPEN_MESSAGE, "view": "b"}, [])
    comm.wait_for(lambda m: m["type"] == "vertices", start)
    assert w.wait(60)
    greeting = comm.sent[start:]
    assert [c["type"] for c, _ in greeting][:3] == ["welcome", "mesh", "state"]
    assert all(c.get("to") == "b" for c, _ in greeting)

    start = len(comm.sent)
    fixed, top = _bottom_top(V)
    comm.request({"type": "set_constraints", "roi": None, "fixed": fixed, "handle_groups": [top], "view": "a"})
    comm.request({"type": "drag", "seq": 1, "transforms": [_translation(0.3)], "view": "a"})
    comm.request({"type": "end_drag", "view": "a"})
    comm.request({"type": "export", "format": "obj", "view": "a"})
    comm.request({"type": "nonsense", "view": "b"})
    _, export, _ = comm.wait_for(lambda m: m["type"] == "export", start)
    _, error, _ = comm.wait_for(lambda m: m["type"] == "error", start)
    assert w.wait(60)
    assert export["to"] == "a" and error["to"] == "b"
    shared = [c for c, _ in comm.sent[start:] if c["type"] in ("state", "vertices", "settle")]
    assert shared and all("to" not in c for c in shared)
    assert not any("view" in c for c, _ in comm.sent)


def test_a_stopped_widget_tells_its_views(cactus: tuple[np.ndarray, np.ndarray]) -> None:
    """Stopping tells every view (after the last reply); a view shown afterwards is told so instead of a greeting it
    would wait for forever."""
    w = arap.widget(*cactus)
    comm = Comm(w)
    comm.request({**OPEN_MESSAGE, "view": "a"}, [])
    comm.wait_for(lambda m: m["type"] == "state")
    assert w.wait(60)
    n, notes = len(comm.sent), len(comm.notes)  # a note while the session was prepared, perhaps
    w.stop()
    assert comm.notes[notes:] == [({"widget": "stopped"}, [])] and len(comm.sent) == n
    w.stop()  # idempotent: told once
    assert len(comm.notes) == notes + 1
    comm.request({**OPEN_MESSAGE, "view": "b"}, [])
    assert comm.notes[-1] == ({"widget": "stopped", "to": "b"}, [])
    comm.request({"type": "get_constraints", "view": "b"})
    time.sleep(0.2)
    assert len(comm.notes) == notes + 2 and len(comm.sent) == n  # nothing else is answered


SERVER_STACK = ("starlette", "uvicorn", "websockets", "anyio")

WIDGET_WITHOUT_SERVER_STACK = f"""
import sys
import threading


class Refused:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {SERVER_STACK!r}:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)


sys.meta_path.insert(0, Refused())
import arap
from arap.jupyter_widget import OPEN_MESSAGE

w = arap.widget(*arap.builtin_mesh("bar"))
sent, greeted = [], threading.Event()
def send(content, buffers=None):
    if "widget" in content:  # the widget's own note: a picture while the session is prepared
        return
    sent.append(content.get("type"))
    if content.get("type") == "state":
        greeted.set()
w.send = send
w._receive(OPEN_MESSAGE, [])
assert greeted.wait(240), sent
w.stop()
assert not [m for m in sys.modules if m.split(".")[0] in {SERVER_STACK!r}]
print("greeted:", sent[:3])
"""


def test_the_widget_needs_no_server_stack() -> None:
    """``pip install "arap[notebook]"`` brings anywidget, not the studio server's stack: the widget, its greeting
    included, imports none of it."""
    run = subprocess.run([sys.executable, "-c", WIDGET_WITHOUT_SERVER_STACK], capture_output=True, text=True,
                         timeout=300, env=os.environ.copy())
    assert run.returncode == 0, run.stderr[-3000:]
    assert "greeted: ['welcome', 'mesh', 'state']" in run.stdout


def test_a_view_opening_while_the_session_is_prepared_gets_a_picture_of_the_mesh(
        cactus: tuple[np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch) -> None:
    """On a first run the session waits for the solver's kernels (tens of seconds): a view that opens meanwhile is
    sent a picture of the mesh at once, then its greeting once the session is ready; later views get the greeting
    alone."""
    from tests.png_files import decode_png

    load = Session.load
    gate = threading.Event()

    def held_load(self: Session, *args: Any, **kwargs: Any) -> Any:
        gate.wait(60)
        return load(self, *args, **kwargs)

    monkeypatch.setattr(Session, "load", held_load)
    w = arap.widget(*cactus)
    try:
        comm = Comm(w)
        comm.request({**OPEN_MESSAGE, "view": "a"}, [])
        (content, buffers), = comm.notes
        assert content["widget"] == "preparing" and content["to"] == "a" and isinstance(content["first_run"], bool)
        assert buffers[0].startswith(PNG) and decode_png(buffers[0]).shape == (320, 480, 3)
        assert comm.sent == []  # the greeting waits for the session
        gate.set()
        comm.wait_for(lambda m: m["type"] == "state")
        assert comm.types()[:3] == ["welcome", "mesh", "state"]
        assert w.wait(60)
        start = len(comm.sent)
        comm.request({**OPEN_MESSAGE, "view": "b"}, [])  # the session is ready: the greeting alone
        comm.wait_for(lambda m: m["type"] == "state", start)
        assert comm.types(start)[:3] == ["welcome", "mesh", "state"] and len(comm.notes) == 1
    finally:
        gate.set()
        w.stop()
