"""Property-based fuzzing of the protocol: messages generated from the message definitions, valid and corrupted,
never end the session or cause an internal error; bounded in examples and time."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from tests.server.fuzz_messages import messages
from tests.server.helpers import StudioClient

pytestmark = pytest.mark.timeout(300)

@settings(max_examples=400, deadline=None, database=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(text=messages())
def test_fuzzed_messages_never_end_the_session(studio: StudioClient, text: str) -> None:
    studio.send(text)
    studio.send({"type": "get_constraints"})  # the marker: everything before it has been answered
    while True:
        reply = studio.recv()
        assert not (reply.type == "error" and reply.data["code"] == "internal"), (text, reply.data)
        if reply.type == "constraints":
            break
