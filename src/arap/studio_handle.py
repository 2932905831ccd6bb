"""What the notebook's studio handles (:mod:`arap.notebook`, the served page, and :mod:`arap.jupyter_widget`, the
widget) read from a studio session and put on a new one: the selection as arrays, and initial constraints."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from arap.constraints import Constraints, load_constraints
from arap.errors import ConstraintError

if TYPE_CHECKING:
    from arap.server.session import Session

__all__ = ["Selection", "initial_constraints", "picture_input", "session_selection"]


@dataclass(frozen=True)
class Selection:
    """What the user selected in the studio.

    Attributes
    ----------
    roi : (r,) int64 array or None
        Region of interest; None is the whole mesh.
    fixed : (f,) int64 array
        Anchors.
    handle_groups : list of (h_g,) int64 arrays
        Handle groups.
    targets : (h, 3) float64 array
        Current positions of the handle vertices, groups concatenated in order.
    document : dict
        The same constraints in the command-line format (``arap deform MESH CONSTRAINTS``; see
        :func:`arap.save_constraints`).

    Examples
    --------
    >>> import arap
    >>> with arap.studio(*arap.sphere(1), show=False) as s:
    ...     selection = s.constraints                          # no page has selected anything yet
    >>> selection.fixed.tolist(), selection.handle_groups, selection.targets.shape, selection.document["fixed"]
    ([], [], (0, 3), [])
    """

    roi: NDArray[np.int64] | None
    fixed: NDArray[np.int64]
    handle_groups: list[NDArray[np.int64]]
    targets: NDArray[np.float64]
    document: dict[str, Any]


def session_selection(session: Session | None) -> Selection:
    """The selection of a studio session (empty for None or a session without a mesh)."""
    if session is None or session.mesh is None:
        empty = np.zeros(0, dtype=np.int64)
        return Selection(None, empty, [], np.zeros((0, 3)), {"fixed": [], "handles": [], "targets": []})
    cs, transforms = session.constraints, session.transforms
    return Selection(
        roi=None if cs.roi is None else cs.roi.copy(),
        fixed=cs.fixed.copy(),
        handle_groups=[g.copy() for g in cs.groups],
        targets=np.array(cs.handle_targets(transforms), dtype=np.float64).reshape(-1, 3),
        document=session.constraints_document(),
    )


def initial_constraints(source: Constraints | Mapping[str, Any] | str | os.PathLike[str],
                         n_vertices: int) -> Callable[[Session], object]:
    """Validate initial constraints; return what sets them on a new session."""
    c = load_constraints(source.to_dict() if isinstance(source, Constraints) else source, n_vertices)
    if c.stiffness is not None:
        raise ConstraintError("the studio does not edit stiffness; give constraints without it")
    handles = c.handles.tolist()
    groups = [list(map(int, g)) for g in c.handle_groups] if c.handle_groups else ([handles] if handles else [])
    grouped = [i for g in groups for i in g]
    if sorted(grouped) != sorted(handles):
        raise ConstraintError("handle_groups must hold exactly the handles, each once")
    row = {int(v): k for k, v in enumerate(handles)}
    targets = c.targets[[row[i] for i in grouped]].tolist() if grouped else None
    roi = None if c.roi is None else c.roi.tolist()
    fixed = c.fixed.tolist()

    def prepare(session: Session) -> object:
        return session.set_constraints(roi, fixed, groups, targets)

    return prepare


def picture_input(V: object, F: object, name: str) -> tuple[Any, Any] | None:
    """The studio's mesh and look of a picture given to :func:`arap.studio` or :func:`arap.widget` in place of a
    mesh (a path to a PNG, JPEG or WebP file, or an (h, w, 3|4) uint8 array, with no ``F``); None for a mesh.

    The picture opens as **Open file…** opens one: meshed, drawn textured with itself and bent in its plane with the
    puppet warp's modes (:mod:`arap.server.pictures`).

    Raises
    ------
    ArapError
        An unusable picture (:func:`arap.puppet.picture.as_picture`), one without an opaque part, or one whose mesh
        is over the studio's vertex limit.
    """
    is_path = isinstance(V, (str, os.PathLike)) and str(V).lower().endswith((".png", ".jpg", ".jpeg", ".webp"))
    is_array = isinstance(V, np.ndarray) and V.ndim == 3 and V.dtype == np.uint8
    if F is not None or not (is_path or is_array):
        return None
    from arap.errors import ArapError
    from arap.puppet.picture import as_picture
    from arap.server.errors import RequestError
    from arap.server.pictures import picture_mesh
    from arap.server.studio_config import StudioConfig

    pixels = as_picture(V)
    stem = os.path.splitext(os.path.basename(str(V)))[0] if is_path and name == "mesh" else name
    try:
        return picture_mesh(pixels, stem, StudioConfig().max_vertices)
    except RequestError as exc:
        raise ArapError(exc.message) from exc
