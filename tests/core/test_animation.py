"""Keyframe animation: frames at the keys are the solver's shapes, poses between them interpolate as documented,
and the written files hold every frame."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh

import arap
from arap.animation import Keyframes, animate, frame_paths, frame_times, load_keyframes, save_animation
from arap.errors import ConstraintError, OptionError


def _bar() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    V, F = arap.builtin_mesh("bar")
    y = V[:, 1]
    return V, F, np.flatnonzero(y < 0.2), np.flatnonzero(y > 4.8)


def _rotation_z(angle: float, pivot: np.ndarray) -> list[list[float]]:
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = pivot - R @ pivot
    return T.tolist()


def test_frames_at_the_keys_are_the_solvers_shapes_and_poses_between_are_linear() -> None:
    V, F, fixed, top = _bar()
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    poses = [V[top], V[top] + [0.8, 0.0, 0.0], V[top] + [-0.5, 0.05, 0.4]]  # no compression: one minimum
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": t, "targets": p.tolist()} for t, p in zip([0.0, 0.4, 1.0], poses, strict=True)]}
    keys = Keyframes.from_json(doc, V)
    np.testing.assert_allclose(keys.handle_targets(0.2), (poses[0] + poses[1]) / 2, atol=1e-12)
    np.testing.assert_allclose(keys.handle_targets(0.7), (poses[1] + poses[2]) / 2, atol=1e-12)
    np.testing.assert_array_equal(keys.handle_targets(-1.0), poses[0])  # held before the first key
    np.testing.assert_array_equal(keys.handle_targets(9.0), poses[2])  # and after the last
    anim = animate(V, F, keys, fps=10)
    np.testing.assert_allclose(anim.times, np.arange(11) / 10, atol=1e-12)
    assert anim.converged.all() and anim.vertices.shape == (11, len(V), 3)
    cold = arap.ArapSolver(V, F, np.concatenate([fixed, top]))
    for t, pose in ((0.4, poses[1]), (1.0, poses[2])):
        k = int(np.argmin(np.abs(anim.times - t)))
        expected = cold.solve(np.concatenate([V[fixed], pose]), initial="auto").vertices
        assert np.abs(anim.vertices[k] - expected).max() <= 1e-6 * diag
    np.testing.assert_allclose(anim.vertices[5][top], keys.handle_targets(0.5), atol=1e-12)  # handles on target


def test_transform_keyframes_turn_about_the_group_pivot() -> None:
    V, _F, fixed, top = _bar()
    pivot = V[top].mean(axis=0)
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()]},
                         {"time": 2.0, "transforms": [_rotation_z(np.pi / 2, pivot)]}]}
    keys = load_keyframes(doc, V)
    half = keys.handle_targets(1.0)
    rotated = (V[top] - pivot) @ np.array(_rotation_z(np.pi / 4, np.zeros(3)))[:3, :3].T + pivot
    np.testing.assert_allclose(half, rotated, atol=1e-12)
    # a linear blend of the two poses would pull the handles towards the pivot: the turn keeps their distances
    np.testing.assert_allclose(np.linalg.norm(half - pivot, axis=1), np.linalg.norm(V[top] - pivot, axis=1))


def test_a_glb_animation_holds_every_frame(tmp_path: Path) -> None:
    V, F, fixed, top = _bar()
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                         {"time": 0.3, "targets": (V[top] + [0.6, 0.0, 0.0]).tolist()}]}
    anim = animate(V, F, doc, fps=10)
    out = tmp_path / "bend.glb"
    assert save_animation(out, F, anim) == [out]
    data = out.read_bytes()
    magic, version, total = struct.unpack("<4sII", data[:12])
    assert (magic, version, total) == (b"glTF", 2, len(data))
    n_json = struct.unpack("<I", data[12:16])[0]
    gltf = json.loads(data[20:20 + n_json])
    binary = data[20 + n_json + 8:]
    primitive = gltf["meshes"][0]["primitives"][0]
    assert len(primitive["targets"]) == len(anim.times) == 4

    def accessor(i: int, width: int) -> np.ndarray:
        a = gltf["accessors"][i]
        view = gltf["bufferViews"][a["bufferView"]]
        dtype = "<f4" if a["componentType"] == 5126 else "<u4"
        raw = np.frombuffer(binary, dtype=dtype, count=a["count"] * width, offset=view["byteOffset"])
        return raw.reshape(a["count"], width) if width > 1 else raw

    base = accessor(primitive["attributes"]["POSITION"], 3)
    for k, target in enumerate(primitive["targets"]):
        frame = base + accessor(target["POSITION"], 3)
        np.testing.assert_allclose(frame, anim.vertices[k], atol=1e-5)
    sampler = gltf["animations"][0]["samplers"][0]
    np.testing.assert_allclose(accessor(sampler["input"], 1), anim.times - anim.times[0], atol=1e-6)
    np.testing.assert_array_equal(accessor(sampler["output"], 1).reshape(4, 4), np.eye(4))
    loaded = trimesh.load(out, force="mesh")
    np.testing.assert_allclose(loaded.vertices, anim.vertices[0], atol=1e-5)


def test_numbered_frames(tmp_path: Path) -> None:
    V, F, fixed, top = _bar()
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                         {"time": 0.2, "targets": (V[top] + [0.3, 0.0, 0.0]).tolist()}]}
    anim = animate(V, F, doc, fps=10)
    paths = save_animation(tmp_path / "frame_##.ply", F, anim)
    assert [p.name for p in paths] == ["frame_00.ply", "frame_01.ply", "frame_02.ply"]
    for p, frame in zip(paths, anim.vertices, strict=True):
        np.testing.assert_allclose(arap.load_mesh(p)[0], frame)
    assert [p.name for p in frame_paths("a#/f#.obj", 12)][-1] == "f11.obj"
    with pytest.raises(OptionError, match="####"):
        save_animation(tmp_path / "frames.obj", F, anim)


@pytest.mark.parametrize(("change", "words"), [
    (lambda d: d["keyframes"].append({"time": 0.0, "targets": d["keyframes"][0]["targets"]}), "not after"),
    (lambda d: d["keyframes"][0].update(transforms=[np.eye(4).tolist()]), "not both"),
    (lambda d: d["keyframes"][0].update(targets=[[0, 0, 0]]), "keyframes\\[0\\]"),
    (lambda d: d["keyframes"].__setitem__(0, {"time": 0.0, "transforms": [np.diag([-1, 1, 1, 1]).tolist()]}),
     "mirrors"),
    (lambda d: d["keyframes"][0].update(time=float("nan")), "finite"),
    (lambda d: d.__setitem__("keyframes", []), "needs \"keyframes\""),
    (lambda d: d["keyframes"][0].update(speed=2), "unknown keys"),
])
def test_bad_keyframes_are_refused_by_name(change: object, words: str) -> None:
    V, _F, fixed, top = _bar()
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()}]}
    change(doc)  # type: ignore[operator]
    with pytest.raises(ConstraintError, match=words):
        load_keyframes(doc, V)


def test_frame_rate_is_checked() -> None:
    V, _F, fixed, top = _bar()
    keys = load_keyframes({"fixed": fixed.tolist(), "handles": top.tolist(),
                           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                                         {"time": 0.25, "targets": V[top].tolist()}]}, V)
    np.testing.assert_allclose(frame_times(keys, 10), [0.0, 0.1, 0.2, 0.25])  # the last key is a frame
    for bad in (0, -1, float("inf"), True):
        with pytest.raises(OptionError, match="fps"):
            frame_times(keys, bad)  # type: ignore[arg-type]
    with pytest.raises(OptionError, match="more than"):
        frame_times(keys, 1e9)


def test_arap_animate_writes_the_frames_the_library_solves(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from arap.cli import main

    V, F, fixed, top = _bar()
    pivot = V[top].mean(axis=0)
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()]},
                         {"time": 0.3, "transforms": [_rotation_z(0.6, pivot)]}]}
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps(doc))
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "f_###.obj"), "--fps", "10"]) == 0
    err = capsys.readouterr().err
    assert "4 frames solved" in err and "frame 4/4" in err
    expected = animate(V, F, doc, fps=10, exact=False)  # arap animate's default
    for k in range(4):
        np.testing.assert_allclose(arap.load_mesh(tmp_path / f"f_{k:03d}.obj")[0], expected.vertices[k], atol=1e-9)
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "a.glb"), "-q"]) == 0
    assert (tmp_path / "a.glb").read_bytes()[:4] == b"glTF"
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "frames.obj")]) == 1
    assert "####" in capsys.readouterr().err
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "f_#.obj"), "--fps", "0"]) == 1
    assert "fps must be a positive number" in capsys.readouterr().err


def _turn_and_back(V: np.ndarray, seconds: float) -> dict[str, object]:
    """The lowest 10% of the vertices held, the highest 10% turned 60° about a horizontal axis and back."""
    y = V[:, 1]
    fixed, top = np.flatnonzero(y <= np.quantile(y, 0.1)), np.flatnonzero(y >= np.quantile(y, 0.9))
    pivot = V[top].mean(axis=0)
    a = np.radians(60.0)
    R = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    turned = np.eye(4)
    turned[:3, :3], turned[:3, 3] = R, pivot - R @ pivot
    return {"fixed": fixed.tolist(), "handles": top.tolist(),
            "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()]},
                          {"time": seconds / 2, "transforms": [turned.tolist()]},
                          {"time": seconds, "transforms": [np.eye(4).tolist()]}]}


def _each_to_convergence(V: np.ndarray, F: np.ndarray, doc: dict[str, object], fps: float) -> np.ndarray:
    """Every frame solved to the default tolerance, each from the previous one (a plain loop over the solver)."""
    keys = load_keyframes(doc, V)
    c = keys.constraints
    solver = arap.ArapSolver(V, F, c.constrained)
    frames = []
    for t in frame_times(keys, fps):
        result = solver.solve(np.concatenate([V[c.fixed], keys.handle_targets(float(t))]))
        assert result.converged
        frames.append(result.vertices)
    return np.array(frames)


def test_frames_between_keys_are_within_the_stated_distance_of_converged_frames() -> None:
    from arap.animation import FRAME_TOLERANCE

    V, F = arap.builtin_mesh("cactus")
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    doc = _turn_and_back(V, 1.0)
    exact = animate(V, F, doc, fps=10)  # the library's default
    fast = animate(V, F, doc, fps=10, exact=False)
    assert fast.at_key is not None and fast.at_key.tolist() == [True] + [False] * 4 + [True] + [False] * 4 + [True]
    assert exact.converged.all() and fast.converged.all()
    np.testing.assert_allclose(exact.vertices, _each_to_convergence(V, F, doc, 10), atol=1e-9 * diag)
    distance = np.linalg.norm(fast.vertices - exact.vertices, axis=2).max(axis=1) / diag
    assert distance.max() <= 1e-3, distance  # the module's stated bound
    assert distance[fast.at_key].max() <= 1e-6  # the keyframes are converged
    assert fast.iterations[~fast.at_key].sum() < 0.6 * exact.iterations[~exact.at_key].sum()
    with pytest.raises(OptionError, match="frame_tolerance"):
        animate(V, F, doc, fps=10, exact=False, frame_tolerance=-1.0)
    loose = animate(V, F, doc, fps=10, exact=False, frame_tolerance=10 * FRAME_TOLERANCE)
    assert loose.iterations[~loose.at_key].sum() < fast.iterations[~fast.at_key].sum()


def test_arap_animate_estimates_its_time_and_exact_converges_every_frame(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from arap.cli import main

    V, F = arap.builtin_mesh("bar")
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    doc = _turn_and_back(V, 0.8)
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps(doc))
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "f_##.ply"), "--fps", "10"]) == 0
    err = capsys.readouterr().err
    assert "expected time for the 9 frames: about" in err and "left" in err
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "e_##.ply"), "--fps", "10", "--exact"]) == 0
    assert "every frame to convergence" in capsys.readouterr().err
    converged = _each_to_convergence(V, F, doc, 10)
    fast = np.array([arap.load_mesh(tmp_path / f"f_{k:02d}.ply")[0] for k in range(9)])
    exact = np.array([arap.load_mesh(tmp_path / f"e_{k:02d}.ply")[0] for k in range(9)])
    np.testing.assert_allclose(exact, converged, atol=1e-9 * diag)
    assert np.linalg.norm(fast - converged, axis=2).max() <= 1e-3 * diag


def _turned_shape(V: np.ndarray, F: np.ndarray, fixed: np.ndarray, top: np.ndarray,
                  angle: float) -> tuple[np.ndarray, list[list[float]]]:
    """The shape reached by turning the top of the bar about z in ten steps (as a drag does), and the last turn."""
    pivot = V[top].mean(axis=0)
    solver = arap.ArapSolver(V, F, np.concatenate([fixed, top]))
    for a in np.linspace(0.0, angle, 10)[1:]:
        R = np.array(_rotation_z(a, pivot))
        shape = solver.solve(np.concatenate([V[fixed], V[top] @ R[:3, :3].T + R[:3, 3]])).vertices
    return shape, _rotation_z(angle, pivot)


def test_a_keyed_shape_is_the_frame_at_its_key_and_the_start_of_the_next() -> None:
    V, F, fixed, top = _bar()
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    shape, turn = _turned_shape(V, F, fixed, top, 0.75 * np.pi)
    pivot = V[top].mean(axis=0)
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()]}, {"time": 1.0, "transforms": [turn]},
                         {"time": 1.2, "transforms": [_rotation_z(0.8 * np.pi, pivot)]}]}
    again = animate(V, F, doc, fps=5)  # the pose solved again from another path: another minimum
    assert np.abs(again.vertices[5] - shape).max() > 0.01 * diag
    doc["keyframes"][1]["shape"] = shape.tolist()  # type: ignore[index]
    anim = animate(V, F, doc, fps=5)
    assert np.abs(anim.vertices[5] - shape).max() <= 1e-9 * diag
    assert anim.at_key is not None and anim.at_key[5] and anim.converged.all()
    # the frame after the key starts from the keyed shape
    keys = load_keyframes(doc, V)
    from_shape = arap.ArapSolver(V, F, np.concatenate([fixed, top])).solve(
        np.concatenate([V[fixed], keys.handle_targets(1.2)]), initial=shape).vertices
    assert np.abs(anim.vertices[6] - from_shape).max() <= 1e-5 * diag
    doc["keyframes"][1]["shape"] = (shape + np.array([0.0, 0.0, 0.01])).tolist()  # type: ignore[index]
    with pytest.raises(ConstraintError, match="shape puts a handle"):
        load_keyframes(doc, V)
    doc["keyframes"][1]["shape"] = shape[:-1].tolist()  # type: ignore[index]
    with pytest.raises(ConstraintError, match="one \\[x, y, z\\] per vertex"):
        load_keyframes(doc, V)


def test_easing_changes_the_pace_between_keys_not_the_path() -> None:
    V, _F, fixed, top = _bar()
    shift = np.array([0.8, 0.0, 0.0])
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist(), "easing": "ease-in-out"},
                         {"time": 1.0, "targets": (V[top] + shift).tolist(), "easing": "linear"},
                         {"time": 2.0, "targets": V[top].tolist()}]}
    keys = load_keyframes(doc, V)
    np.testing.assert_allclose(keys.handle_targets(0.25), V[top] + 0.15625 * shift, atol=1e-12)  # s² (3 - 2 s)
    np.testing.assert_allclose(keys.handle_targets(0.5), V[top] + 0.5 * shift, atol=1e-12)
    np.testing.assert_allclose(keys.handle_targets(1.25), V[top] + 0.75 * shift, atol=1e-12)  # linear after key 2
    assert keys.keys[0].easing == "ease-in-out" and keys.keys[2].easing == "linear"
    doc["keyframes"][0]["easing"] = "bounce"  # type: ignore[index]
    with pytest.raises(ConstraintError, match="easing must be one of"):
        load_keyframes(doc, V)


def test_point_handles_move_with_the_keyframes() -> None:
    V, F, fixed, top = _bar()
    face = int(np.flatnonzero(V[F].mean(axis=1)[:, 1] > 4.0)[0])  # a triangle near the top
    bary = [0.2, 0.3, 0.5]
    start = np.asarray(bary) @ V[F[face]]
    right = np.array([1.0, 0.0, 0.0])
    doc = {"version": 2, "fixed": fixed.tolist(), "handles": top.tolist(),
           "points": [{"face": face, "barycentric": bary, "target": start.tolist()}],
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                         {"time": 0.4, "targets": V[top].tolist(), "point_targets": [(start + 0.5 * right).tolist()]},
                         {"time": 0.6, "targets": V[top].tolist()}]}
    keys = load_keyframes(doc, V, len(F))
    np.testing.assert_allclose(keys.point_targets(0.0), [start])  # the point's own target before any keyframe
    np.testing.assert_allclose(keys.point_targets(0.2), [start + 0.25 * right], atol=1e-12)
    np.testing.assert_allclose(keys.point_targets(0.6), [start + 0.5 * right], atol=1e-12)  # held after
    anim = animate(V, F, doc, fps=10)
    moved = np.asarray(bary) @ anim.vertices[:, F[face]]  # (frames, 3): where the point is in each frame
    np.testing.assert_allclose(moved[2], start + 0.25 * right, atol=1e-6)
    np.testing.assert_allclose(moved[4], start + 0.5 * right, atol=1e-6)
    del doc["points"]
    with pytest.raises(ConstraintError, match="no point handles"):
        load_keyframes(doc, V, len(F))


def test_the_glb_has_the_normals_of_every_frame() -> None:
    from arap.io.animated_gltf import animation_glb
    from arap.meshes._geometry import vertex_normals

    V, F, fixed, top = _bar()
    doc = {"fixed": fixed.tolist(), "handles": top.tolist(),
           "keyframes": [{"time": 0.0, "targets": V[top].tolist()},
                         {"time": 0.2, "targets": (V[top] + [2.0, 0.0, 0.0]).tolist()}]}
    anim = animate(V, F, doc, fps=10)
    data = animation_glb(F, anim.times, anim.vertices)
    n_json = struct.unpack("<I", data[12:16])[0]
    gltf = json.loads(data[20:20 + n_json])
    binary = data[20 + n_json + 8:]
    primitive = gltf["meshes"][0]["primitives"][0]

    def vec3(i: int) -> np.ndarray:
        a = gltf["accessors"][i]
        assert (a["type"], a["componentType"], a["count"]) == ("VEC3", 5126, len(V))
        view = gltf["bufferViews"][a["bufferView"]]
        assert view["byteOffset"] % 4 == 0 and view["byteLength"] == 12 * len(V) and view["target"] == 34962
        return np.frombuffer(binary, dtype="<f4", count=3 * len(V), offset=view["byteOffset"]).reshape(-1, 3)

    base = vec3(primitive["attributes"]["NORMAL"])
    np.testing.assert_allclose(np.linalg.norm(base, axis=1), 1.0, atol=1e-6)
    assert all(set(t) == {"POSITION", "NORMAL"} for t in primitive["targets"])
    for k, target in enumerate(primitive["targets"]):
        np.testing.assert_allclose(base + vec3(target["NORMAL"]), vertex_normals(anim.vertices[k], F), atol=1e-5)
    bent = base + vec3(primitive["targets"][-1]["NORMAL"])
    assert np.abs(bent - base).max() > 0.1  # the bend turns the normals


def test_arap_animate_reads_shapes_easings_and_point_targets(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    from arap.cli import main
    from tests.animated_glb import glb_frames

    V, F, fixed, top = _bar()
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    shape, turn = _turned_shape(V, F, fixed, top, 0.75 * np.pi)
    face = int(np.flatnonzero(V[F].mean(axis=1)[:, 1] > 3.0)[0])
    third = np.full(3, 1 / 3)
    start = third @ V[F[face]]
    doc = {"version": 2, "fixed": fixed.tolist(), "handles": top.tolist(),
           "points": [{"face": face, "barycentric": third.tolist(), "target": start.tolist(), "weight": 10.0}],
           "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()], "easing": "ease-in-out"},
                         {"time": 0.4, "transforms": [turn], "shape": shape.tolist(),
                          "point_targets": [(shape[F[face]].T @ third).tolist()]}]}
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps(doc))
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "a.glb"), "--fps", "10", "-q"]) == 0
    _, frames = glb_frames((tmp_path / "a.glb").read_bytes())
    expected = animate(V, F, doc, fps=10, exact=False)
    np.testing.assert_allclose(frames, expected.vertices, atol=1e-5 * diag)
    assert np.abs(frames[-1] - shape).max() <= 1e-6 * diag  # the keyed shape (float32 in the file)
    doc["keyframes"][0]["easing"] = "smooth"  # type: ignore[index]
    keys.write_text(json.dumps(doc))
    assert main(["animate", "bar", "-k", str(keys), "-o", str(tmp_path / "b.glb")]) == 1
    err = capsys.readouterr().err
    assert "easing must be one of" in err and len(err.strip().splitlines()) == 1 and not (tmp_path / "b.glb").exists()
