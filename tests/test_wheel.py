"""The package as a user gets it: build the sdist and wheel from a clean copy of the checkout, install the wheel
into a fresh virtual environment (core first, then the ``notebook`` extra, then the ``studio`` extra) and use each
install as its documentation shows, without Node.js.

Needs git, npm and the package indexes (PyPI, npm); about one to two minutes. Deselect with ``-m "not packaging"``.
"""

from __future__ import annotations

import json
import os
import queue
import re
import shutil
import subprocess
import sys
import tarfile
import threading
import urllib.request
import venv
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.conftest import REPO_ROOT
from tests.waiting import scaled

# One pytest-xdist worker runs them all (with --dist loadgroup): the module's build and environment are made once.
pytestmark = [pytest.mark.packaging, pytest.mark.slow, pytest.mark.timeout(900), pytest.mark.xdist_group("package")]

STEP_TIMEOUT = 600
"""Seconds for one build or install step on an idle machine, stretched on a loaded one (:func:`tests.waiting.scaled`:
CI builds the package while other jobs run their tests)."""


def _run(args: list[str], cwd: Path, env: dict[str, str] | None = None,
         timeout: float = STEP_TIMEOUT) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=scaled(timeout))
    assert result.returncode == 0, f"{' '.join(args)} failed ({result.returncode}):\n{result.stdout}\n{result.stderr}"
    return result


def _clean_copy(dest: Path) -> None:
    """The checkout's tracked and unignored files (as in the working tree), without builds or node_modules."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=REPO_ROOT,
                            capture_output=True, check=True, timeout=60).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = REPO_ROOT / name
        if source.is_file():
            (dest / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, dest / name)


def _pins(dest: Path, lock: str = "runtime.txt") -> Path:
    """``requirements/LOCK`` as a constraints file (versions and markers, hashes dropped)."""
    text = (REPO_ROOT / "requirements" / lock).read_text()
    pins = re.findall(r"^([A-Za-z0-9_.\-]+==[^\s;\\]+(?: ; [^\\\n]+?)?)[ \\]*$", text, flags=re.MULTILINE)
    assert pins, f"no pins in requirements/{lock}"
    dest.write_text("\n".join(pins) + "\n")
    return dest


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR", "VIRTUAL_ENV")}
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


@pytest.fixture(scope="module")
def dists(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(sdist, wheel) built by ``python -m build`` from a clean copy: sdist first, the wheel from the sdist."""
    if shutil.which("git") is None or shutil.which("npm") is None:
        pytest.skip("building the package needs git and npm")
    pytest.importorskip("build")
    root = tmp_path_factory.mktemp("checkout")
    _clean_copy(root)
    assert not (root / "src" / "arap" / "static").exists() and not (root / "web" / "node_modules").exists()
    result = _run([sys.executable, "-m", "build", "--no-isolation", "--outdir", "dist", "."], cwd=root, env=_env())
    log = result.stdout + result.stderr
    assert "npm ci" in log and "npm run --silent build" in log  # the client was built from web/ ...
    assert "studio client already built and up to date" in log  # ... once: the wheel reused the sdist's
    (sdist,) = (root / "dist").glob("arap-*.tar.gz")
    (wheel,) = (root / "dist").glob("arap-*.whl")
    return sdist, wheel


@pytest.fixture(scope="module")
def fresh_venv(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A new virtual environment without arap or any of its dependencies."""
    path = tmp_path_factory.mktemp("venv")
    venv.create(path, with_pip=True, clear=True)
    return path / "bin"


def test_sdist_carries_web_sources_and_the_built_client(dists: tuple[Path, Path]) -> None:
    sdist, _ = dists
    with tarfile.open(sdist) as tar:
        names = {name.split("/", 1)[1] for name in tar.getnames() if "/" in name}
    for expected in ("web/package.json", "web/package-lock.json", "web/vite.config.js", "web/src/main.js",
                     "web/index.html", "setup.py", "LICENSE", "src/arap/static/index.html",
                     "src/arap/static/.source-hash"):
        assert expected in names, expected
    assert not any("node_modules" in name for name in names)


def test_wheel_carries_the_client_and_right_metadata(dists: tuple[Path, Path]) -> None:
    _, wheel = dists
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
        metadata = zf.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    assert "arap/static/index.html" in names and "arap/py.typed" in names
    scripts = [n for n in names if re.fullmatch(r"arap/static/assets/[^/]+\.js", n)]
    assert scripts, sorted(names)
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)
    assert not any(n.startswith(("web/", "tests/")) for n in names)
    requires = re.findall(r"^Requires-Dist: (.+)$", metadata, flags=re.MULTILINE)
    core = [r for r in requires if "extra ==" not in r]
    studio = [r for r in requires if 'extra == "studio"' in r]
    notebook = [r for r in requires if 'extra == "notebook"' in r]
    assert {re.split(r"[<>=\[ ;]", r)[0] for r in core} == {"numpy", "scipy", "numba", "trimesh", "cholespy", "tqdm"}
    assert {re.split(r"[<>=\[ ;]", r)[0] for r in studio} == {"starlette", "uvicorn", "websockets"}
    assert {re.split(r"[<>=\[ ;]", r)[0] for r in notebook} == {"anywidget"}
    assert "License-Expression: MIT" in metadata


def _read_lines(stream: object, lines: queue.Queue[str]) -> None:
    for line in stream:  # type: ignore[attr-defined]
        lines.put(line)


@contextmanager
def _studio(bin_dir: Path, cwd: Path) -> Iterator[tuple[str, queue.Queue[str]]]:
    """Run ``arap studio --port 0`` from the environment; yields its URL and its stderr lines."""
    process = subprocess.Popen([str(bin_dir / "arap"), "studio", "bar", "--port", "0"], cwd=cwd, env=_env(),
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out: queue.Queue[str] = queue.Queue()
    err: queue.Queue[str] = queue.Queue()
    for stream, lines in ((process.stdout, out), (process.stderr, err)):
        threading.Thread(target=_read_lines, args=(stream, lines), daemon=True).start()
    try:
        try:
            first = out.get(timeout=120)
        except queue.Empty:
            pytest.fail("arap studio printed no URL within 120 s")
        match = re.search(r"(http://\S+/)", first)
        assert match, first
        yield match.group(1), err
    finally:
        process.terminate()
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=30)


NOTEBOOK_WIDGET = """
import importlib.util
import threading

import arap
from arap.jupyter_widget import OPEN_MESSAGE

assert importlib.util.find_spec("starlette") is None and importlib.util.find_spec("uvicorn") is None
V, F = arap.builtin_mesh("bar")
w = arap.widget(V, F, name="bar")  # as docs/notebook.md shows it, here without a kernel: no view, no comm
sent, greeted = [], threading.Event()
def send(content, buffers=None):
    if "widget" in content:  # the widget's own note: a picture while the session is prepared
        return
    sent.append(content.get("type"))
    if content.get("type") == "state":
        greeted.set()
w.send = send  # what a view would get through the comm
w._receive(OPEN_MESSAGE, [])
assert greeted.wait(120), sent
assert w.vertices.shape == V.shape and w.constraints.fixed.size == 0
w.stop()
print("greeted:", sent[:3], repr(w))
try:
    arap.studio(V, F, show=False)  # outside a kernel: the server, which the notebook extra does not bring
except arap.ArapError as exc:
    print("server:", exc)
"""


def test_fresh_install_core_then_notebook_then_studio(dists: tuple[Path, Path], fresh_venv: Path,
                                                      tmp_path: Path) -> None:
    _, wheel = dists
    pins = _pins(tmp_path / "pins.txt")
    pip = [str(fresh_venv / "python"), "-m", "pip", "install", "-q", "--disable-pip-version-check", "-c", str(pins)]

    # The core install: the library and every command but the studio.
    _run([*pip, str(wheel)], cwd=tmp_path, env=_env())
    arap = str(fresh_venv / "arap")
    info = json.loads(_run([arap, "info", "bar", "--json"], cwd=tmp_path, env=_env()).stdout)
    assert info["n_vertices"] == 4314 and info["ready"] is True
    missing = subprocess.run([arap, "studio", "--port", "0"], cwd=tmp_path, env=_env(), capture_output=True,
                             text=True, timeout=120)
    assert missing.returncode == 2 and "pip install 'arap[studio]'" in missing.stderr

    # Compiled kernels are cached inside the installed package: only the first run compiles.
    bench = [arap, "bench", "sphere:500", "-n", "1", "-r", "1", "--json"]
    first = json.loads(_run(bench, cwd=tmp_path, env=_env()).stdout)["kernels"]
    second = json.loads(_run(bench, cwd=tmp_path, env=_env()).stdout)["kernels"]
    assert first["compiled"] is True and second["compiled"] is False
    assert "site-packages" in first["cache_dir"] and first["cache_dir"] == second["cache_dir"]

    # The notebook extra alone: the widget (anywidget) without the server's stack.
    notebook_pins = _pins(tmp_path / "notebook-pins.txt", "lock.txt")
    _run([*pip[:-2], "-c", str(notebook_pins), f"{wheel}[notebook]"], cwd=tmp_path, env=_env())
    widget = _run([str(fresh_venv / "python"), "-c", NOTEBOOK_WIDGET], cwd=tmp_path, env=_env()).stdout
    assert "greeted: ['welcome', 'mesh', 'state'] <arap.StudioWidget stopped, 4314 vertices>" in widget, widget
    assert 'server: the studio needs its server stack: pip install "arap[studio]"' in widget, widget

    # The studio extra, then the studio from the wheel alone (no Node.js, no checkout).
    _run([*pip, f"{wheel}[studio]"], cwd=tmp_path, env=_env())
    with _studio(fresh_venv, tmp_path) as (url, err):
        with urllib.request.urlopen(url, timeout=30) as response:
            assert response.status == 200
            page = response.read().decode()
        script = re.search(r'<script[^>]+src="\.?/?(assets/[^"]+\.js)"', page)
        assert script, page[:500]
        with urllib.request.urlopen(url + script.group(1), timeout=30) as response:
            assert response.status == 200 and "javascript" in response.headers["Content-Type"]
            assert len(response.read()) > 100_000  # the bundled client with three.js
        from websockets.sync.client import connect

        with connect(url.replace("http://", "ws://") + "ws", open_timeout=30) as ws:
            # while a fresh install compiles its kernels, the server says how far it is (preparing), then greets
            welcome = json.loads(ws.recv(timeout=scaled(300)))
            while welcome["type"] == "preparing":
                welcome = json.loads(ws.recv(timeout=scaled(300)))
        assert welcome["type"] == "welcome" and welcome["protocol"] >= 1
        lines = []
        while not err.empty():
            lines.append(err.get_nowait())
        assert not any("client is missing" in line for line in lines), lines
