"""A list of vertex indices longer than the largest mesh the server accepts is refused when counted, before any of
its numbers is decoded: the server's memory stays within a small multiple of the frame, whatever the list holds."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import tracemalloc

import pytest

from arap.server.errors import RequestError
from arap.server.protocol import parse_large_text
from tests.waiting import scaled

pytestmark = pytest.mark.timeout(300)


def _zeros(count: int) -> str:
    return "0," * (count - 1) + "0"


def _message(fixed: str = "", groups: str = "", stiffness: str = "") -> bytes:
    text = ('{"type":"set_constraints","roi":null,"fixed":[' + fixed + '],"handle_groups":[' + groups + "]"
            + (',"stiffness":[' + stiffness + "]" if stiffness else "") + "}")
    return text.encode()


@pytest.mark.parametrize(("data", "name"), [
    (_message(fixed=_zeros(1_000_000)), "set_constraints.fixed"),
    (_message(groups="[1],[" + _zeros(1_000_000) + "]"), "set_constraints.handle_groups[1]"),
    (_message(stiffness='{"vertices":[' + _zeros(1_000_000) + '],"value":2}'), "set_constraints.stiffness[0].vertices"),
])
def test_index_lists_longer_than_the_largest_mesh_are_refused_before_decoding(data: bytes, name: str) -> None:
    tracemalloc.start()
    try:
        with pytest.raises(RequestError) as info:
            parse_large_text(data, max_indices=5000)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.code == "too_large"
    assert info.value.request == "set_constraints"
    assert f"{name} lists 1,000,000 vertex indices, more than the 5,000 vertices" in info.value.message
    assert peak < len(data), peak  # decoded, the list would take twice the text (int32), four times as int64


def test_index_lists_within_the_limit_are_decoded() -> None:
    msg = parse_large_text(_message(fixed=_zeros(5000), groups="[" + _zeros(5000) + "]"), max_indices=5000)
    assert len(msg.fixed) == 5000 and len(msg.handle_groups[0]) == 5000  # type: ignore[attr-defined]
    with pytest.raises(RequestError, match="5,001 vertex indices"):
        parse_large_text(_message(fixed=_zeros(5001)), max_indices=5000)


_SERVER = textwrap.dedent("""
    import json, resource, sys
    from pathlib import Path
    from starlette.testclient import TestClient
    from arap.server import create_app
    from tests.server.helpers import StudioClient

    static = Path(sys.argv[1])
    (static / "assets").mkdir(parents=True, exist_ok=True)
    (static / "index.html").write_text("<!doctype html>")
    count = int(sys.argv[2])
    text = '{"type":"set_constraints","roi":null,"fixed":[' + "0," * (count - 1) + '0],"handle_groups":[]}'
    app = create_app("cactus", static_dir=static, allowed_hosts=["testserver"], max_vertices=5000)
    with TestClient(app) as http, http.websocket_connect("/ws") as ws:
        client = StudioClient(ws)
        client.greet()
        client.send({"type": "set_constraints", "roi": None, "fixed": [0] * 200_000, "handle_groups": []})
        client.recv()  # the decoder's worker has started
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        client.send(text)
        error = client.error()
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({"error": error, "grown": (peak - base) * 1024, "text": len(text)}))
""")


def test_the_server_refuses_a_huge_index_list_in_a_small_multiple_of_its_text(tmp_path: object) -> None:
    """The decoder refuses the list when it has counted it: the decoded list never crosses back from its process
    (32 million zeros took the server 558 MB)."""
    out = subprocess.run([sys.executable, "-c", _SERVER, str(tmp_path), str(6_000_000)], capture_output=True,
                         text=True, timeout=scaled(240), check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["error"]["code"] == "too_large", result
    assert "6,000,000 vertex indices" in result["error"]["message"], result
    # before: 7.3 times the text (the decoded list pickled back, then unpickled); now the text sent to the decoder
    assert result["grown"] < 3 * result["text"], result
