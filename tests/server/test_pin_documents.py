"""A picture's pins in constraints documents: Save constraints keeps the angles they hold and their depths, loading
the document gives them back, old documents still load, and the command line says what it does with them."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from arap.cli import main
from arap.constraints import load_constraints, save_constraints
from arap.errors import ConstraintError
from arap.server.pictures import load_picture, page_draw_order
from arap.server.session import Session
from tests.server.test_pictures import _two_squares_png, blue_pinned_over_red


def _turned_and_layered() -> Session:
    """The two squares with a pin on each, the blue one moved over the red one; pin 0 holds 30 degrees, pin 1 is in
    front."""
    s = blue_pinned_over_red()
    s.set_pin_angle(0, 30.0)
    s.end_drag()
    s.set_pin_depth([0, 1])
    return s


def _pin_keys(doc: dict[str, Any]) -> list[dict[str, Any]]:
    return [{k: p[k] for k in ("angle", "depth") if k in p} for p in doc["points"]]


def test_the_document_holds_the_pins_angles_and_depths_and_reads_them_back(tmp_path: Path) -> None:
    s = _turned_and_layered()
    doc = s.constraints_document()
    keys = _pin_keys(doc)
    assert keys[0]["angle"] == pytest.approx(30.0, abs=1e-9) and "angle" not in keys[1]
    assert [k["depth"] for k in keys] == [0, 1]
    assert s.mesh is not None
    c = load_constraints(json.loads(json.dumps(doc)), s.mesh.n_vertices, s.mesh.n_faces)
    assert c.pin_angles is not None and c.pin_angles[0] == pytest.approx(30.0) and c.pin_angles[1] is None
    assert c.pin_depth == [0, 1]
    path = tmp_path / "pins.json"
    save_constraints(path, c)  # the library's own round trip keeps them too
    again = load_constraints(path, s.mesh.n_vertices, s.mesh.n_faces)
    assert again.pin_angles == c.pin_angles and again.pin_depth == [0, 1]


def test_loading_the_document_in_a_new_session_restores_the_angles_and_the_drawing_order() -> None:
    """What the page does with a loaded document: the pins (with their targets), then their depths and angles."""
    s = _turned_and_layered()
    doc = json.loads(json.dumps(s.constraints_document()))
    mesh, look = load_picture(_two_squares_png(), "squares.png", 100_000)
    t = Session()
    t.load(mesh, look)
    c = load_constraints(doc, mesh.n_vertices, mesh.n_faces)
    plain = [{k: v for k, v in p.items() if k not in ("angle", "depth")} for p in doc["points"]]
    t.set_constraints(None, [], [], points=plain)
    assert c.pin_depth is not None and c.pin_angles is not None
    t.set_pin_depth(c.pin_depth)
    for k, angle in enumerate(c.pin_angles):
        if angle is not None:
            t.set_pin_angle(k, angle)
    t.end_drag()
    angles = t.pin_angles()
    assert angles[0] == pytest.approx(30.0, abs=1e-9) and angles[1] is None
    assert page_draw_order(t) == page_draw_order(s) and page_draw_order(t) is not None
    s.settle(lambda: False)
    t.settle(lambda: False)
    np.testing.assert_allclose(t.U, s.U, atol=1e-3 * float(np.ptp(s.V)))


def test_documents_without_angles_or_depths_load_as_before() -> None:
    doc = {"version": 2, "points": [{"face": 0, "barycentric": [0.2, 0.3, 0.5], "target": [0.0, 0.0, 0.0]}]}
    c = load_constraints(doc, 10, 4)
    assert c.pin_angles is None and c.pin_depth is None
    assert c.to_dict()["points"] == doc["points"]
    c = load_constraints({"fixed": [0, 1]}, 10)
    assert c.pin_angles is None and c.pin_depth is None


@pytest.mark.parametrize(("extra", "match"), [
    ({"angle": "30"}, r"points\[0\]\.angle must be a finite number"),
    ({"angle": True}, r"points\[0\]\.angle must be a finite number"),
    ({"angle": float("nan")}, r"points\[0\]\.angle must be a finite number"),
    ({"depth": 1.5}, r"points\[0\]\.depth must be an integer"),
    ({"depth": 10**40}, r"points\[0\]\.depth must be an integer"),
    ({"turn": 3}, r'points\[0\] must be an object with .*"angle" and "depth"'),
])
def test_bad_angles_and_depths_are_refused_with_their_reason(extra: dict[str, Any], match: str) -> None:
    doc = {"version": 2, "points": [{"face": 0, "barycentric": [0.2, 0.3, 0.5], "target": [0.0, 0.0, 0.0]} | extra]}
    with pytest.raises(ConstraintError, match=match):
        load_constraints(doc, 10, 4)


def test_the_studio_still_refuses_angles_in_its_set_constraints() -> None:
    from arap.constraints.entries import points_from_json

    with pytest.raises(ConstraintError, match="must be an object"):
        points_from_json([{"face": 0, "barycentric": [1, 0, 0], "angle": 3.0}], 4, require_target=False)


def _mesh_file(s: Session, path: Path) -> Path:
    from arap.io import save_mesh

    assert s.mesh is not None
    save_mesh(path, s.V, s.mesh.F)
    return path


def test_arap_deform_says_why_it_does_not_hold_a_pins_angle(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    s = _turned_and_layered()
    mesh = _mesh_file(s, tmp_path / "squares.obj")
    doc = tmp_path / "pins.json"
    doc.write_text(json.dumps(s.constraints_document()))
    out = tmp_path / "out.obj"
    assert main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "--quiet"]) == 1
    said = capsys.readouterr().err.strip()
    assert len(said.splitlines()) == 1, said
    assert "arap deform cannot hold a pin's surroundings turned: points[0] holds an angle of 30 degrees" in said
    assert not out.exists()
    # without the angle (the depths only concern drawing) it deforms
    free = json.loads(doc.read_text())
    del free["points"][0]["angle"]
    doc.write_text(json.dumps(free))
    assert main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "--quiet"]) == 0
    assert out.exists()


def test_arap_warp_names_a_constraints_document_and_honours_angles(tmp_path: Path,
                                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    from arap.puppet.warp import PuppetWarp
    from tests.puppet.pictures import bar

    img = bar()
    image = tmp_path / "bar.png"
    Image.fromarray(img).save(image)
    doc = tmp_path / "doc.json"
    doc.write_text(json.dumps(_turned_and_layered().constraints_document()))
    out = tmp_path / "out.png"
    assert main(["warp", str(image), "--pins", str(doc), "-o", str(out)]) == 1
    said = capsys.readouterr().err.strip()
    assert len(said.splitlines()) == 1 and "this is a constraints document" in said and not out.exists()

    pins = {"pins": [[30, 100], [100, 100], [170, 100]], "targets": [None, None, [160, 60]], "angles": [None, 45, None]}
    pins_file = tmp_path / "pins.json"
    pins_file.write_text(json.dumps(pins))
    assert main(["warp", str(image), "--pins", str(pins_file), "-o", str(out), "--spacing", "8"]) == 0
    puppet = PuppetWarp(img, pins["pins"], spacing=8, angles=pins["angles"])
    expected = puppet(pins["targets"])
    written = np.asarray(Image.open(out)).astype(float)
    assert np.abs(written - expected).mean() <= 1.0
    free = PuppetWarp(img, pins["pins"], spacing=8)(pins["targets"])
    assert np.abs(written - free).mean() > 1.0  # the angle changed the warp
    pins_file.write_text(json.dumps(pins | {"angles": 45}))
    assert main(["warp", str(image), "--pins", str(pins_file), "-o", str(tmp_path / "o2.png")]) == 1
    assert '"angles" must be a list' in capsys.readouterr().err


def test_arap_batch_says_why_a_job_with_a_pins_angle_fails(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    s = _turned_and_layered()
    _mesh_file(s, tmp_path / "squares.obj")
    (tmp_path / "pins.json").write_text(json.dumps(s.constraints_document()))
    manifest = tmp_path / "jobs.jsonl"
    manifest.write_text(json.dumps({"mesh": "squares.obj", "constraints": "pins.json", "output": "out.obj"}) + "\n")
    assert main(["batch", str(manifest), "--backend", "serial", "-q"]) == 1
    assert "arap batch cannot hold a pin's surroundings turned" in capsys.readouterr().err
    assert not (tmp_path / "out.obj").exists()
