"""Errors of the studio protocol: the ``error`` codes, the exception a rejected request raises, and the one table
that gives the code of each refusal of a session (:mod:`arap.server.session_errors`).

Part of the wire protocol (:mod:`arap.server.protocol`).
"""

from __future__ import annotations

from arap.server.session_errors import (
    BadValues,
    ConstraintsRejected,
    NoMesh,
    SessionError,
    SolveFailed,
    UnusableMesh,
)

__all__ = ["ERROR_CODES", "SESSION_ERROR_CODES", "RequestError", "request_error"]

ERROR_CODES: dict[str, str] = {
    "bad_message": "not JSON, not an object, unknown type, unknown or missing field, wrong field type/range",
    "bad_mesh": "the mesh could not be read or is unusable",
    "too_large": "a frame, upload or mesh exceeds the server's limits",
    "bad_constraints": "indices out of range or repeated, or a region no constraint pins down",
    "no_mesh": "the request needs a mesh and the session has none",
    "busy": "too many requests are waiting in this session; the request was dropped",
    "internal": "an unexpected server error; the session continues",
}
"""Error codes of the ``error`` message and what they mean."""


class RequestError(Exception):
    """A request was rejected; becomes an ``error`` message (:func:`arap.server.protocol.error_message`) and leaves the
    session unchanged.

    Parameters
    ----------
    code : str
        One of :data:`ERROR_CODES`.
    message : str
        Human-readable explanation (shown to the user).
    request : str or None
        Type of the rejected message, when known.
    """

    def __init__(self, code: str, message: str, request: str | None = None) -> None:
        if code not in ERROR_CODES:
            raise ValueError(f"unknown error code {code!r}")
        super().__init__(message)
        self.code = code
        self.message = message
        self.request = request

    def __reduce__(self) -> tuple[type[RequestError], tuple[str, str, str | None]]:
        # Pickled with its fields (a request decoded in another process raises it there).
        return (RequestError, (self.code, self.message, self.request))


SESSION_ERROR_CODES: dict[type[SessionError], str] = {
    NoMesh: "no_mesh",
    ConstraintsRejected: "bad_constraints",
    BadValues: "bad_message",
    UnusableMesh: "bad_mesh",
    SolveFailed: "internal",
}
"""The ``error`` code of each refusal of a session."""


def request_error(exc: SessionError, request: str | None = None) -> RequestError:
    """The :class:`RequestError` (and so the ``error`` message) that reports the session's refusal ``exc`` of a
    ``request`` message.

    Example
    -------
    >>> request_error(NoMesh("no mesh is loaded"), "undo").code
    'no_mesh'
    """
    code = next((SESSION_ERROR_CODES[c] for c in type(exc).__mro__ if c in SESSION_ERROR_CODES), "internal")
    return RequestError(code, exc.message, request)
