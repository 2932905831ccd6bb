"""Files a mesh file names (glTF buffers and images, OBJ ``mtllib``, MTL textures, PLY ``TextureFile``) are read only
inside the mesh file's own folder: a reference leading elsewhere (absolute, ``..``, percent-encoded ``..``, a
symbolic link pointing out, another URI scheme) is named in a warning and left out, and the file it names never
reaches what is written (a GLB or OBJ + MTL saved, ``arap deform -o``) or what the studio sends (its texture)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import uuid
import warnings
from pathlib import Path

import pytest

from arap.cli import main
from arap.errors import MeshFormatError
from arap.io import load_asset, obj_asset, paths, save_asset
from arap.io.obj_asset import mtl_texture_references
from arap.server.appearance import export_glb, look_from_path
from arap.server.mesh_model import MeshData
from tests.io.asset_models import cube_gltf_document, cube_obj, cube_ply, glb_bytes, png


class Model:
    """A folder ``model/`` for the mesh file, and beside it (outside) ``outside/secret.png``: a PNG image holding a
    unique secret, which must appear in no output."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.folder = root / "model"
        self.folder.mkdir()
        (root / "outside").mkdir()
        self.secret = f"SECRET-{uuid.uuid4().hex}".encode()
        self.marker = root / "outside" / "secret.png"
        self.marker.write_bytes(png(8, 8, 9) + self.secret)
        (self.folder / "link.png").symlink_to(self.marker)  # a link inside the folder pointing out of it
        (self.folder / "sub").mkdir()
        (root / "out").mkdir()

    def references(self) -> dict[str, str]:
        """Ways to name the secret file from inside the folder."""
        return {"absolute": str(self.marker), "dotdot": "../outside/secret.png", "link": "link.png",
                "backslash": "..\\outside\\secret.png", "deep": "sub/../../outside/secret.png"}

    def assert_not_leaked(self) -> None:
        for path in self.root.rglob("*"):
            if path.is_file() and not path.is_symlink() and path.parent.name != "outside":
                assert self.secret not in path.read_bytes(), f"{path} holds the secret"


@pytest.fixture
def model(tmp_path: Path) -> Model:
    return Model(tmp_path)


def _load_warning(path: Path, reference: str) -> object:
    """Load ``path``, checking that a warning names ``reference``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        asset = load_asset(path)
    messages = [str(w.message) for w in caught]
    assert any(repr(reference) in m or reference in m for m in messages), messages
    return asset


def _studio(path: Path) -> tuple[bytes, bytes]:
    """The texture the studio would send for the file at ``path``, and its Export GLB of the mesh moved."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        asset = load_asset(path)
    mesh = MeshData.make("m", asset.vertices, asset.faces, [], None)
    look = look_from_path(path, mesh)
    exported = export_glb("m", mesh.V * 2.0, mesh.F, look)[2]
    return (b"" if look is None else look.texture), exported


def _gltf_with_image(model: Model, uri: str) -> Path:
    document, blob = cube_gltf_document(None)
    document["images"] = [{"uri": uri}]
    document["textures"] = [{"source": 0}]
    path = model.folder / "cube.glb"
    path.write_bytes(glb_bytes(document, blob))
    return path


GLTF_URIS = {"percent": "%2e%2e/outside/secret.png", "percent_slash": "..%2Foutside%2Fsecret.png"}


@pytest.mark.parametrize("kind", ["absolute", "dotdot", "link", "backslash", "deep", "percent", "percent_slash",
                                  "file_uri"])
def test_gltf_image_outside_the_folder_is_left_out(model: Model, kind: str) -> None:
    uri = {**model.references(), **GLTF_URIS, "file_uri": model.marker.as_uri()}[kind]
    path = _gltf_with_image(model, uri)
    asset = _load_warning(path, uri)
    assert asset.textures == {}  # type: ignore[attr-defined]
    save_asset(model.root / "out" / "saved.glb", asset)  # type: ignore[arg-type]
    save_asset(model.root / "out" / "saved.gltf", asset)  # type: ignore[arg-type]
    texture, exported = _studio(path)
    assert texture == b"" and model.secret not in exported
    assert main(["deform", str(path), "-c", str(_constraints(model, 24)), "-o",
                 str(model.root / "out" / "deformed.glb"), "-q"]) == 0
    model.assert_not_leaked()


def test_gltf_image_inside_the_folder_is_read(model: Model) -> None:
    image = png(8, 8, 2)
    (model.folder / "img").mkdir()
    (model.folder / "img" / "a b.png").write_bytes(image)
    (model.folder / "inner.png").symlink_to(model.folder / "img" / "a b.png")  # a link staying inside
    for uri in ("img/a%20b.png", "img/../img/a%20b.png", "inner.png"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            asset = load_asset(_gltf_with_image(model, uri))
        assert list(asset.textures.values()) == [image]


@pytest.mark.parametrize("kind", ["absolute", "dotdot", "link", "percent"])
def test_gltf_buffer_outside_the_folder_is_refused(model: Model, kind: str,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    document, blob = cube_gltf_document(None)
    (model.root / "outside" / "data.bin").write_bytes(blob + model.secret)
    (model.folder / "data.bin").symlink_to(model.root / "outside" / "data.bin")
    uri = {"absolute": str(model.root / "outside" / "data.bin"), "dotdot": "../outside/data.bin",
           "link": "data.bin", "percent": "%2E%2E/outside/data.bin"}[kind]
    document["buffers"][0]["uri"] = uri
    path = model.folder / "cube.gltf"
    path.write_text(json.dumps(document))
    with pytest.raises(MeshFormatError, match=r"buffer 0 .* cannot be read \(it leads outside "):
        load_asset(path)
    out = model.root / "out" / "deformed.glb"
    assert main(["deform", str(path), "-c", str(_constraints(model, 24)), "-o", str(out), "-q"]) == 1
    assert "leads outside " in capsys.readouterr().err
    assert not out.exists()
    model.assert_not_leaked()


def test_gltf_buffer_naming_proc_environ_leaks_nothing(model: Model) -> None:
    """The repro: ``MY_API_KEY=x arap deform evil.gltf -c c.json -o out.glb`` must not copy the environment."""
    document, blob = cube_gltf_document(png(8, 8, 1))
    document["buffers"].append({"uri": "/proc/self/environ", "byteLength": 1})  # merged into the GLB if read
    document["buffers"][0]["uri"] = "evil.bin"
    (model.folder / "evil.bin").write_bytes(blob)
    path = model.folder / "evil.gltf"
    path.write_text(json.dumps(document))
    out = model.root / "out" / "out.glb"
    env = {**os.environ, "MY_API_KEY": model.secret.decode()}
    done = subprocess.run([sys.executable, "-m", "arap.cli", "deform", str(path), "-c", str(_constraints(model, 24)),
                           "-o", str(out), "-q"], env=env, capture_output=True, timeout=300)
    assert done.returncode == 1, done.stderr
    assert b"/proc/self/environ" in done.stderr and b"leads outside " in done.stderr
    assert not out.exists()
    model.assert_not_leaked()


def _constraints(model: Model, n: int) -> Path:
    path = model.root / f"c{n}.json"
    path.write_text(json.dumps({"fixed": [0, 1, 2], "handles": [n - 1], "targets": [[0.0, 0.0, 3.0]]}))
    return path


def _obj(model: Model, mtllib: str, mtl: str | None = None) -> Path:
    path = cube_obj(model.folder)
    text = path.read_text().replace("mtllib cube.mtl", f"mtllib {mtllib}")
    path.write_text(text)
    if mtl is not None:
        (model.folder / "cube.mtl").write_text(mtl)
    return path


@pytest.mark.parametrize("kind", ["absolute", "dotdot", "link", "deep"])
def test_obj_mtllib_outside_the_folder_is_left_out(model: Model, kind: str) -> None:
    mtl = model.root / "outside" / "evil.mtl"
    mtl.write_text(f"newmtl red\nKd 1 0 0\n# {model.secret.decode()}\n")
    (model.folder / "evil_link.mtl").symlink_to(mtl)
    ref = {"absolute": str(mtl), "dotdot": "../outside/evil.mtl", "link": "evil_link.mtl",
           "deep": "sub/../../outside/evil.mtl"}[kind]
    path = _obj(model, ref)
    asset = _load_warning(path, ref)
    assert asset.data.mtl_files == {}  # type: ignore[attr-defined]
    written = save_asset(model.root / "out" / "out.obj", asset)  # type: ignore[arg-type]
    assert not (model.root / "out" / "out.mtl").exists()
    assert [p.name for p in written] == ["out.obj"]
    assert main(["deform", str(path), "-c", str(_constraints(model, 8)), "-o", str(model.root / "out" / "d.obj"),
                 "-q"]) == 0
    assert not (model.root / "out" / "d.mtl").exists()
    model.assert_not_leaked()


@pytest.mark.parametrize("kind", ["absolute", "dotdot", "link", "backslash"])
def test_mtl_texture_outside_the_folder_is_left_out(model: Model, kind: str) -> None:
    ref = model.references()[kind]
    path = _obj(model, "cube.mtl", f"newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 {ref}\n")
    asset = _load_warning(path, ref)
    assert asset.textures == {}  # type: ignore[attr-defined]
    save_asset(model.root / "out" / "out.obj", asset)  # type: ignore[arg-type]
    texture, exported = _studio(path)
    assert texture == b"" and model.secret not in exported
    model.assert_not_leaked()


@pytest.mark.parametrize("kind", ["absolute", "dotdot", "link"])
def test_ply_texture_file_outside_the_folder_is_left_out(model: Model, kind: str) -> None:
    ref = model.references()[kind]
    path = cube_ply(model.folder)
    text = path.read_text()
    assert "comment TextureFile checker.png" in text
    path.write_text(text.replace("comment TextureFile checker.png", f"comment TextureFile {ref}"))
    asset = _load_warning(path, ref)
    assert asset.textures == {}  # type: ignore[attr-defined]
    save_asset(model.root / "out" / "out.ply", asset)  # type: ignore[arg-type]
    texture, exported = _studio(path)
    assert texture == b"" and model.secret not in exported
    model.assert_not_leaked()


def test_a_fifo_named_as_a_texture_is_refused_at_once(model: Model) -> None:
    os.mkfifo(model.folder / "pipe.png")
    path = _obj(model, "cube.mtl", "newmtl red\nmap_Kd pipe.png\n")
    asset = _load_warning(path, "pipe.png")  # would block forever if it were opened for reading
    assert asset.textures == {}  # type: ignore[attr-defined]


def test_map_file_names_keep_their_spaces(model: Model) -> None:
    image = png(8, 8, 1)
    (model.folder / "fuze uv.jpg").write_bytes(image)
    path = _obj(model, "cube.mtl", "newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 -clamp on -bm 0.5 fuze uv.jpg\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        asset = load_asset(path)
    assert asset.textures == {"fuze uv.jpg": image}
    save_asset(model.root / "out" / "out.obj", asset)
    assert (model.root / "out" / "fuze uv.jpg").read_bytes() == image


@pytest.mark.parametrize(("arguments", "name"), [
    ("tex.png", "tex.png"),
    ("fuze uv.jpg", "fuze uv.jpg"),
    ("-s 1 1 1 tex/checker.png", "tex/checker.png"),
    ("-s 2 2 a b.png", "a b.png"),
    ("-o 0.5 -clamp on my texture.png", "my texture.png"),
    ("-bm 1.5 -imfchan l bump map.png  ", "bump map.png"),
    ("-type sphere sky.png", "sky.png"),
    ("-mm 0 1 -texres 512 t.png", "t.png"),
])
def test_map_file_name_is_the_rest_of_the_line_after_the_options(arguments: str, name: str) -> None:
    assert obj_asset.map_file_name(arguments) == name
    assert mtl_texture_references(f"map_Kd {arguments}\n".encode()) == [name]


def test_read_reference_is_the_one_rule(model: Model) -> None:
    read_reference, SpecialFileError = paths.read_reference, paths.SpecialFileError
    (model.folder / "ok.bin").write_bytes(b"fine")
    assert read_reference(model.folder, "ok.bin") == b"fine"
    assert read_reference(model.folder, "./sub/../ok.bin") == b"fine"
    for ref in [*model.references().values(), "/etc/passwd", "/proc/self/environ", "..", "."]:
        with pytest.raises(SpecialFileError):
            read_reference(model.folder, ref)
    with pytest.raises(SpecialFileError, match="more than the 3 accepted"):
        read_reference(model.folder, "ok.bin", max_bytes=3)
    with pytest.raises(FileNotFoundError):
        read_reference(model.folder, "missing.bin")
