"""The studio as a Jupyter widget: the page in the notebook, its session in the kernel, talking through the kernel's
comm (anywidget). No server and no port, so it works wherever the notebook's widgets do: JupyterLab, Notebook 7,
VS Code, Colab, and kernels on another machine.

>>> import arap
>>> V, F = arap.builtin_mesh("cactus")
>>> w = arap.widget(V, F)          # doctest: +SKIP
>>> w                              # doctest: +SKIP
>>> # ... anchor, handle and drag in the widget ...
>>> w.vertices, w.constraints      # doctest: +SKIP

The comm carries the studio protocol's messages unchanged (``docs/protocol.md``): a text message as the custom
message's content, a binary one as its header (the content) and its payload (one buffer). Three messages are its
own. A view sends ``{"widget": "open"}`` when it opens; the kernel answers with the greeting (``welcome``, ``mesh``,
``state`` and the current shape). The kernel sends ``{"widget": "preparing"}`` to a view that opens while the session
is still being prepared (on the first run in an environment the solver's kernels compile first, for tens of
seconds), with a PNG picture of the mesh as its buffer, which the view shows with the time waited until its greeting
comes; and ``{"widget": "stopped"}`` to every view when the widget is stopped, and to a view that opens afterwards
instead of the greeting (the view says so over the studio's page, which no longer gets answers). A view names itself
in a ``"view"`` key of what it sends (removed before the message is read); the replies meant for that view alone
(its greeting, the answer to an export, an error) carry it as ``"to"``, and the views drop those meant for another.
Requests are answered in order on a thread of the widget's, as by the studio's server (:mod:`arap.server.channel`,
which also says which replies go to every view): drags coalesce, and the shape settles while no request waits.

A saved notebook keeps no live widget, so a picture of the shape with its constraints (:func:`arap.show`) is shown
under it and replaced whenever an edit is finished (after a drag has settled, an undo, a new constraint set):
that picture is what the saved notebook shows, e.g. on GitHub or in nbviewer.
"""

from __future__ import annotations

import logging
import os
import threading
import uuid
from collections.abc import Mapping
from functools import cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from arap.constraints import Constraints
from arap.errors import ArapError
from arap.meshes.mesh import MeshLike, check_mesh, mesh_arrays
from arap.studio_handle import Selection, initial_constraints, picture_input, session_selection

if TYPE_CHECKING:
    from arap.render.picture import Picture
    from arap.server.channel import ChannelWorker
    from arap.server.dispatch import Dispatcher
    from arap.server.replies import Reply
    from arap.server.session import Session

__all__ = ["OPEN_MESSAGE", "PREPARING_MESSAGE", "STOPPED_MESSAGE", "StudioWidget", "has_comm_kernel", "widget",
           "widget_module"]

logger = logging.getLogger(__name__)

OPEN_MESSAGE = {"widget": "open"}
"""What a view of the widget sends when it opens (outside the studio protocol, with its ``"view"`` name); the kernel
answers with the greeting."""

PREPARING_MESSAGE = {"widget": "preparing"}
"""What the kernel sends to a view that opens before the session is ready (outside the studio protocol), addressed to
it, with ``first_run`` (whether the solver's kernels are being compiled) and a PNG picture of the mesh as its
buffer."""

STOPPED_MESSAGE = {"widget": "stopped"}
"""What the kernel sends to the views of a stopped widget (outside the studio protocol): to every view when it is
stopped, and to a view that opens afterwards (addressed to it)."""

MAX_VIEW_NAME = 64
"""Longest view name a view may give; a longer one, or one that is not a string, is ignored."""

PICTURE_SIZE = (480, 320)
"""Width and height of the picture kept in the notebook."""


def widget_module() -> str:
    """The widget's ES module (``static/widget.js``, built with the studio's page by ``./dev setup``).

    Raises
    ------
    ArapError
        It is not built.
    """
    from arap.server.client_files import client_dir, client_missing_advice

    path = client_dir() / "widget.js"
    if not path.is_file():
        advice = client_missing_advice(client_dir())
        if advice is None:
            advice = f"The notebook widget's module {path} is missing: build it with ./dev setup."
        raise ArapError(advice)
    return path.read_text(encoding="utf-8")


def has_comm_kernel() -> bool:
    """Whether the code runs in a Jupyter kernel that has a comm channel (where widgets work)."""
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


@cache
def _widget_class() -> type:
    try:
        import anywidget
        import traitlets
    except ImportError as exc:
        raise ArapError(f'the studio widget needs anywidget: pip install "arap[notebook]" ({exc.name} is missing)'
                        ) from exc

    class _StudioWidget(anywidget.AnyWidget, StudioWidget):
        _esm = traitlets.Unicode().tag(sync=True)
        height = traitlets.Int(640).tag(sync=True)

        def __init__(self, **kwargs: Any) -> None:
            anywidget.AnyWidget.__init__(self, _esm=widget_module(), height=kwargs.pop("height"))
            self._setup(**kwargs)
            self.on_msg(lambda _w, content, buffers: self._receive(content, buffers))

        def _send_message(self, content: dict[str, Any], buffers: list[Any] | None) -> None:
            self.send(content, buffers)

        def close(self) -> None:
            """Close the widget (its views go) and stop its session's thread; the results stay readable."""
            self.stop()
            anywidget.AnyWidget.close(self)

        def _widget_bundle(self) -> dict[str, Any]:
            bundle = anywidget.AnyWidget._repr_mimebundle_(self)
            return dict(bundle[0] if isinstance(bundle, tuple) else bundle or {})

        def __repr__(self) -> str:
            return StudioWidget.__repr__(self)

    _StudioWidget.__name__ = _StudioWidget.__qualname__ = "StudioWidget"
    return _StudioWidget


class StudioWidget:
    """The studio in a notebook, served by this kernel; see :func:`widget`.

    Attributes
    ----------
    url : None
        There is no page to open elsewhere (the studio's server has one: ``arap.studio(..., transport="server")``).

    Examples
    --------
    >>> import arap
    >>> w = arap.widget(*arap.sphere(1))
    >>> w.url, w.vertices.shape, w.constraints.fixed.tolist()
    (None, (42, 3), [])
    >>> w.stop()
    """

    url: str | None = None

    def _setup(self, *, V: NDArray[np.float64], F: NDArray[np.int64], name: str, prepare: Any = None,
               picture: bool = True, opened: Any = None) -> None:
        from arap.server.channel import ChannelWorker
        from arap.server.dispatch import Dispatcher
        from arap.server.mesh_model import MeshData
        from arap.server.session import Session
        from arap.server.studio_config import StudioConfig
        from arap.warmup import KERNELS_READY

        self._V = V
        self._F = F
        config = StudioConfig()
        self.session: Session = Session(config.max_history_steps, config.max_history_bytes)
        self._dispatcher: Dispatcher = Dispatcher(self.session, config)
        self._worker: ChannelWorker = ChannelWorker(self._dispatcher, self._send_reply, self._idle)
        self._config = config
        self._picture = picture
        self._picture_id = uuid.uuid4().hex
        self._picture_key: Any = None
        self._picture_lock = threading.Lock()
        self._picture_wanted = threading.Event()
        self._picture_thread: threading.Thread | None = None
        self._stopped = False
        self._ready = threading.Event()
        self._preview: bytes | None = None
        mesh, look = opened if opened is not None else (MeshData.make(name, V, F), None)

        def load() -> Any:
            try:
                KERNELS_READY.wait(600.0)
                self.session.load(mesh, look)
                if prepare is not None:
                    prepare(self.session)
            finally:
                self._ready.set()
            return iter(())

        self._worker.start()
        self._worker.call(load)

    # ------------------------------------------------------------------ messages
    def _send_message(self, content: dict[str, Any], buffers: list[Any] | None) -> None:
        raise NotImplementedError  # the widget class sends through its comm

    def _send_reply(self, reply: Reply, view: str | None = None) -> None:
        """Send one server message: a text message as the content, a binary one as its header and one buffer;
        addressed ``"to"`` ``view`` when it is for that view alone."""
        from arap.server.frames import decode_binary

        def addressed(content: dict[str, Any]) -> dict[str, Any]:
            return content if view is None else {**content, "to": view}

        if isinstance(reply, dict):
            self._send_message(addressed(reply), None)
        elif isinstance(reply, bytes):
            header, payload = decode_binary(reply)
            self._send_message(addressed(header), [payload])
        else:
            header, parts = reply
            self._send_message(addressed(header), [parts[0] if len(parts) == 1 else b"".join(parts)])

    def _receive(self, content: Any, buffers: list[Any] | None) -> None:
        """A custom message from a view: the open message, or a studio request (answered on the worker thread)."""
        from arap.server.dispatch import decode_message

        view = None
        if isinstance(content, dict) and "view" in content:
            content = dict(content)
            name = content.pop("view")
            view = name if isinstance(name, str) and 0 < len(name) <= MAX_VIEW_NAME else None
        if self._stopped:
            if content == OPEN_MESSAGE:  # a view shown after the stop: it says so instead of waiting for a greeting
                self._send_message(STOPPED_MESSAGE if view is None else {**STOPPED_MESSAGE, "to": view}, None)
            return
        if content == OPEN_MESSAGE:
            if not self._ready.is_set():  # the greeting waits for the session: the view shows the mesh meanwhile
                self._send_preparing(view)
            self._worker.call(self._dispatcher.rejoin, view)
            return
        self._worker.put(decode_message(self._config, content, buffers), view)

    def _send_preparing(self, view: str | None) -> None:
        """Tell a view that its greeting waits for the session to be prepared, with a picture of the mesh to show
        meanwhile (drawn once, without the solver's kernels)."""
        from arap.render.show import show
        from arap.solve.kernel_cache import first_compile_pending

        if self._preview is None:
            width, height = PICTURE_SIZE
            self._preview = show(self._V, self._F, width=width, height=height).png()
        message = {**PREPARING_MESSAGE, "first_run": first_compile_pending()}
        self._send_message(message if view is None else {**message, "to": view}, [self._preview])

    def wait(self, timeout: float = 30.0) -> bool:
        """Wait until every request has been answered and the shape has settled; False on timeout."""
        return self._worker.idle(timeout)

    # ------------------------------------------------------------------ results
    @property
    def running(self) -> bool:
        """Whether the widget answers its views (until :meth:`stop`)."""
        return not self._stopped

    @property
    def vertices(self) -> NDArray[np.float64]:
        """(n, 3) float64 array: the current deformed shape (the given mesh before any edit)."""
        if self.session.mesh is None:
            return self._V.copy()
        return np.array(self.session.U, dtype=np.float64)

    @property
    def faces(self) -> NDArray[np.int64]:
        """(m, 3) int64 array: the triangles of the session's mesh (the given mesh until another is loaded in it)."""
        if self.session.mesh is None:
            return self._F.copy()
        return np.array(self.session.mesh.F, dtype=np.int64)

    @property
    def constraints(self) -> Selection:
        """The selection made in the widget (empty before any)."""
        return session_selection(self.session if self.session.mesh is not None else None)

    def stop(self, timeout: float = 10.0) -> None:
        """Stop answering the views (a settling run stops at its next iteration) and tell them so; idempotent. The
        results stay readable."""
        if getattr(self, "_worker", None) is None:  # never set up (its construction failed)
            return
        stopping = not self._stopped
        self._stopped = True
        self._worker.close(timeout)
        if stopping:  # after the worker's last reply, so that nothing follows it
            self._send_message(dict(STOPPED_MESSAGE), None)

    def __enter__(self) -> StudioWidget:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped"
        n = len(self.session.U) if self.session.mesh is not None else len(self._V)
        return f"<arap.StudioWidget {state}, {n} vertices>"

    # ------------------------------------------------------------------ the picture kept in the notebook
    def picture(self) -> Picture:
        """A picture of the current shape with its constraints (:func:`arap.show`), as kept in the notebook; for a
        picture opened for the puppet warp, the warped picture (as **Export PNG** gives it, on white, made smaller to
        fit :data:`PICTURE_SIZE`)."""
        from arap.render.show import show

        U, F = self.vertices, self.faces
        width, height = PICTURE_SIZE
        mesh = self.session.mesh
        if mesh is not None and mesh.picture is not None:
            return _warped_picture(mesh, U, self.session)
        try:
            return show(U, F, constraints=self.session.constraints_document(), width=width, height=height)
        except (ArapError, ValueError, KeyError, IndexError):  # constraints in another numbering (a repaired file)
            return show(U, F, width=width, height=height)

    def _picture_bundle(self) -> dict[str, Any]:
        return {"image/png": self.picture().png(),
                "text/plain": "Picture of the studio's shape (kept when the notebook is saved)"}

    def _widget_bundle(self) -> dict[str, Any]:
        return {"text/plain": repr(self)}

    def _ipython_display_(self) -> None:
        from IPython.display import display

        display(self._widget_bundle(), raw=True)
        if self._picture:
            display(self._picture_bundle(), raw=True, display_id=self._picture_id)
            self._picture_key = self._shape_key()

    def _shape_key(self) -> Any:
        s = self.session
        return (id(s.mesh), id(s.U), id(s.constraints))

    def _idle(self) -> None:
        """The worker has nothing left to do: replace the picture if the shape or the constraints changed, unless a
        drag is under way (it is replaced once the drag has ended and the shape has settled)."""
        if not self._picture or self._picture_key is None or not self.session.settled:
            return
        if self._shape_key() == self._picture_key:
            return
        self._picture_wanted.set()
        with self._picture_lock:
            if self._picture_thread is None or not self._picture_thread.is_alive():
                self._picture_thread = threading.Thread(target=self._draw_pictures, name="arap-widget-picture",
                                                        daemon=True)
                self._picture_thread.start()

    def _draw_pictures(self) -> None:
        from IPython.display import update_display

        while self._picture_wanted.is_set() and not self._stopped:
            self._picture_wanted.clear()
            key = self._shape_key()
            try:
                update_display(self._picture_bundle(), raw=True, display_id=self._picture_id)
                self._picture_key = key
            except Exception:
                logger.exception("could not update the studio's picture")


def _warped_picture(mesh: Any, U: NDArray[np.float64], session: Session) -> Picture:
    """The warped picture of a picture's ``mesh`` at ``U`` (:func:`arap.server.pictures.warped_picture_png`, its pins'
    depths the session's), on white, made smaller to fit :data:`PICTURE_SIZE` (never larger)."""
    import io

    from PIL import Image

    from arap.render.picture import Picture
    from arap.server.pictures import warped_picture_png

    png = warped_picture_png(mesh, U, session.constraints.points, session.pin_depth)
    with Image.open(io.BytesIO(png)) as image:
        warped = image.convert("RGBA")
    warped.thumbnail(PICTURE_SIZE, Image.Resampling.LANCZOS)
    flat = Image.new("RGBA", warped.size, (255, 255, 255, 255))
    flat.alpha_composite(warped)
    return Picture(np.asarray(flat.convert("RGB")))


def widget(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    *,
    name: str = "mesh",
    height: int = 640,
    constraints: Constraints | Mapping[str, Any] | str | os.PathLike[str] | None = None,
    picture: bool = True,
) -> StudioWidget:
    """The studio as a Jupyter widget served by this kernel (no server, no port); display it (the last expression
    of a cell) to edit the mesh in the notebook.

    Parameters
    ----------
    V : (n, 3) float array, MeshLike, picture path or (h, w, 3|4) uint8 array
        Rest positions, or a mesh object with ``vertices`` and ``faces`` (then leave out ``F``); or a picture,
        opened for the puppet warp (as :func:`arap.studio` opens one).
    F : (m, 3) int array or None
    name : str
        Name shown in the page and used for exports.
    height : int
        Height of the widget in pixels.
    constraints : Constraints, mapping, path or None
        Initial constraints (the ``arap deform`` format, see :func:`arap.load_constraints`), as for
        :func:`arap.studio`.
    picture : bool
        Show a picture of the shape under the widget, replaced after each finished edit: the notebook keeps it
        when saved (a saved notebook has no live widget).

    Returns
    -------
    StudioWidget
        An anywidget with ``vertices``, ``faces``, ``constraints``, ``picture()`` and ``stop()``.

    Raises
    ------
    MeshError
        The mesh is unusable (as :func:`arap.check_mesh`).
    ConstraintError
        ``constraints`` is invalid for this mesh, or holds stiffness.
    ArapError
        anywidget is not installed (``pip install "arap[notebook]"``) or the widget's module is not built.

    Examples
    --------
    >>> import arap
    >>> w = arap.widget(*arap.sphere(1), height=480)             # display w in a cell to edit the mesh
    >>> type(w).__name__, w.faces.shape
    ('StudioWidget', (80, 3))
    >>> w.stop()
    """
    rest: NDArray[np.float64]
    faces: NDArray[np.int64]
    opened = picture_input(V, F, name)
    if opened is not None:
        rest, faces = opened[0].V, opened[0].F
    else:
        rest, faces = check_mesh(*mesh_arrays(V, F))
    prepare = None if constraints is None else initial_constraints(constraints, len(rest))
    cls = _widget_class()
    w: StudioWidget = cls(V=rest, F=faces, name=name, prepare=prepare, picture=picture, height=int(height),
                          opened=opened)
    return w
