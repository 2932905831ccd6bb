"""Mirror editing on shapes that are only nearly symmetric: a scan (the armadillo) and a generated symmetric shape
with noise and triangles that do not mirror each other. The plane is found (refined from the principal axes), a
vertex's partner is where its reflection meets the surface within the tolerance set in the panel, and a handle
painted on one side gets a partner of about its size on the other."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import uvicorn
from playwright.sync_api import Browser, Page, expect
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from arap.server import bind_socket, create_app, studio_url
from arap.server.app import frame_limit
from tests.e2e.conftest import VIEWPORT, screen_points, wait_idle, wait_ready
from tests.e2e.test_studio import box_select
from tests.e2e.test_studio_mirror import mirror_state, paint_at, press_mirror, reflect, upload

pytestmark = pytest.mark.e2e


class _MeshServer(threading.Thread):
    """A studio server whose sessions start with the given mesh file."""

    def __init__(self, mesh: Path) -> None:
        super().__init__(daemon=True, name="studio-server-mesh")
        app = create_app(mesh)
        self.sock = bind_socket("127.0.0.1", 0)
        self.url = studio_url("127.0.0.1", self.sock.getsockname()[1])
        config = uvicorn.Config(app, log_level="warning", ws_per_message_deflate=False,
                                ws_max_size=frame_limit(1 << 20), lifespan="off")
        self.server = uvicorn.Server(config)

    def run(self) -> None:
        self.server.run(sockets=[self.sock])


@pytest.fixture
def armadillo_url(server_url: str, shared_meshes_dir: Path) -> Iterator[str]:
    """A server whose sessions start with the shared armadillo (``server_url`` builds the client)."""
    server = _MeshServer(shared_meshes_dir / "armadillo.obj")
    server.start()
    yield server.url
    server.server.should_exit = True
    server.join(timeout=10)


def open_page(browser: Browser, url: str) -> Page:
    page = browser.new_context(viewport=VIEWPORT).new_page()
    page.goto(url)
    wait_ready(page, timeout_ms=120_000)
    return page


def paint_one_side(page: Page, side: np.ndarray, other: np.ndarray) -> tuple[list[int], list[int]]:
    """Box-select a handle over vertices of `side` (a boolean mask) with mirror editing on, in a rectangle that no
    vertex of `other` falls in: the two groups."""
    pts = screen_points(page)
    centre = np.median(pts[side], axis=0)
    half = np.ptp(pts[side], axis=0) / 2
    while True:
        inside = np.all(np.abs(pts - centre) <= half, axis=1)
        if not (inside & other).any():
            break
        half *= 0.85
    assert (inside & side).sum() >= 15
    page.get_by_test_id("role-handle").click()
    box_select(page, *(centre - half), *(centre + half))
    wait_idle(page)
    groups = page.evaluate("() => window.__arap.constraints().handle_groups")
    assert len(groups) == 2, "the handle should get a partner group"
    assert page.evaluate("() => window.__arap.partners()") == [1, 0]
    return groups[0], groups[1]


def test_the_armadillo_is_found_symmetric_and_a_handle_gets_a_partner_of_its_size(
        browser: Browser, armadillo_url: str) -> None:
    page = open_page(browser, armadillo_url)
    V = np.asarray(page.evaluate("() => window.__arap.positions()")).reshape(-1, 3)
    m = press_mirror(page)
    print(f"armadillo: {100 * m['matched']:.1f}% of {len(V)} vertices paired, plane {m['plane']}, "
          f"{m['ms']:.0f} ms")
    assert m["on"] and m["active"], "the armadillo's symmetry plane should be found"
    assert m["matched"] >= 0.8
    normal = np.asarray(m["plane"]["normal"])
    assert abs(normal[0]) > 0.98, "the armadillo is symmetric about a plane close to x = const"
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    assert abs(m["tolerance"] - 0.015 * diag) < 1e-6 * diag, "the default tolerance: 1.5% of the diagonal"
    expect(page.get_by_test_id("mirror-status")).to_contain_text("symmetric")

    # every partner lies where the reflection meets the surface: within the tolerance plus about an edge
    mirror_of = np.asarray(m["mirrorOf"])
    paired = mirror_of >= 0
    miss = np.linalg.norm(reflect(V[paired], m["plane"]) - V[mirror_of[paired]], axis=1)
    assert np.quantile(miss, 0.99) < 0.03 * diag

    # a handle on one side (the upper part, right of the plane): a partner of about its size on the other side
    c = np.asarray(m["plane"]["point"])
    s = (V - c) @ normal
    y = V[:, 1]
    side = (s > 0.15 * diag) & (y > np.quantile(y, 0.6))
    g0, g1 = paint_one_side(page, side, s < 0.05 * diag)
    print(f"armadillo: handle of {len(g0)} vertices, partner of {len(g1)}")
    assert len(g0) > 500
    assert 0.7 * len(g0) <= len(g1) <= 1.3 * len(g0)
    assert (s[g1] < 0).mean() > 0.95, "the partner lies on the other side of the plane"
    assert not page.evaluate("() => window.__arap.errors")
    page.context.close()


def scan_like_mesh(n: int = 1400) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A warped ellipsoid symmetric about a tilted plane (normal R[:, 0] through t), sampled at random points (so
    its triangles do not mirror each other) and moved by noise of 0.3% of its size: (V, F, R, t)."""
    rng = np.random.default_rng(5)
    P = rng.normal(size=(n, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    F = ConvexHull(P).simplices.copy()
    centre = P[F].mean(axis=1)
    normal = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    flip = (normal * centre).sum(axis=1) < 0
    F[flip] = F[flip][:, [0, 2, 1]]
    Q = np.column_stack([1.3 * P[:, 0], 0.8 * P[:, 1] + 0.35 * (P[:, 2] + 0.5) ** 2, P[:, 2]])
    Q += rng.normal(scale=0.003 * np.linalg.norm(np.ptp(Q, axis=0)), size=Q.shape)
    R = Rotation.from_euler("xyz", [0.3, 0.7, -0.4]).as_matrix()
    t = np.array([0.5, -2.0, 3.0])
    return Q @ R.T + t, F, R, t


def test_a_noisy_differently_meshed_symmetric_shape_pairs_within_the_tolerance_set(
        page: Page, tmp_path: Path) -> None:
    V0, F, R, t = scan_like_mesh()
    V = upload(page, tmp_path, "scanlike", V0, F)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    m = press_mirror(page)
    print(f"scan-like: {100 * m['matched']:.1f}% paired, {m['ms']:.0f} ms")
    assert m["active"] and m["matched"] >= 0.9
    normal = np.asarray(m["plane"]["normal"])
    assert abs(abs(normal @ R[:, 0]) - 1) < 1e-3, "the plane is refined to the true one, not a principal axis"
    assert abs(normal @ (np.asarray(m["plane"]["point"]) - t)) < 2e-3 * diag
    mirror_of = np.asarray(m["mirrorOf"])
    paired = mirror_of >= 0
    miss = np.linalg.norm(reflect(V[paired], m["plane"]) - V[mirror_of[paired]], axis=1)
    edge = np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1).mean()
    assert miss.max() < 0.015 * diag + 1.5 * edge

    # a handle on one side: its partner covers the mirrored region, however the triangles fall there
    s = (V - t) @ R[:, 0]
    toward = np.array([0.35, 0.28, 1.0])  # where the camera looks from (Viewer.fit)
    side = s > 0.3 * diag
    target = V[np.flatnonzero(side)[np.argmax(V[side] @ toward)]]
    page.get_by_test_id("brush-units").select_option("world")
    page.get_by_test_id("brush-radius").fill("12")
    page.get_by_test_id("role-handle").click()
    paint_at(page, target)
    g0, g1 = page.evaluate("() => window.__arap.constraints().handle_groups")
    assert len(g0) >= 15 and 0.8 * len(g0) <= len(g1) <= 1.25 * len(g0)
    assert (s[g1] < 0).all()

    # the tolerance field: a hair's breadth pairs too few vertices (no plane, mirror editing goes off and says so);
    # a wider one pairs them again
    tolerance = page.get_by_test_id("mirror-tolerance")
    expect(tolerance).to_have_value("1.5")
    tolerance.fill("0.1")
    tolerance.press("Enter")
    wait_idle(page)
    m = mirror_state(page)
    assert not m["on"] and m["plane"] is None and m["matched"] < 0.8
    assert abs(m["tolerance"] - 0.001 * diag) < 1e-6 * diag
    expect(page.get_by_test_id("status-text")).to_contain_text("No mirror symmetry found")
    tolerance.fill("3")
    tolerance.press("Enter")
    page.get_by_test_id("mirror-on").check()
    m = mirror_state(page)
    assert m["active"] and m["matched"] > 0.99
    assert abs(m["tolerance"] - 0.03 * diag) < 1e-6 * diag
    assert not page.evaluate("() => window.__arap.errors")
