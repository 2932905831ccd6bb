"""A picture's pins that hold an angle (Photoshop's fixed pin rotation, Alt-drag about a pin): the pin keeps its place
and its surroundings turn about it by the angle, held by a hidden ring of points that only the solver sees."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from arap.server.constraints import matrices_to_json
from arap.server.pictures import load_picture
from arap.server.replies import state_message
from arap.server.session import Session
from arap.server.session_errors import BadValues, UnusableMesh
from tests.server.helpers import StudioClient, translation
from tests.server.test_pictures import _disc_png, _pin_at


def _pinned() -> tuple[Session, np.ndarray]:
    """The disc with a pin left of its centre (0) and one near its right edge (1), settled; and the pins' places."""
    mesh, look = load_picture(_disc_png(), "disc.png", 100_000)
    s = Session()
    s.load(mesh, look)
    s.set_constraints(None, [], [], points=[_pin_at(mesh, 40, 60), _pin_at(mesh, 95, 60)])
    s.settle(lambda: False)
    return s, _pins(s)


def _pins(s: Session) -> np.ndarray:
    pts = s.constraints.points
    assert pts is not None and s.mesh is not None
    return np.einsum("kc,kcd->kd", pts.barycentric, s.U[s.mesh.F[pts.faces]])


def _turn_near(s: Session, centre: np.ndarray, radius: float) -> np.ndarray:
    """The turn (degrees) of every edge of the triangles within ``radius`` of ``centre`` at rest."""
    assert s.mesh is not None
    F = s.mesh.F
    near = F[np.linalg.norm(s.V[F].mean(axis=1)[:, :2] - centre[:2], axis=1) < radius]
    edges = np.concatenate([near[:, [0, 1]], near[:, [1, 2]], near[:, [2, 0]]])
    a = s.V[edges[:, 1], :2] - s.V[edges[:, 0], :2]
    b = s.U[edges[:, 1], :2] - s.U[edges[:, 0], :2]
    return np.degrees(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], (a * b).sum(axis=1)))


def test_a_pin_turned_by_90_degrees_turns_its_surroundings_and_undo_frees_it() -> None:
    s, at_rest = _pinned()
    before = s.U.copy()
    assert s.pin_angles() == [None, None]
    s.set_pin_angle(0, 90.0)
    s.end_drag()
    s.settle(lambda: False)
    np.testing.assert_allclose(_pins(s), at_rest, atol=1e-6)  # both pins keep their places
    rings = s.constraints.rings
    assert rings is not None
    radius = float(np.linalg.norm(rings.offset[0]))  # within its ring
    turn = _turn_near(s, at_rest[0], radius)
    assert len(turn) > 6 and abs(float(np.median(turn)) - 90.0) < 15.0, np.median(turn)
    assert abs(float(np.median(_turn_near(s, at_rest[1], radius)))) < 45.0  # the other pin's end turns far less
    angle = s.pin_angles()[0]
    assert angle is not None and abs(angle - 90.0) < 1e-9 and s.pin_angles()[1] is None

    state = state_message(s)["constraints"]
    assert len(state["points"]) == 2 and abs(state["points"][0]["angle"] - 90.0) < 1e-9
    assert "angle" not in state["points"][1]
    document = s.constraints.document(s.V, s.transforms)  # (a picture's mesh is not its file's: this numbering)
    assert len(document["points"]) == 2 and all(set(p) <= {"face", "barycentric", "target", "weight"}
                                                for p in document["points"])
    assert s.export("png")[2][:4] == b"\x89PNG"

    assert s.undo()
    assert s.pin_angles() == [None, None]
    assert len(state_message(s)["constraints"]["points"]) == 2
    np.testing.assert_allclose(s.U, before, atol=1e-6)
    assert s.redo()
    redone = s.pin_angles()[0]
    assert redone is not None and abs(redone - 90.0) < 1e-9


def test_a_held_pin_turns_with_its_transform_and_keeps_its_angle_through_new_pins() -> None:
    s, at_rest = _pinned()
    s.set_pin_angle(0)  # hold the angle it shows now
    shown = s.pin_angles()[0]
    assert shown is not None and abs(shown) < 5.0
    p = at_rest[0]
    c, si = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    turn = np.eye(4)
    turn[:2, :2] = [[c, -si], [si, c]]
    turn[:2, 3] = p[:2] - turn[:2, :2] @ p[:2]  # about the pin
    s.drag([turn.T.reshape(16).tolist(), translation(0.0)])
    s.end_drag()
    s.settle(lambda: False)
    angle = s.pin_angles()[0]
    assert angle is not None and abs(angle - shown - 30.0) < 1e-6
    np.testing.assert_allclose(_pins(s), at_rest, atol=1e-6)
    rings = s.constraints.rings
    assert rings is not None
    assert abs(float(np.median(_turn_near(s, p, float(np.linalg.norm(rings.offset[0]))))) - angle) < 15.0
    assert matrices_to_json(s.transforms)[0] == pytest.approx(turn.T.reshape(16).tolist())

    mesh = s.mesh
    assert mesh is not None
    pins = [*s.constraints.points_json(s.transforms), _pin_at(mesh, 60, 90)]
    s.set_constraints(None, [], [], points=pins)  # a third pin: the first keeps its angle
    kept = s.pin_angles()
    assert kept[0] is not None and abs(kept[0] - angle) < 1e-6 and kept[1:] == [None, None]
    s.remesh("coarse", 100_000)
    again = s.pin_angles()
    assert again[0] is not None and abs(again[0] - angle) < 1e-6 and again[1:] == [None, None]
    s.reset()  # back to the rest pose: the pin holds it, unturned
    assert s.pin_angles() == [0.0, None, None]
    s.settle(lambda: False)
    np.testing.assert_allclose(s.U, s.V, atol=1e-6)


def test_pin_angles_are_refused_off_pictures_and_pins() -> None:
    from arap.server.meshdata import load_builtin

    s, _ = _pinned()
    with pytest.raises(BadValues, match="no pin 2"):
        s.set_pin_angle(2, 10.0)
    bar = Session()
    bar.load(load_builtin("bar"))
    with pytest.raises(UnusableMesh, match="picture"):
        bar.set_pin_angle(0, 10.0)


def test_the_studio_turns_a_pin_and_its_state_holds_the_angle_not_the_ring(studio: StudioClient) -> None:
    studio.send_binary({"type": "upload", "filename": "disc.png"}, _disc_png())
    studio.read_mesh()
    while studio.recv().type != "state":
        pass
    points: list[dict[str, Any]] = [{"face": 0, "barycentric": [1 / 3, 1 / 3, 1 / 3]}]
    studio.send({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": [], "points": points})
    studio.expect("state")
    studio.send({"type": "set_pin_angle", "pin": 0, "angle": 45})
    while (reply := studio.recv()).type != "state":
        pass
    assert reply.data["constraints"]["points"] == [{**points[0], "angle": 45.0}]
    studio.send({"type": "end_drag"})
    assert studio.expect("state").data["can_undo"]


def test_an_animation_turns_a_held_pin_as_its_keyframes_do() -> None:
    import io
    import zipfile

    from PIL import Image

    from arap.server.animation_export import export_animation

    s, at_rest = _pinned()
    s.set_pin_angle(0, 0.0)
    s.end_drag()
    p = at_rest[0]
    turned = np.eye(4)
    turned[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]
    turned[:2, 3] = p[:2] - turned[:2, :2] @ p[:2]  # a quarter turn about the pin
    still = np.eye(4).reshape(16).tolist()
    transforms = [still, still, turned.T.reshape(16).tolist(), still]
    data = export_animation(s, [0, 1000], transforms, 2.0, lambda: False, fmt="zip")[2]
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        frames = [np.asarray(Image.open(io.BytesIO(z.read(n))).convert("RGBA")) for n in sorted(z.namelist())]
    assert len(frames) == 3 and np.abs(frames[0].astype(int) - frames[-1]).max() > 100  # the pin's part turned
