"""Fixtures of the browser tests: the real studio server on a free local port, headless Chromium (the system's,
through Playwright) and a page connected to its own studio session."""

from __future__ import annotations

import base64
import os
import shutil
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import uvicorn
from playwright.sync_api import Browser, ConsoleMessage, Frame, Page, Playwright, expect, sync_playwright
from playwright.sync_api import TimeoutError as PlaywrightTimeoutError

from arap.batching.locks import output_lock
from arap.server import bind_socket, create_app, studio_url
from arap.server.app import frame_limit
from arap.server.client_files import CLIENT_ENV
from arap.server.runner import websocket_protocol
from tests.waiting import scaled_ms, wait_until

REPO = Path(__file__).resolve().parents[2]
WEB = REPO / "web"
E2E_CLIENT = REPO / "build" / "studio-e2e"
"""The client with the test hook (``window.__arap``) that these tests read: ``npm run build:e2e``, served in place of
the package's (which has no hook) through :data:`arap.server.client_files.CLIENT_ENV`."""
CLIENT_SOURCES = ("src", "index.html", "vite.config.js", "package.json")
"""What the client is built from, in ``web/``: the test build is made again when any is newer."""
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
MAX_UPLOAD_BYTES = 256 * 1024
"""Upload cap of the test server (small, so that the oversized-upload test needs only a modest file)."""
VIEWPORT = {"width": 1280, "height": 800}
DEFAULT_WAIT_SECONDS = 30.0
"""Playwright's own default deadline (actions, waits without one), before :func:`tests.waiting.scaled` stretches it."""
EXPECT_SECONDS = 5.0
"""Playwright's default deadline of an ``expect`` assertion, before it is stretched likewise."""


def _client_built() -> bool:
    """Whether the test build is there and newer than every source of the client."""
    built = E2E_CLIENT / "index.html"
    if not (built.is_file() and (E2E_CLIENT / "widget.js").is_file()):
        return False
    sources = [p for name in CLIENT_SOURCES for p in ((WEB / name).rglob("*") if (WEB / name).is_dir()
                                                       else [WEB / name]) if p.is_file()]
    return all(p.stat().st_mtime <= built.stat().st_mtime for p in sources)


def _build_client() -> str | None:
    """Build the tests' web client when it is missing or older than its sources; the reason it cannot be built,
    or None. Several test processes (pytest-xdist's workers) may ask at once: one builds while the others wait for
    it (a lock beside the build), then find the build fresh."""
    if _client_built():
        return None
    E2E_CLIENT.parent.mkdir(parents=True, exist_ok=True)
    with output_lock(E2E_CLIENT):
        return None if _client_built() else _build_client_now()


def _build_client_now() -> str | None:
    """Build the tests' web client (:func:`_build_client` holds the lock)."""
    npm = shutil.which("npm")
    if npm is None or not (WEB / "package.json").is_file():
        return "the web client's test build is missing or stale (build/studio-e2e) and npm is not available to build it"
    steps = [[npm, "ci", "--no-audit", "--no-fund"]] if not (WEB / "node_modules").is_dir() else []
    steps.append([npm, "run", "build:e2e"])
    for cmd in steps:
        done = subprocess.run(cmd, cwd=WEB, capture_output=True, text=True, timeout=600, check=False)
        if done.returncode != 0:
            return f"building the web client failed ({' '.join(cmd[1:])}): {done.stderr[-400:]}"
    return None if _client_built() else "the web client's test build did not produce build/studio-e2e/index.html"


@pytest.fixture(scope="session", autouse=True)
def e2e_client() -> Iterator[Path]:
    """Every studio these tests start (in this process or in a child) serves the test build, which has the hook."""
    reason = _build_client()
    if reason is not None:
        pytest.skip(reason)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(CLIENT_ENV, str(E2E_CLIENT))
        yield E2E_CLIENT


class _ServerThread(threading.Thread):
    """uvicorn serving the studio app on an already bound socket, in a daemon thread (``port`` 0 picks a free
    port; ``options``: more arguments of ``create_app``, such as ``max_sessions`` or ``default_mesh``)."""

    def __init__(self, port: int = 0, **options: Any) -> None:
        super().__init__(daemon=True, name="studio-server")
        self.options = options
        app = create_app(max_upload_bytes=MAX_UPLOAD_BYTES, **{"default_mesh": None, **options})
        self.sock = bind_socket("127.0.0.1", port)
        self.port = int(self.sock.getsockname()[1])
        self.url = studio_url("127.0.0.1", self.sock.getsockname()[1])
        config = uvicorn.Config(app, log_level="warning", ws=websocket_protocol(), ws_per_message_deflate=False,
                                ws_max_size=frame_limit(MAX_UPLOAD_BYTES), lifespan="off")
        self.server = uvicorn.Server(config)

    def run(self) -> None:
        self.server.run(sockets=[self.sock])

    def wait_started(self, timeout: float = 30.0) -> None:
        def started() -> bool:
            if not self.is_alive():
                raise RuntimeError("the studio server did not start")
            return bool(self.server.started)

        wait_until(started, timeout, "the studio server to start")

    def stop(self) -> None:
        self.server.should_exit = True
        self.join(timeout=10)
        self.sock.close()

    def restarted(self) -> _ServerThread:
        """Stop this server and start a new one on the same port (its sessions are gone)."""
        self.stop()
        again = _ServerThread(self.port, **self.options)
        again.start()
        again.wait_started()
        return again


@contextmanager
def page_on_server(browser: Browser, server: _ServerThread) -> Iterator[Page]:
    """A page of ``server``, which is started here and stopped after (e.g. one started with a mesh of its own,
    ``_ServerThread(default_mesh=...)``), once the page is ready."""
    server.start()
    try:
        server.wait_started()
        context = browser.new_context(viewport=VIEWPORT)
        try:
            page = context.new_page()
            page.goto(server.url)
            wait_ready(page)
            yield page
        finally:
            context.close()
    finally:
        server.stop()


@pytest.fixture(scope="session")
def server_url() -> Iterator[str]:
    """URL of a studio server for the whole test session (each page opens its own editing session)."""
    server = _ServerThread()
    server.start()
    server.wait_started()
    yield server.url
    server.stop()


@pytest.fixture
def own_server() -> Iterator[list[_ServerThread]]:
    """A studio server for one test, which may restart it: ``servers[-1]`` is the one running, append the result
    of :meth:`_ServerThread.restarted`; all are stopped at the end."""
    reason = _build_client()
    if reason is not None:
        pytest.skip(reason)
    servers = [_ServerThread()]
    servers[0].start()
    servers[0].wait_started()
    yield servers
    for server in servers:
        server.stop()


@pytest.fixture(scope="session")
def pw() -> Iterator[Playwright]:
    with sync_playwright() as p:
        yield p


@pytest.fixture(scope="session")
def browser(pw: Playwright, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Browser]:
    """Headless Chromium from the system (Debian's package; `./dev test` installs it)."""
    if not CHROMIUM.is_file():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    b = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS,
                           downloads_path=tmp_path_factory.mktemp("downloads"))
    # a loaded machine: slower, not failing (every context's default deadline, as it is made; every expect's, see
    # scaled_expect)
    new_context = b.new_context

    def scaled_context(*args: Any, **kwargs: Any) -> Any:
        context = new_context(*args, **kwargs)
        context.set_default_timeout(scaled_ms(DEFAULT_WAIT_SECONDS))
        return context

    b.new_context = scaled_context  # type: ignore[method-assign]
    yield b
    b.close()


@pytest.fixture(autouse=True)
def scaled_expect() -> None:
    """Every ``expect``'s default deadline, stretched by the load as each test starts: the load changes during a
    run (pytest-xdist's workers each drive a browser), so a factor taken once when the session began could be
    that of an idle machine."""
    expect.set_options(timeout=scaled_ms(EXPECT_SECONDS))


@pytest.fixture
def page(browser: Browser, server_url: str) -> Iterator[Page]:
    """A studio page with its mesh loaded; fails the test on uncaught page errors."""
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    pg = context.new_page()
    page_errors: list[str] = []
    pg.on("pageerror", lambda exc: page_errors.append(str(exc)))

    def on_console(msg: ConsoleMessage) -> None:
        if msg.type == "error":
            page_errors.append(msg.text)

    pg.on("console", on_console)
    pg.goto(server_url)
    wait_ready(pg)
    yield pg
    context.close()
    assert not page_errors, f"errors in the page: {page_errors}"


def wait_for_page(page: Page | Frame, expression: str, what: str, seconds: float = DEFAULT_WAIT_SECONDS) -> None:
    """Wait until the JavaScript ``expression`` (a function) is true in the page; fail naming ``what`` after
    ``seconds`` on an idle machine, stretched on a loaded one (:func:`tests.waiting.scaled`)."""
    timeout = scaled_ms(seconds)
    try:
        page.wait_for_function(expression, timeout=timeout)
    except PlaywrightTimeoutError:
        raise AssertionError(f"timed out after {timeout / 1000:g} s waiting for {what} "
                             f"(in the page: {expression})") from None


def wait_ready(page: Page | Frame, timeout_ms: float = 30_000) -> None:
    """Wait until the studio has a mesh and nothing is pending (``timeout_ms`` on an idle machine)."""
    wait_for_page(page, "() => window.__arap && window.__arap.ready && !window.__arap.busy",
                  "the studio to be ready (its mesh shown, no request pending)", timeout_ms / 1000)


def wait_settled(page: Page, timeout_ms: float = 60_000) -> None:
    """Wait until the server reports the shape settled (after a drag ends it keeps iterating and streaming frames)."""
    wait_for_page(page, "() => document.querySelector('[data-testid=settle-status]')?.dataset.status === 'settled'"
                  " && !window.__arap.busy", "the shape to settle (settle status 'settled', no request pending)",
                  timeout_ms / 1000)


def wait_idle(page: Page, timeout_ms: float = 30_000) -> None:
    """Wait until no request that changes the view is unanswered, then for one more frame to be drawn."""
    wait_for_page(page, "() => !window.__arap.busy", "every request of the page to be answered", timeout_ms / 1000)
    page.evaluate("() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")


@pytest.fixture
def shoot(page: Page, tmp_path: Path) -> Callable[[str], Path]:
    """Save a screenshot of the page under a name (in tmp_path, and in $ARAP_TEST_ARTIFACTS when set)."""

    def save(name: str) -> Path:
        path = tmp_path / f"{name}.png"
        page.screenshot(path=str(path))
        folder = os.environ.get("ARAP_TEST_ARTIFACTS")
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
            shutil.copy(path, Path(folder) / path.name)
        return path

    return save


def canvas_pixels(page: Page) -> np.ndarray:
    """The 3D view's pixels as an ``(h, w, 4)`` uint8 array (CSS-pixel resolution)."""
    data = page.evaluate(
        """() => {
            const src = document.getElementById('view');
            const w = src.clientWidth, h = src.clientHeight;
            const c = document.createElement('canvas');
            c.width = w; c.height = h;
            const ctx = c.getContext('2d');
            ctx.drawImage(src, 0, 0, w, h);
            const bytes = ctx.getImageData(0, 0, w, h).data;
            let s = '';
            for (let i = 0; i < bytes.length; i += 0x8000) {
                s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
            }
            return { w, h, b64: btoa(s) };
        }"""
    )
    raw = np.frombuffer(base64.b64decode(data["b64"]), dtype=np.uint8)
    return raw.reshape(data["h"], data["w"], 4)


def positions(page: Page) -> np.ndarray:
    """Current vertex positions shown by the client, ``(n, 3)``."""
    return np.asarray(page.evaluate("() => window.__arap.positions()"), dtype=np.float64).reshape(-1, 3)


def screen_points(page: Page) -> np.ndarray:
    """Page coordinates (CSS pixels) of every vertex, ``(n, 2)``."""
    pts = page.evaluate(
        """() => {
            const p = window.__arap.positions();
            const out = [];
            for (let i = 0; i < p.length; i += 3) out.push(window.__arap.project([p[i], p[i + 1], p[i + 2]]));
            return out;
        }"""
    )
    return np.asarray(pts, dtype=np.float64)


def canvas_origin(page: Page) -> tuple[float, float]:
    """Page coordinates of the 3D view's top-left corner."""
    box = page.locator("#view").bounding_box()
    assert box is not None
    return box["x"], box["y"]
