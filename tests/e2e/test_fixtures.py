"""The browser tests' own fixtures: what lets pytest-xdist's workers run them side by side."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from tests.e2e import conftest
from tests.waiting import wait_until


def test_workers_that_find_the_client_stale_at_once_build_it_once(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Two workers ask for the test build together: one builds, the other waits for it and then finds it fresh
    (two builds into one folder at once would serve a half-written client)."""
    built = tmp_path / "build" / "studio-e2e" / "index.html"
    monkeypatch.setattr(conftest, "E2E_CLIENT", built.parent)
    looks: list[str] = []
    builds: list[str] = []

    def client_built() -> bool:
        looks.append(threading.current_thread().name)
        return built.is_file()

    def build_now() -> None:
        builds.append(threading.current_thread().name)
        # the other worker looks while this one builds
        wait_until(lambda: any(name != threading.current_thread().name for name in looks), 30,
                   "the other worker to look at the build")
        built.parent.mkdir(parents=True, exist_ok=True)
        built.write_text("<html></html>")

    monkeypatch.setattr(conftest, "_client_built", client_built)
    monkeypatch.setattr(conftest, "_build_client_now", build_now)
    reasons: list[str | None] = []
    workers = [threading.Thread(target=lambda: reasons.append(conftest._build_client()), name=f"worker-{k}")
               for k in range(2)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=120)
    assert reasons == [None, None]
    assert len(builds) == 1, f"the client was built {len(builds)} times"
