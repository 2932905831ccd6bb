"""The ``distortion`` reply: how far each cell of the session's current shape is from rigid."""

from __future__ import annotations

from typing import Any

import numpy as np

from arap.energy import cell_distortion
from arap.server.protocol import RequestError, server_message
from arap.server.session import Session

HIGH_PERCENTILE = 98.0
"""Percentile of the values sent as the top of the colour scale (a few extreme cells would wash out the rest)."""


def distortion_frame(session: Session) -> tuple[dict[str, Any], bytes]:
    """The ``distortion`` message of the session's current shape and its payload.

    Parameters
    ----------
    session : Session
        Its rest pose ``V``, current shape ``U`` and solver parameters are used.

    Returns
    -------
    header : dict
        The ``distortion`` message (``high``, ``max``).
    payload : bytes
        (n,) little-endian float32 values of :func:`arap.cell_distortion`.

    Raises
    ------
    RequestError
        ``no_mesh`` without a mesh.
    """
    if session.mesh is None:
        raise RequestError("no_mesh", "no mesh is loaded")
    p = session.params
    D = cell_distortion(session.V, session.mesh.F, session.U, energy=p.energy, weights=p.weights, alpha=p.alpha)
    high = float(np.percentile(D, HIGH_PERCENTILE)) if len(D) else 0.0
    top = float(D.max(initial=0.0))
    return server_message("distortion", high=high, max=top), np.ascontiguousarray(D, dtype="<f4").tobytes()
