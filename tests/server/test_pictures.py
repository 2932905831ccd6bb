"""Pictures in the studio: opened as flat textured meshes, pinned with point handles and bent in their plane, and
exported as the warped picture."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest
from PIL import Image

from arap.server.pictures import is_picture, load_picture
from arap.server.session import Session
from tests.server.helpers import StudioClient, translation


def _disc_png(size: int = 120) -> bytes:
    """A red disc with a green dot, on a transparent background."""
    y, x = np.mgrid[:size, :size]
    rgba = np.zeros((size, size, 4), dtype=np.uint8)
    inside = (x - size / 2) ** 2 + (y - size / 2) ** 2 < (0.4 * size) ** 2
    rgba[inside] = [220, 40, 40, 255]
    rgba[(np.abs(x - 0.8 * size) < 3) & (np.abs(y - size / 2) < 3)] = [0, 200, 0, 255]
    out = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(out, format="PNG")
    return out.getvalue()


def _loaded() -> Session:
    mesh, look = load_picture(_disc_png(), "disc.png", 100_000)
    s = Session()
    s.load(mesh, look)
    return s


def test_a_picture_becomes_a_flat_textured_mesh() -> None:
    assert is_picture("Cat.PNG") and is_picture("a.webp") and not is_picture("a.obj")
    s = _loaded()
    mesh = s.mesh
    assert mesh is not None and mesh.picture is not None and mesh.picture.shape == (120, 120, 4)
    assert np.all(mesh.V[:, 2] == 0.0) and 200 < mesh.n_vertices < 20_000
    assert s.look is not None and s.look.textured
    assert any("picture" in line for line in mesh.report)


def test_pins_bend_the_picture_in_its_plane_and_the_png_shows_it() -> None:
    s = _loaded()
    mesh = s.mesh
    assert mesh is not None
    centre = mesh.V[mesh.F].mean(axis=1)
    left = int(np.argmin(centre[:, 0]))
    right = int(np.argmax(centre[:, 0]))
    third = [1 / 3, 1 / 3, 1 / 3]
    target = (np.array(third) @ mesh.V[mesh.F[right]] + [0.0, 30.0, 25.0]).tolist()  # also off the plane
    s.set_constraints(None, [], [], points=[{"face": left, "barycentric": third},
                                             {"face": right, "barycentric": third, "target": target}])
    s.drag([translation(0.0), translation(0.0)])
    s.end_drag()
    s.settle(lambda: False)
    assert s.solver is not None and s.solver.energy_type == "elements"
    assert np.all(s.U[:, 2] == 0.0)  # put back on the plane
    np.testing.assert_allclose(np.array(third) @ s.U[mesh.F[right]], [*target[:2], 0.0], atol=1e-6)
    name, mime, data = s.export("png")
    assert name == "disc-deformed.png" and mime == "image/png"
    picture = np.asarray(Image.open(io.BytesIO(data)))
    assert picture.shape == (120, 120, 4)
    green = np.argwhere((picture[:, :, 1] > 150) & (picture[:, :, 0] < 80) & (picture[:, :, 3] > 0))
    assert len(green) and green[:, 0].mean() < 60 - 20  # the dot went up with its pin (rows run down)
    opaque = (picture[:, :, 3] > 0).sum()
    assert abs(opaque - np.pi * 48 ** 2) < 0.1 * np.pi * 48 ** 2
    glb = s.export("glb")[2]
    assert glb[:4] == b"glTF"


def test_a_surface_exports_a_picture_of_its_shape() -> None:
    from arap.server.meshdata import load_builtin

    s = Session()
    s.load(load_builtin("bar"))
    name, mime, data = s.export("png")
    assert name.endswith(".png") and mime == "image/png" and data[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("data", "match"), [(b"not a picture", "not a picture"), (_disc_png()[:60], "corrupt")])
def test_bad_pictures_are_refused_with_their_reason(data: bytes, match: str) -> None:
    from arap.server.errors import RequestError

    with pytest.raises(RequestError, match=match):
        load_picture(data, "x.png", 100_000)


def _stretched_area(warp: str) -> tuple[float, Session]:
    """The picture's area after its two ends are pulled apart, in the warp mode ``warp``."""
    s = _loaded()
    s.set_params(warp=warp)
    mesh = s.mesh
    assert mesh is not None
    centre = mesh.V[mesh.F].mean(axis=1)
    left, right = int(np.argmin(centre[:, 0])), int(np.argmax(centre[:, 0]))
    third = [1 / 3, 1 / 3, 1 / 3]
    target = (np.array(third) @ mesh.V[mesh.F[right]] + [40.0, 0.0, 0.0]).tolist()
    s.set_constraints(None, [], [], points=[{"face": left, "barycentric": third},
                                             {"face": right, "barycentric": third, "target": target}])
    s.settle(lambda: False)
    assert np.all(s.U[:, 2] == 0.0)
    np.testing.assert_allclose(np.array(third) @ s.U[mesh.F[right]], target, atol=1e-6)

    def area(P: np.ndarray) -> float:
        e1, e2 = P[mesh.F[:, 1]] - P[mesh.F[:, 0]], P[mesh.F[:, 2]] - P[mesh.F[:, 0]]
        return float(0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]).sum())

    return area(s.U) / area(mesh.V), s


def test_the_warp_mode_chooses_how_much_the_picture_may_grow() -> None:
    rigid, s = _stretched_area("rigid")
    normal, _ = _stretched_area("normal")
    distort, _ = _stretched_area("distort")
    assert s.params.warp == "rigid"
    assert rigid + 0.02 < normal < distort - 0.1
    assert distort > 1.3  # a disc pulled wider by 40 of its 96 pixels grows as a whole


def test_changing_the_warp_mode_solves_again() -> None:
    s = _loaded()
    mesh = s.mesh
    assert mesh is not None
    third = [1 / 3, 1 / 3, 1 / 3]
    centre = mesh.V[mesh.F].mean(axis=1)
    left, right = int(np.argmin(centre[:, 0])), int(np.argmax(centre[:, 0]))
    target = (np.array(third) @ mesh.V[mesh.F[right]] + [40.0, 0.0, 0.0]).tolist()
    s.set_constraints(None, [], [], points=[{"face": left, "barycentric": third},
                                             {"face": right, "barycentric": third, "target": target}])
    s.settle(lambda: False)
    before = s.U.copy()
    s.set_params(warp="distort")
    assert not s.settled
    s.settle(lambda: False)
    assert np.abs(s.U - before).max() > 1.0


def test_the_mesh_frame_says_it_is_a_picture_and_its_size() -> None:
    from arap.server.frames import decode_binary
    from arap.server.meshdata import load_builtin, mesh_frame

    s = _loaded()
    assert s.mesh is not None
    assert decode_binary(mesh_frame(s.mesh))[0]["picture"] == [120, 120]
    assert decode_binary(mesh_frame(load_builtin("bar")))[0]["picture"] is None


def _two_squares_png() -> bytes:
    """A red square and a blue one side by side, apart, on a transparent background (120 × 60)."""
    rgba = np.zeros((60, 120, 4), dtype=np.uint8)
    rgba[10:50, 10:50] = [220, 40, 40, 255]
    rgba[10:50, 70:110] = [40, 40, 220, 255]
    out = io.BytesIO()
    Image.fromarray(rgba, "RGBA").save(out, format="PNG")
    return out.getvalue()


def _pin_at(mesh: Any, x: float, y: float) -> dict[str, Any]:
    """A point handle at the triangle whose centroid is nearest to (x, y) (the studio's coordinates)."""
    centre = mesh.V[mesh.F].mean(axis=1)
    face = int(np.argmin(np.hypot(centre[:, 0] - x, centre[:, 1] - y)))
    return {"face": face, "barycentric": [1 / 3, 1 / 3, 1 / 3]}


def blue_pinned_over_red() -> Session:
    """The two squares with a pin on each, the blue one's pin moved 40 px left, over the red square."""
    mesh, look = load_picture(_two_squares_png(), "squares.png", 100_000)
    s = Session()
    s.load(mesh, look)
    red, blue = _pin_at(mesh, 30, 30), _pin_at(mesh, 90, 30)
    blue["target"] = (np.array(blue["barycentric"]) @ mesh.V[mesh.F[blue["face"]]] + [-40.0, 0.0, 0.0]).tolist()
    s.set_constraints(None, [], [], points=[red, blue])
    return s


def test_pin_depth_chooses_which_part_covers_the_other_in_the_png() -> None:
    s = blue_pinned_over_red()
    s.settle(lambda: False)

    def overlap_colour() -> np.ndarray:
        picture = np.asarray(Image.open(io.BytesIO(s.export("png")[2])))
        return picture[25:35, 35:45].reshape(-1, 4).mean(axis=0)  # where the blue square now covers the red one

    s.set_pin_depth([0, 1])
    front_blue = overlap_colour()
    assert front_blue[2] > 200 and front_blue[0] < 60
    s.set_pin_depth([1, 0])
    front_red = overlap_colour()
    assert front_red[0] > 200 and front_red[2] < 60


def test_the_state_gives_the_page_the_drawing_order_of_the_pins_depths() -> None:
    from arap.server.meshdata import load_builtin
    from arap.server.replies import state_message

    mesh, look = load_picture(_two_squares_png(), "squares.png", 100_000)
    s = Session()
    s.load(mesh, look)
    s.set_constraints(None, [], [], points=[_pin_at(mesh, 30, 30), _pin_at(mesh, 90, 30)])
    assert state_message(s)["draw_order"] is None  # no depths: the mesh's order
    assert state_message(s)["draw_layers"] is None
    blue = mesh.V[mesh.F].mean(axis=1)[:, 0] > 60  # the triangles of the right square (pin 1's part)

    def last_drawn() -> np.ndarray:
        state = state_message(s)
        order = state["draw_order"]
        assert order is not None and sorted(order) == list(range(mesh.n_faces))
        # the layers: the runs of the order whose triangles share a depth (here a square each), back to front
        drawn = blue[np.asarray(order)]
        assert state["draw_layers"] == [int((drawn == drawn[0]).sum()), int((drawn != drawn[0]).sum())]
        return drawn

    s.set_pin_depth([0, 1])
    assert last_drawn()[-int(blue.sum()):].all()  # the blue square's triangles after the red one's
    s.set_pin_depth([1, 0])
    assert not last_drawn()[-int((~blue).sum()):].any()
    s.set_pin_depth([0, 0])
    assert state_message(s)["draw_order"] is None and state_message(s)["draw_layers"] is None
    bar = Session()
    bar.load(load_builtin("bar"))
    bar.set_pin_depth([1])
    assert state_message(bar)["draw_order"] is None


def test_meshing_again_keeps_the_pins_places_and_targets() -> None:
    s = _loaded()
    mesh = s.mesh
    assert mesh is not None
    left, right = _pin_at(mesh, 25, 60), _pin_at(mesh, 95, 60)
    right["weight"] = 50.0
    right["target"] = (np.array(right["barycentric"]) @ mesh.V[mesh.F[right["face"]]] + [10.0, 20.0, 0.0]).tolist()
    s.set_constraints(None, [], [], points=[left, right])
    s.settle(lambda: False)
    s.set_pin_depth([0, 1])
    old = s.constraints.points
    assert old is not None
    rest = np.einsum("kc,kcd->kd", old.barycentric, mesh.V[mesh.F[old.faces]])
    now = np.einsum("kc,kcd->kd", old.barycentric, s.U[mesh.F[old.faces]])
    for density, more in (("coarse", False), ("fine", True)):
        before = s.n_vertices
        new = s.remesh(density, 100_000)
        assert s.mesh is new and new.picture is not None and (new.n_vertices > before) == more
        pts = s.constraints.points
        assert pts is not None and len(pts.faces) == 2 and s.pin_depth == [0, 1]
        np.testing.assert_allclose(np.einsum("kc,kcd->kd", pts.barycentric, new.V[new.F[pts.faces]]), rest, atol=1e-6)
        np.testing.assert_allclose(pts.weights, old.weights)
        s.settle(lambda: False)
        at = np.einsum("kc,kcd->kd", pts.barycentric, s.U[new.F[pts.faces]])
        np.testing.assert_allclose(at[0], now[0], atol=1e-6)  # the hard pin where it was
        np.testing.assert_allclose(at[1], now[1], atol=2.0)  # the soft one near it


def test_only_a_picture_is_meshed_again() -> None:
    from arap.server.meshdata import load_builtin
    from arap.server.session_errors import UnusableMesh

    s = Session()
    s.load(load_builtin("bar"))
    with pytest.raises(UnusableMesh, match="picture"):
        s.remesh("fine", 100_000)


def test_the_studio_sets_pin_depths_and_meshes_a_picture_again(studio: StudioClient) -> None:
    studio.send_binary({"type": "upload", "filename": "disc.png"}, _disc_png())
    normal = studio.read_mesh().data["n_vertices"]
    while studio.recv().type != "state":  # the picture's appearance first
        pass
    studio.send({"type": "set_constraints", "roi": None, "fixed": [], "handle_groups": [],
                 "points": [{"face": 0, "barycentric": [1 / 3, 1 / 3, 1 / 3]}]})
    studio.expect("state")
    studio.send({"type": "set_pin_depth", "depth": [2]})
    studio.expect("state")
    studio.send({"type": "remesh", "density": "coarse"})
    assert studio.read_mesh().data["n_vertices"] < normal
    replies = []
    while (reply := studio.recv()).type != "state":
        replies.append(reply.type)
    assert "appearance" in replies and "vertices" in replies and len(reply.data["constraints"]["points"]) == 1


def test_a_server_started_on_a_picture_file_opens_it_as_the_page_opens_one(tmp_path: Any) -> None:
    """``arap studio picture.png``: the picture is meshed and textured as an upload of it is, and the texture its look
    sends is the picture itself, which the page keeps as the session's source: opened again, the same mesh."""
    from arap.server.app import create_app
    from arap.studio_handle import picture_input

    path = tmp_path / "disc.png"
    path.write_bytes(_disc_png())
    studio = create_app(path).state.studio
    uploaded, _ = load_picture(_disc_png(), "disc.png", 100_000)
    mesh, look = studio.default_mesh, studio.default_look
    assert mesh.name == "disc" and mesh.picture is not None and look is not None and look.textured
    assert np.array_equal(mesh.V, uploaded.V) and np.array_equal(mesh.F, uploaded.F)
    opened = picture_input(path, None, "mesh")  # arap.studio(picture) from a notebook
    assert opened is not None
    for m, lk in ((mesh, look), opened):
        assert lk.texture_mime == "image/png"
        again, _ = load_picture(lk.texture, "disc.png", 100_000)
        assert again.picture is not None and np.array_equal(again.picture, m.picture)
        assert np.array_equal(again.V, m.V) and np.array_equal(again.F, m.F)


def test_a_server_refuses_a_picture_file_it_cannot_mesh_with_its_reason(tmp_path: Any) -> None:
    from arap.errors import ArapError
    from arap.server.app import create_app

    empty = tmp_path / "empty.png"
    Image.fromarray(np.zeros((20, 20, 4), dtype=np.uint8), "RGBA").save(empty)
    with pytest.raises(ArapError, match=r"empty\.png: the picture's shape is empty"):
        create_app(empty)
    broken = tmp_path / "broken.png"
    broken.write_bytes(b"not a picture")
    with pytest.raises(ArapError, match=r"broken\.png: not a picture file") as info:
        create_app(broken)
    assert str(info.value).count("broken.png") == 1
