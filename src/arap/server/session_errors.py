"""Why a studio session refuses a request, in the session's own terms: no mesh, constraints it cannot use, values it
cannot use, a mesh it cannot use, a solve that went wrong.

A :class:`~arap.server.session.Session` and the helpers it calls (constraint sets, solvers, vertex renumbering)
raise these and know nothing of the wire: each carries only the message shown to the user, and the transports'
layer turns them into ``error`` messages with the code :data:`arap.server.errors.SESSION_ERROR_CODES` gives each
class. A refused request leaves the session unchanged.
"""

from __future__ import annotations

__all__ = ["BadValues", "ConstraintsRejected", "NoMesh", "SessionError", "SolveFailed", "UnusableMesh"]


class SessionError(Exception):
    """A request the session refused.

    Parameters
    ----------
    message : str
        Human-readable explanation (shown to the user).
    """

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.message = message


class NoMesh(SessionError):
    """The request needs a mesh and the session has none."""


class ConstraintsRejected(SessionError):
    """Vertex indices out of range or repeated, or constraints the solver cannot use (a region nothing pins
    down, nothing to solve)."""


class BadValues(SessionError):
    """Values of a request the session cannot use: targets of the wrong shape or absurdly far away, options the
    solver refuses."""


class UnusableMesh(SessionError):
    """A mesh that cannot be used: a deformed shape that cannot become the rest pose, or cannot be exported."""


class SolveFailed(SessionError):
    """A solve went wrong (non-finite positions); the shape is unchanged."""
