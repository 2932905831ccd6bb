"""``arap.show``: what it takes, how it marks constraints, the Picture it returns and the errors it raises."""

from __future__ import annotations

import json
import os
import zlib
from pathlib import Path

import numpy as np
import pytest

import arap
from arap.errors import ConstraintError, MeshError, OptionError
from arap.io.paths import SpecialFileError
from arap.render.camera import view_basis
from arap.render.png import SIGNATURE, encode_png
from arap.render.show import STUDIO_COLORS
from tests.png_files import decode_png
from tests.render.pixels import colour_share
from tests.waiting import scaled

V, F = arap.builtin_mesh("sphere:500")
TOWARD = view_basis(30.0, 20.0)[2]  # the default view
CAP = np.flatnonzero(V @ TOWARD > 0.8 * np.abs(V).max())  # vertices facing the viewer
SIDE = np.setdiff1d(np.flatnonzero((V @ TOWARD > 0) & (V[:, 1] > 0.7 * V[:, 1].max())), CAP)
SMALL = {"width": 96, "height": 72}


def test_anchors_show_in_the_studios_red_and_only_when_marked() -> None:
    plain = arap.show(V, F, **SMALL).pixels
    marked = arap.show(V, F, fixed=CAP, **SMALL).pixels
    assert colour_share(plain, STUDIO_COLORS["fixed"]) == 0
    assert colour_share(marked, STUDIO_COLORS["fixed"]) > 0.02
    assert (plain[0, 0] == marked[0, 0]).all()


def test_handle_groups_get_distinct_colours() -> None:
    pic = arap.show(V, F, handles=[CAP, SIDE], **SMALL).pixels
    first, second = STUDIO_COLORS["handles"][:2]
    assert colour_share(pic, first) > 0.02 and colour_share(pic, second) > 0.005
    assert colour_share(pic, STUDIO_COLORS["fixed"]) == 0
    one_group = arap.show(V, F, handles=np.concatenate([CAP, SIDE]), **SMALL).pixels
    assert colour_share(one_group, first) > 0.02 and colour_share(one_group, second) == 0


@pytest.mark.parametrize("kind", ["dict", "file", "Constraints"])
def test_constraints_documents_files_and_sets_are_marked(kind: str, tmp_path: Path) -> None:
    doc = {"fixed": CAP.tolist(), "handles": SIDE.tolist(), "targets": V[SIDE].tolist()}
    source: object = doc
    if kind == "file":
        source = tmp_path / "c.json"
        source.write_text(json.dumps(doc))
    elif kind == "Constraints":
        source = arap.load_constraints(doc, len(V))
    pic = arap.show(V, F, constraints=source, **SMALL).pixels
    assert colour_share(pic, STUDIO_COLORS["fixed"]) > 0.02
    assert colour_share(pic, STUDIO_COLORS["handles"][0]) > 0.005


def test_a_region_of_interest_is_blue_and_the_rest_darker() -> None:
    roi = np.flatnonzero(V @ TOWARD > 0).tolist()
    pic = arap.show(V, F, constraints={"fixed": CAP.tolist(), "roi": roi}, **SMALL).pixels
    assert colour_share(pic, STUDIO_COLORS["roi"], 0.08) > 0.05


def test_bad_constraints_are_refused_with_the_librarys_messages() -> None:
    with pytest.raises(ConstraintError, match="fixed has 1 indices out of range"):
        arap.show(V, F, constraints={"fixed": [len(V)]})
    with pytest.raises(ConstraintError, match="fixed has 1 indices out of range"):
        arap.show(V, F, fixed=[0, len(V)])
    with pytest.raises(ConstraintError, match="not both"):
        arap.show(V, F, constraints={"fixed": [0]}, fixed=[1])
    with pytest.raises(ConstraintError, match="constraints must be"):
        arap.show(V, F, constraints=42)


def test_arrays_results_mesh_objects_and_names_are_taken(tmp_path: Path) -> None:
    trimesh = pytest.importorskip("trimesh")
    from_arrays = arap.show(V, F, **SMALL).pixels
    np.testing.assert_array_equal(arap.show(trimesh.Trimesh(V, F, process=False), **SMALL).pixels, from_arrays)
    np.testing.assert_array_equal(arap.show("sphere:500", **SMALL).pixels, from_arrays)
    arap.save_mesh(tmp_path / "s.obj", V, F)
    np.testing.assert_array_equal(arap.show(tmp_path / "s.obj", **SMALL).pixels, from_arrays)
    Vb, Fb = arap.builtin_mesh("bar")
    top = np.flatnonzero(Vb[:, 1] > 4.7)
    result = arap.ArapSolver(Vb, Fb, np.concatenate([np.flatnonzero(Vb[:, 1] < 0.3), top])).solve(
        np.concatenate([Vb[Vb[:, 1] < 0.3], Vb[top] + [2.0, 0, 0]]), max_iterations=3)
    rest = arap.show(Vb, Fb, **SMALL)
    bent = arap.show(result, Fb, camera=rest.camera)
    assert bent.camera is rest.camera and bent.pixels.shape == rest.pixels.shape
    assert (bent.pixels != rest.pixels).any(axis=2).mean() > 0.01
    with pytest.raises(MeshError, match="ArapResult holds the deformed vertices only"):
        arap.show(result)


def test_per_vertex_and_single_colours() -> None:
    blue = arap.show(V, F, colors="#0000ff", **SMALL).pixels
    assert colour_share(blue, "#0000ff") > 0.2
    per_vertex = np.where((V[:, 0] > 0)[:, None], [255, 0, 0], [0, 255, 0]).astype(np.uint8)
    both = arap.show(V, F, colors=per_vertex, **SMALL).pixels
    assert colour_share(both, "#ff0000") > 0.05 and colour_share(both, "#00ff00") > 0.05
    white = arap.show(V, F, background=(255, 255, 255), **SMALL).pixels
    assert white[0, 0].tolist() == [255, 255, 255]


@pytest.mark.parametrize(("call", "error", "message"), [
    (lambda: arap.show(V, np.array([[0, 1, len(V)]])), MeshError, f"out of range [0, {len(V)})"),
    (lambda: arap.show(V, np.array([[0, -1, 2]])), MeshError, "out of range"),
    (lambda: arap.show(np.zeros((0, 3)), np.zeros((0, 3), int)), MeshError, "the mesh is empty"),
    (lambda: arap.show(V, np.zeros((0, 3), int)), MeshError, "the mesh is empty"),
    (lambda: arap.show(V), MeshError, "F (the triangles) is missing"),
    (lambda: arap.show(V, F[:, :2]), MeshError, "faces must be triangles"),
    (lambda: arap.show(np.column_stack([V, V[:, :1]]), F), MeshError, "vertices must be an (n, 3) array"),
    (lambda: arap.show(np.where(np.arange(len(V))[:, None] == 7, np.nan, V), F), MeshError, "NaN"),
    (lambda: arap.show("no-such-mesh"), MeshError, "neither a built-in mesh"),
    (lambda: arap.show(V, F, width=0), OptionError, "width must be from 1 to 4096 pixels, got 0"),
    (lambda: arap.show(V, F, height=2.5), OptionError, "height must be a whole number of pixels"),
    (lambda: arap.show(V, F, azimuth=float("nan")), OptionError, "azimuth must be a finite number"),
    (lambda: arap.show(V, F, colors=[2.0, 0, 0]), OptionError, "from 0 to 1"),
    (lambda: arap.show(V, F, colors=np.ones((3, 3))), OptionError, "one row per vertex"),
    (lambda: arap.show(V, F, background="#12"), OptionError, "background must be '#rrggbb'"),
    (lambda: arap.show(V, F, camera="front"), OptionError, "camera must be the camera of an earlier picture"),
])
def test_bad_input_raises_the_projects_errors(call: object, error: type, message: str) -> None:
    with pytest.raises(error) as info:
        call()  # type: ignore[operator]
    assert message in str(info.value)
    assert issubclass(error, arap.ArapError)


def test_an_unused_vertex_with_nan_is_left_out() -> None:
    Vn = np.vstack([V, [np.nan, np.nan, np.nan]])
    np.testing.assert_array_equal(arap.show(Vn, F, **SMALL).pixels, arap.show(V, F, **SMALL).pixels)


# ---------------------------------------------------------------------------------------------- the picture
def _unfilter(data: bytes) -> np.ndarray:
    """The pixels of a PNG file written with any of the filters None, Sub, Up, read with zlib only (not the module's
    own decoder)."""
    pos, idat, header = 8, b"", b""
    while pos < len(data):
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind = data[pos + 4:pos + 8]
        if kind == b"IHDR":
            header = data[pos + 8:pos + 8 + length]
        elif kind == b"IDAT":
            idat += data[pos + 8:pos + 8 + length]
        pos += 12 + length
    w, h = int.from_bytes(header[:4], "big"), int.from_bytes(header[4:8], "big")
    assert header[8:] == bytes([8, 2, 0, 0, 0])
    raw = np.frombuffer(zlib.decompress(idat), dtype=np.uint8).reshape(h, 3 * w + 1)
    out = np.zeros((h, 3 * w), dtype=np.int64)
    for i in range(h):
        row = raw[i, 1:].astype(np.int64)
        if raw[i, 0] == 1:
            for j in range(3 * w):
                out[i, j] = (row[j] + (out[i, j - 3] if j >= 3 else 0)) % 256
        else:
            out[i] = (row + (out[i - 1] if raw[i, 0] == 2 and i else 0)) % 256
    return out.reshape(h, w, 3).astype(np.uint8)


def test_the_png_decodes_back_to_the_pixels() -> None:
    pic = arap.show(V, F, width=40, height=30)
    data = pic.png()
    assert data.startswith(SIGNATURE) and pic._repr_png_() == data
    np.testing.assert_array_equal(_unfilter(data), pic.pixels)
    np.testing.assert_array_equal(decode_png(data), pic.pixels)
    noise = np.random.default_rng(0).integers(0, 256, (7, 5, 3), dtype=np.uint8)
    for name in ("none", "sub", "up"):
        encoded = encode_png(noise, filter=name)
        np.testing.assert_array_equal(_unfilter(encoded), noise)
        np.testing.assert_array_equal(decode_png(encoded), noise)
    damaged = bytearray(data)
    damaged[20] ^= 1
    with pytest.raises(arap.ArapError, match="CRC"):
        decode_png(bytes(damaged))


def test_pixels_are_read_only_and_the_picture_knows_its_size() -> None:
    pic = arap.show(V, F, width=33, height=21)
    assert (pic.width, pic.height, repr(pic)) == (33, 21, "Picture(33x21)")
    with pytest.raises(ValueError):
        pic.pixels[0, 0] = 0
    assert "show" in arap.__all__ and "Picture" in arap.__all__ and isinstance(pic, arap.Picture)


def test_save_writes_the_png(tmp_path: Path) -> None:
    pic = arap.show(V, F, **SMALL)
    pic.save(tmp_path / "a.png")
    assert (tmp_path / "a.png").read_bytes() == pic.png()
    (tmp_path / "target.png").write_bytes(b"old")
    (tmp_path / "link.png").symlink_to(tmp_path / "target.png")
    pic.save(tmp_path / "link.png")  # the link is kept, the file it names replaced
    assert (tmp_path / "link.png").is_symlink() and (tmp_path / "target.png").read_bytes() == pic.png()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs (POSIX)")
def test_save_refuses_a_folder_a_fifo_and_a_missing_folder_like_the_io_layer(tmp_path: Path) -> None:
    pic = arap.show(V, F, width=8, height=8)
    os.mkfifo(tmp_path / "fifo.png")
    (tmp_path / "folder.png").mkdir()
    for name, message in [("folder.png", "it is a folder, not a file"),
                          ("fifo.png", "it is a named pipe (FIFO), not a regular file"),
                          ("missing/a.png", "does not exist")]:
        with pytest.raises(SpecialFileError, match=message.replace("(", r"\(").replace(")", r"\)")):
            pic.save(tmp_path / name)
    assert sorted(os.listdir(tmp_path)) == ["fifo.png", "folder.png"]  # no temporary file left
    assert list((tmp_path / "folder.png").iterdir()) == []


def test_the_armadillo_renders_quickly(shared_meshes_dir: Path) -> None:
    import time

    Va, Fa = arap.load_mesh(shared_meshes_dir / "armadillo.obj", repair=False)
    arap.show(Va, Fa, width=64, height=48)
    start = time.perf_counter()
    pic = arap.show(Va, Fa, width=640, height=480)
    seconds = time.perf_counter() - start
    assert seconds < scaled(3.0)  # about 0.2 s on a laptop core: room for a machine running other jobs too
    covered = (pic.pixels != pic.pixels[0, 0]).any(axis=2).mean()
    assert 0.1 < covered < 0.6
