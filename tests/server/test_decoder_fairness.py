"""A session's frame of a few megabytes is decoded while another session's large frame is still being decoded: it
never waits behind it."""

from __future__ import annotations

import asyncio
import json
import os
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient

from arap.server.decoder import (
    LARGE_BYTES,
    LARGE_LANE_NICENESS,
    PROCESS_BYTES,
    FrameDecoder,
    decode_text_frame,
    lane_of,
)
from tests.server.helpers import StudioClient
from tests.waiting import wait_until

pytestmark = pytest.mark.timeout(120)

SLOW_SECONDS = 6.0


def _padded(message: dict[str, Any], size: int) -> str:
    text = json.dumps(message)
    return text[:-1] + " " * (size - len(text)) + "}"


def _slow_when_asked(data: bytes | str, max_indices: int | None = None) -> Any:
    """Runs in the decoder process: a frame with a ``slow`` field takes SLOW_SECONDS to decode; it first creates the
    file the field names (decoding has started)."""
    text = data if isinstance(data, str) else data.decode()
    if '"slow"' in text:
        Path(json.loads(text)["slow"]).touch()
        time.sleep(SLOW_SECONDS)  # the scenario: a large frame that takes long to decode
    return decode_text_frame(data, max_indices)


def test_lanes() -> None:
    assert lane_of(PROCESS_BYTES) == lane_of(LARGE_BYTES - 1) == "small"
    assert lane_of(LARGE_BYTES) == lane_of(64 * 2**20) == "large"


def test_a_small_frame_does_not_wait_behind_another_sessions_large_one(http: TestClient, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("arap.server.decoder.decode_text_frame", _slow_when_asked)
    small = _padded({"type": "undo"}, PROCESS_BYTES + 1000)
    large = _padded({"type": "undo"}, LARGE_BYTES + 1000)
    with http.websocket_connect("/ws") as ws_a, http.websocket_connect("/ws") as ws_b:
        a, b = StudioClient(ws_a), StudioClient(ws_b)
        a.greet()
        b.greet()
        for text in (large, small):  # both decoder processes started
            b.send(text)
            b.expect("state")
        decoding = tmp_path / "decoding"
        a.send(_padded({"type": "undo", "slow": str(decoding)}, LARGE_BYTES + 1000))
        wait_until(decoding.exists, SLOW_SECONDS / 3, "A's frame to be decoded")
        t0 = time.monotonic()
        b.send(small)
        b.expect("state")
        waited = time.monotonic() - t0
        assert waited < SLOW_SECONDS / 3, f"the small frame waited {waited:.1f} s"
        assert "unknown field 'slow'" in a.error("bad_message")["message"]  # A is answered too, later
        a.ping()
        b.ping()


def test_the_large_lane_runs_at_a_lower_cpu_priority() -> None:
    psutil = pytest.importorskip("psutil")
    if not hasattr(os, "nice"):
        pytest.skip("no process priorities here")
    decoder = FrameDecoder()

    async def decode_both() -> None:
        for size in (PROCESS_BYTES + 10, LARGE_BYTES + 10):
            assert (await decoder.decode(_padded({"type": "undo"}, size))).type == "undo"

    try:
        # on a thread of its own: the browser tests' Playwright keeps an event loop running on the main thread
        failures: list[BaseException] = []

        def run() -> None:
            try:
                asyncio.run(decode_both())
            except BaseException as exc:  # noqa: BLE001 - handed to the test's thread
                failures.append(exc)

        worker = threading.Thread(target=run)
        worker.start()
        worker.join(timeout=120)
        assert not worker.is_alive() and not failures, failures
        server = psutil.Process()
        niceness = sorted(child.nice() - server.nice() for child in server.children()
                          if "python" in child.name().lower())
        assert niceness[-2:] == [0, LARGE_LANE_NICENESS], niceness
    finally:
        decoder.close()
