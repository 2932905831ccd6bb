"""The ``distortion`` reply: how far each cell of the session's current shape is from rigid."""

from __future__ import annotations

from typing import Any
from weakref import WeakKeyDictionary

import numpy as np

from arap.method.cells import Cells, build_cells
from arap.method.elements import element_cells
from arap.method.energy import distortion_from_cells
from arap.server.errors import RequestError
from arap.server.server_messages import Distortion
from arap.server.session import Session

HIGH_PERCENTILE = 98.0
"""Percentile of the values sent as the top of the colour scale (a few extreme cells would wash out the rest)."""

_CELLS: WeakKeyDictionary[Session, tuple[tuple[Any, ...], Cells]] = WeakKeyDictionary()
"""Per session: the cells of its rest pose for the current energy and weights (rebuilt when any of them changes)."""


def _cells(session: Session, F: np.ndarray, solid: bool) -> Cells:
    key = (id(session.V), session.rest_id, session.params.energy, session.params.weights, solid)
    held = _CELLS.get(session)
    if held is None or held[0] != key:
        cells = element_cells(session.V, F, session.params.weights) if solid else \
            build_cells(session.V, F, session.params.energy, session.params.weights)
        held = (key, cells)
        _CELLS[session] = held
    return held[1]


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
        (n,) little-endian float32 values of :func:`arap.cell_distortion`; for a solid, each vertex gets the mean
        of its tetrahedra's.

    Raises
    ------
    RequestError
        ``no_mesh`` without a mesh.
    """
    if session.mesh is None:
        raise RequestError("no_mesh", "no mesh is loaded")
    p = session.params
    mesh = session.mesh
    if mesh.elements is not None:
        T = mesh.elements
        cells = _cells(session, T, True)
        per_element = distortion_from_cells(cells, session.V, T, session.U, "elements")
        count = np.bincount(T.ravel(), minlength=len(session.V))
        D = np.bincount(T.ravel(), weights=np.repeat(per_element, 4), minlength=len(session.V)) / np.maximum(count, 1)
    else:
        F = mesh.F
        D = distortion_from_cells(_cells(session, F, False), session.V, F, session.U, p.energy, p.alpha)
    high = float(np.percentile(D, HIGH_PERCENTILE)) if len(D) else 0.0
    top = float(D.max(initial=0.0))
    return Distortion(high=high, max=top).to_wire(), np.ascontiguousarray(D, dtype="<f4").tobytes()
