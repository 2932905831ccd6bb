"""A picture's pins in a keyframes document: the studio's saved timeline keeps the angles the pins hold (per keyframe)
and their depths, the document loads them back, and ``arap animate`` holds the angles as the studio's animation
export does."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.animation import animate
from arap.cli import main
from arap.constraints.keyframes import load_keyframes
from arap.errors import ConstraintError
from arap.server.animation_export import export_animation, keyframes_document
from arap.server.pictures import load_picture, pin_turn
from arap.server.session import Session
from tests.animated_glb import glb_frames
from tests.server.helpers import column_major, rotation_z, translation
from tests.server.test_pictures import _disc_png, _pin_at

TIMES = [0, 1000]


def _timeline() -> tuple[Session, list[list[float]]]:
    """The disc with a pin left of its centre (0: holds 30 degrees, depth 0) and one near its right edge (1: turns
    freely, depth 1), and the transforms of two keyframes (per keyframe: pin 0, pin 1): at rest, then pin 0 turned
    a quarter turn about itself and moved 6 px up, pin 1 still."""
    mesh, look = load_picture(_disc_png(), "disc.png", 100_000)
    s = Session()
    s.load(mesh, look)
    s.set_constraints(None, [], [], points=[_pin_at(mesh, 40, 60), _pin_at(mesh, 95, 60)])
    s.set_pin_angle(0, 30.0)
    s.end_drag()
    s.set_pin_depth([0, 1])
    pts = s.constraints.points
    assert pts is not None
    pin = np.einsum("c,cd->d", pts.barycentric[0], s.V[mesh.F[pts.faces[0]]])
    still = translation(0.0)
    return s, [still, still, column_major(rotation_z(math.pi / 2, pin, shift=(0.0, 6.0, 0.0))), still]


def test_the_saved_timeline_keeps_the_pins_angles_per_keyframe_and_their_depths() -> None:
    s, transforms = _timeline()
    doc = json.loads(json.dumps(keyframes_document(s, TIMES, transforms)))
    assert [p.get("angle") for p in doc["points"]] == [pytest.approx(30.0), None]
    assert [p.get("depth") for p in doc["points"]] == [0, 1]
    angles = [k["point_angles"] for k in doc["keyframes"]]
    assert angles == [[pytest.approx(30.0), None], [pytest.approx(120.0), None]]
    assert s.mesh is not None
    keys = load_keyframes(doc, s.V, s.mesh.n_faces)
    c = keys.constraints
    assert c.pin_angles == [pytest.approx(30.0), None] and c.pin_depth == [0, 1]
    assert [k.point_angles for k in keys.keys] == [(pytest.approx(30.0), None), (pytest.approx(120.0), None)]


def test_a_timeline_without_angles_saves_and_loads_as_before() -> None:
    s, transforms = _timeline()
    s.undo()  # before the angle
    assert s.pin_angles() == [None, None]
    doc = keyframes_document(s, TIMES, transforms)
    assert all("point_angles" not in k for k in doc["keyframes"])
    assert all("angle" not in p for p in doc["points"])
    assert s.mesh is not None
    keys = load_keyframes(doc, s.V, s.mesh.n_faces)
    assert keys.constraints.pin_angles is None and all(k.point_angles is None for k in keys.keys)


def _mesh_file(s: Session, path: Path) -> Path:
    from arap.io import save_mesh

    assert s.mesh is not None
    save_mesh(path, s.V, s.mesh.F)
    return path


def test_arap_animate_holds_the_pins_angles_as_the_studios_export_does(tmp_path: Path) -> None:
    from arap.io import load_mesh

    s, transforms = _timeline()
    mesh = _mesh_file(s, tmp_path / "disc.obj")
    doc = tmp_path / "keys.json"
    doc.write_text(json.dumps(keyframes_document(s, TIMES, transforms)))
    p = s.params
    out = tmp_path / "frame_####.obj"
    assert main(["animate", str(mesh), "-k", str(doc), "-o", str(out), "--fps", "2", "--exact", "-q",
                 "--weights", p.weights, "--alpha", str(p.alpha)]) == 0
    frames = np.stack([load_mesh(tmp_path / f"frame_{k:04d}.obj")[0] for k in range(3)])
    _, _, data, count, _ = export_animation(s, TIMES, transforms, 2.0, lambda: False)
    exported = glb_frames(data)[1]
    assert count == 3 and exported.shape == frames.shape
    size = float(np.ptp(s.V[:, :2]))
    np.testing.assert_allclose(frames, exported, atol=1e-5 * size)  # float32 in the GLB
    assert s.mesh is not None and s.constraints.points is not None
    offline = animate(s.V, s.mesh.F, json.loads(doc.read_text()), fps=2.0, energy="elements", weights=p.weights,
                      alpha=p.alpha)  # the library's animate holds them too
    np.testing.assert_allclose(offline.vertices, exported, atol=1e-5 * size)
    turned = math.degrees(pin_turn(s.V, frames[-1], s.mesh.F, s.constraints.points, 0))
    assert abs(turned - 120.0) < 1.0, turned  # the pin's surroundings hold its angle at the last keyframe


def _document(**key: Any) -> dict[str, Any]:
    """Two point handles on the square of two triangles, the first holding 10 degrees; keyframes at 0 and 1 s, the
    second with ``key``."""
    points = [{"face": 0, "barycentric": [0.4, 0.3, 0.3], "target": [0.3, 0.3, 0.0], "angle": 10.0},
              {"face": 1, "barycentric": [0.3, 0.3, 0.4], "target": [0.7, 0.7, 0.0]}]
    return {"version": 2, "points": points, "keyframes": [{"time": 0.0, "transforms": []},
                                                          {"time": 1.0, "transforms": []} | key]}


SQUARE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])


def test_a_keyframe_without_angles_holds_those_before_it() -> None:
    keys = load_keyframes(_document(), SQUARE, 2)
    assert [k.point_angles for k in keys.keys] == [(10.0, None), (10.0, None)]
    doc = _document()
    doc["keyframes"][0]["point_angles"] = [40, None]
    keys = load_keyframes(doc, SQUARE, 2)
    assert [k.point_angles for k in keys.keys] == [(40.0, None), (40.0, None)]


@pytest.mark.parametrize(("angles", "match"), [
    ([10.0], r"keyframes\[1\]\.point_angles must be a list of one angle .* per point handle \(2\)"),
    ("10", r"keyframes\[1\]\.point_angles must be a list"),
    ([None, None], r"keyframes\[1\]\.point_angles\[0\] is null, but points\[0\] holds an angle"),
    ([10.0, 5.0], r"keyframes\[1\]\.point_angles\[1\]: points\[1\] holds no angle"),
    (["10", None], r"keyframes\[1\]\.point_angles\[0\] must be a finite number of degrees"),
    ([True, None], r"keyframes\[1\]\.point_angles\[0\] must be a finite number of degrees"),
    ([10**400, None], r"keyframes\[1\]\.point_angles\[0\] must be a finite number of degrees"),
    ([float("nan"), None], r"keyframes\[1\]\.point_angles\[0\] must be a finite number of degrees"),
])
def test_bad_point_angles_are_refused_with_their_reason(angles: Any, match: str) -> None:
    with pytest.raises(ConstraintError, match=match):
        load_keyframes(_document(point_angles=angles), SQUARE, 2)


def test_arap_animate_says_why_it_cannot_hold_a_pins_angle_off_the_plane(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    from arap.io import save_mesh

    s, transforms = _timeline()
    assert s.mesh is not None
    bent = s.V.copy()
    bent[:, 2] = 0.01 * bent[:, 0] ** 2  # not flat: no turn about z to hold
    save_mesh(tmp_path / "bent.obj", bent, s.mesh.F)
    doc = tmp_path / "keys.json"
    doc.write_text(json.dumps(keyframes_document(s, TIMES, transforms)))
    assert main(["animate", str(tmp_path / "bent.obj"), "-k", str(doc), "-o", str(tmp_path / "f_#.obj"), "-q"]) == 1
    said = capsys.readouterr().err.strip()
    assert len(said.splitlines()) == 1 and "arap animate holds a pin's angle only on a flat mesh" in said, said
    assert not list(tmp_path.glob("f_*.obj"))
