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


def _settled(s: Session) -> np.ndarray:
    s.settle(lambda: False)
    return np.array(s.U)


def _red_square_turned(s: Session, U: np.ndarray, degrees: float) -> None:
    """The red square (pin 0's, alone on its island) in ``U`` is its rest shape turned by ``degrees`` about its pin
    (counter-clockwise as seen), the pin at its target."""
    assert s.mesh is not None and s.constraints.points is not None
    V, F = s.V, s.mesh.F
    red = np.unique(F[V[F].mean(axis=1)[:, 0] < 60.0])
    pin = s.constraints.points.positions(V, F)[0]
    a = np.radians(degrees)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(U[red], (V[red] - pin) @ R.T + pin, atol=1e-4 * float(np.ptp(V)))


def _deformed(mesh: Path, doc: Path) -> np.ndarray:
    """``arap deform`` of ``mesh`` with the document ``doc``: a flat mesh, so the element energy by default (the
    studio's rigid warp)."""
    from arap.io import load_mesh

    out = doc.with_suffix(".out.obj")
    assert main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "--quiet"]) == 0
    U, _ = load_mesh(out, repair=False)
    return U


def test_arap_deform_holds_the_pins_angles_as_the_studio_does(tmp_path: Path) -> None:
    s = _turned_and_layered()
    doc = tmp_path / "pins.json"
    doc.write_text(json.dumps(s.constraints_document()))
    U = _deformed(_mesh_file(s, tmp_path / "squares.obj"), doc)
    np.testing.assert_allclose(U, _settled(s), atol=1e-3 * float(np.ptp(s.V)))
    _red_square_turned(s, U, 30.0)  # pin 0's square, alone on its island, turned by its angle about the pin


def test_arap_deform_turns_a_pins_surroundings_inside_a_bent_shape(tmp_path: Path) -> None:
    """A bar pinned at both ends and in the middle, the middle pin turned 40 degrees: its ring turns by 40 degrees
    about it and the triangles within the ring by about as much (the bar bends away from it), as in the studio;
    without the angle nothing turns."""
    from PIL import Image

    from arap.server.pictures import pin_turn
    from tests.puppet.pictures import bar
    from tests.server.test_pictures import _pin_at

    png = tmp_path / "bar.png"
    Image.fromarray(bar()).save(png)
    mesh, look = load_picture(png.read_bytes(), "bar.png", 100_000)
    s = Session()
    s.load(mesh, look)
    V, F = mesh.V, mesh.F
    middle = float(V[:, 1].max() + V[:, 1].min()) / 2
    s.set_constraints(None, [], [], points=[_pin_at(mesh, x, middle) for x in (30.0, 100.0, 170.0)])
    s.set_pin_angle(1, 40.0)
    s.end_drag()
    path = _mesh_file(s, tmp_path / "bar.obj")
    doc = tmp_path / "pins.json"
    doc.write_text(json.dumps(s.constraints_document()))
    U = _deformed(path, doc)
    np.testing.assert_allclose(U, _settled(s), atol=1e-3 * float(np.ptp(V)))
    assert s.constraints.points is not None
    pin = s.constraints.points.positions(V, F)[1]
    assert np.degrees(pin_turn(V, U, F, s.constraints.points, 1)) == pytest.approx(40.0, abs=1e-6)  # its ring
    assert _mean_turn(V, U, F, pin) == pytest.approx(40.0, abs=4.0)
    free = json.loads(doc.read_text())
    del free["points"][1]["angle"]
    doc.write_text(json.dumps(free))
    assert abs(_mean_turn(V, _deformed(path, doc), F, pin)) < 1.0


def _mean_turn(V: np.ndarray, U: np.ndarray, F: np.ndarray, pin: np.ndarray) -> float:
    """The mean turn (degrees, counter-clockwise as seen) from ``V`` to ``U`` of the triangles within a pin's ring
    (their rest centroids)."""
    from arap.puppet.rings import ring_offsets

    near = F[np.linalg.norm(V[F].mean(axis=1)[:, :2] - pin[:2], axis=1) < np.linalg.norm(ring_offsets(V, F)[0])]
    E0 = np.stack([V[near[:, 1], :2] - V[near[:, 0], :2], V[near[:, 2], :2] - V[near[:, 0], :2]], axis=2)
    E1 = np.stack([U[near[:, 1], :2] - U[near[:, 0], :2], U[near[:, 2], :2] - U[near[:, 0], :2]], axis=2)
    J = E1 @ np.linalg.inv(E0)
    return float(np.degrees(np.arctan2(J[:, 1, 0] - J[:, 0, 1], J[:, 0, 0] + J[:, 1, 1])).mean())


def test_arap_deform_refuses_a_pins_angle_on_a_surface_that_is_not_flat(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    from arap.io import save_mesh

    s = _turned_and_layered()
    assert s.mesh is not None
    bent = np.array(s.V)
    bent[:, 2] = 0.01 * (bent[:, 0] - 60.0) ** 2  # the same triangles, bent out of the plane
    mesh = tmp_path / "bent.obj"
    save_mesh(mesh, bent, s.mesh.F)
    doc = tmp_path / "pins.json"
    doc.write_text(json.dumps(s.constraints_document()))
    out = tmp_path / "out.obj"
    assert main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "--quiet"]) == 1
    said = capsys.readouterr().err.strip()
    assert len(said.splitlines()) == 1, said
    assert "arap deform holds a pin's angle only on a flat mesh in a plane of constant z" in said
    assert "points[0] holds an angle of 30 degrees" in said and not out.exists()
    # without the angle (the depths only concern drawing) it deforms
    free = json.loads(doc.read_text())
    del free["points"][0]["angle"]
    doc.write_text(json.dumps(free))
    assert main(["deform", str(mesh), "-c", str(doc), "-o", str(out), "--quiet"]) == 0
    assert out.exists()


def test_held_points_refuses_angles_on_a_solid() -> None:
    from arap.puppet.rings import held_points

    c = load_constraints({"version": 2, "points": [{"face": 0, "barycentric": [0.25, 0.25, 0.5],
                                                    "target": [0.0, 0.0, 0.0], "angle": 10.0}]}, 4, 1)
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    with pytest.raises(ConstraintError, match=r"arap batch holds a pin's angle only on a flat mesh .* this is a "
                                              r"solid: points\[0\] holds an angle of 10 degrees"):
        held_points(c, V, np.array([[0, 1, 2, 3]]), "arap batch")


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


def test_arap_batch_holds_the_pins_angles_as_arap_deform_does(tmp_path: Path) -> None:
    """Two jobs of one chunk, the same pins with and without an angle: each gets its own solver (the angle's ring
    is a constraint)."""
    from arap.io import load_mesh

    s = _turned_and_layered()
    _mesh_file(s, tmp_path / "squares.obj")
    doc = s.constraints_document()
    (tmp_path / "pins.json").write_text(json.dumps(doc))
    free = json.loads(json.dumps(doc))
    del free["points"][0]["angle"]
    (tmp_path / "free.json").write_text(json.dumps(free))
    manifest = tmp_path / "jobs.jsonl"
    manifest.write_text("".join(json.dumps({"mesh": "squares.obj", "constraints": f"{name}.json",
                                            "output": f"{name}.obj"}) + "\n"
                                for name in ("pins", "free")))
    assert main(["batch", str(manifest), "--backend", "serial", "-q"]) == 0
    U, _ = load_mesh(tmp_path / "pins.obj", repair=False)
    np.testing.assert_allclose(U, _settled(s), atol=1e-3 * float(np.ptp(s.V)))
    _red_square_turned(s, U, 30.0)
    U, _ = load_mesh(tmp_path / "free.obj", repair=False)
    _red_square_turned(s, U, 0.0)  # a lone pin that turns freely: the square keeps its rest turn


def test_a_batch_shares_a_solver_between_pins_angles_not_between_held_and_free_pins(tmp_path: Path) -> None:
    """Jobs whose pins hold other angles share one factorisation; a pin that turns freely has no ring, so its job gets
    a solver of its own, in one chunk as across chunks."""
    from arap.batching.jobs import Job, chunks_for
    from arap.batching.worker import run_chunk
    from arap.io import load_mesh

    s = _turned_and_layered()
    mesh = str(_mesh_file(s, tmp_path / "squares.obj"))
    doc = s.constraints_document()
    files = {}
    for name, angle in (("a30", 30.0), ("a50", 50.0), ("free", None)):
        d = json.loads(json.dumps(doc))
        if angle is None:
            del d["points"][0]["angle"]
        else:
            d["points"][0]["angle"] = angle
        files[name] = tmp_path / f"{name}.json"
        files[name].write_text(json.dumps(d))
    jobs = [Job(k + 1, mesh, str(files[name]), str(tmp_path / f"{name}.obj"))
            for k, name in enumerate(("a30", "a50", "free"))]
    assert sorted(len(c) for c in chunks_for(jobs, 1)) == [1, 2]
    outcomes = run_chunk(jobs)
    assert [o.status for o in outcomes] == ["done"] * 3, [o.reason for o in outcomes]
    assert [o.factorised for o in outcomes] == [True, False, True]
    for name, angle in (("a30", 30.0), ("a50", 50.0), ("free", 0.0)):
        U, _ = load_mesh(tmp_path / f"{name}.obj", repair=False)
        _red_square_turned(s, U, angle)
