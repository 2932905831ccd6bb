"""The studio from Python: serve a mesh in the background, edit it in the browser, read the result back as arrays.

>>> import arap
>>> V, F = arap.builtin_mesh("cactus")
>>> s = arap.studio(V, F)          # doctest: +SKIP
>>> # ... anchor, handle and drag in the page shown inline (Jupyter) or at s.url ...
>>> s.vertices, s.constraints      # doctest: +SKIP
>>> s.stop()                       # doctest: +SKIP

The server is the one ``arap studio`` runs (:mod:`arap.server`), on a free port of 127.0.0.1, in a thread of the
calling process. It has a random token, carried by the handle's URL (``?token=...``): pages and programs without it
are refused, whether in another browser tab or another local process. The handle reads the shape and the selection
of the most recently opened browser session of its own URL; they stay readable after the page is closed, until
:meth:`Studio.stop`.
"""

from __future__ import annotations

import html
import os
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from arap.constraints import Constraints
from arap.errors import ArapError
from arap.meshes.mesh import MeshLike, check_mesh, mesh_arrays
from arap.studio_handle import Selection, initial_constraints, picture_input, session_selection

if TYPE_CHECKING:
    import socket

    import uvicorn

    from arap.jupyter_widget import StudioWidget
    from arap.server.session import Session

__all__ = ["TRANSPORTS", "Studio", "studio"]

TRANSPORTS = ("server", "auto", "widget")
"""How :func:`studio` connects the page and the session: ``server`` through a WebSocket of a server on 127.0.0.1
, ``widget`` through the Jupyter kernel's comm (no port), ``auto`` (the default) the widget where it works (a
Jupyter kernel, anywidget installed), else the server."""

START_TIMEOUT = 30.0
"""Seconds :func:`studio` waits for the server to listen."""


class Studio:
    """A studio server running in the background; see :func:`studio`.

    Attributes
    ----------
    url : str
        The page to open (``http://127.0.0.1:PORT/?token=...``); it holds the token that the server asks of every
        page and program, so share it only with whoever may edit (and read) this mesh.

    Examples
    --------
    >>> import arap
    >>> s = arap.studio(*arap.sphere(1), show=False)           # show=False: no page opened, nothing displayed
    >>> s.running, s.url.startswith("http://127.0.0.1:"), s.vertices.shape
    (True, True, (42, 3))
    >>> s.stop()
    >>> s.running
    False
    """

    def __init__(self, server: uvicorn.Server, sock: socket.socket, url: str, token: str, V: NDArray[np.float64],
                 F: NDArray[np.int64], height: int) -> None:
        self.url = url
        app: Any = server.config.app
        self._shared = app.state.studio
        self._shared.keep_latest = True
        self._token = token
        self._server = server
        self._sock = sock
        self._V = V
        self._F = F
        self._height = height
        self._thread = threading.Thread(target=self._serve, name="arap-studio", daemon=True)
        self._error: OSError | RuntimeError | SystemExit | None = None

    def _serve(self) -> None:
        try:
            self._server.run(sockets=[self._sock])
        except (OSError, RuntimeError, SystemExit) as exc:  # reported by _start(), not lost in the thread
            self._error = exc

    def _start(self) -> None:
        self._thread.start()
        deadline = time.monotonic() + START_TIMEOUT
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                self.stop()
                raise ArapError(f"the studio server did not start: {self._error!r}")
            time.sleep(0.01)

    @property
    def _session(self) -> Session | None:
        session: Session | None = self._shared.latest_session(self._token)
        return session

    @property
    def running(self) -> bool:
        """Whether the server is serving."""
        return self._thread.is_alive()

    @property
    def faces(self) -> NDArray[np.int64]:
        """(m, 3) int64 array: the triangles of the session's mesh (the mesh given to :func:`studio` until the
        user loads another one in the page)."""
        session = self._session
        if session is None or session.mesh is None:
            return self._F.copy()
        return np.array(session.mesh.F, dtype=np.int64)

    @property
    def vertices(self) -> NDArray[np.float64]:
        """(n, 3) float64 array: the current deformed shape of the most recent browser session opened with this
        handle's URL (the given mesh before any page has connected)."""
        session = self._session
        if session is None or session.mesh is None:
            return self._V.copy()
        return np.array(session.U, dtype=np.float64)

    @property
    def constraints(self) -> Selection:
        """The selection of the most recent browser session opened with this handle's URL (empty before any page
        has connected)."""
        return session_selection(self._session)

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the server and wait for its thread (open pages lose their connection); idempotent."""
        self._server.should_exit = True
        if self._thread.is_alive():
            self._thread.join(timeout)
        self._sock.close()

    def __enter__(self) -> Studio:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _repr_html_(self) -> str:
        url = html.escape(self.url, quote=True)
        if not self.running:
            served = html.escape(self.url.split("?")[0], quote=True)  # the token is of no use to anyone now
            return f"<p>ARAP Studio stopped (it served {served}).</p>"
        return (f'<iframe src="{url}" width="100%" height="{self._height}" style="border:0" '
                f'title="ARAP Studio"></iframe><p><a href="{url}" target="_blank" rel="noopener">Open the studio in '
                'a new tab</a></p>')

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped"
        return f"<arap.Studio {state} at {self.url}>"


def studio(
    V: NDArray[np.floating] | MeshLike,
    F: NDArray[np.integer] | None = None,
    *,
    name: str = "mesh",
    port: int = 0,
    show: bool = True,
    height: int = 640,
    constraints: Constraints | Mapping[str, Any] | str | os.PathLike[str] | None = None,
    transport: str = "auto",
) -> Studio | StudioWidget:
    """Serve a mesh in the studio in the background and show it inline in Jupyter.

    In a Jupyter kernel with anywidget installed (``pip install "arap[notebook]"``) the studio is by default a
    widget (:func:`arap.widget`) that talks to the kernel through its comm: it needs no port, works on remote
    kernels, Colab and VS Code, and the notebook keeps a picture of the shape when saved. Elsewhere, or with
    ``transport="server"``, a server on 127.0.0.1 serves the page, shown in an iframe (which only works where the
    browser runs on the kernel's machine) and at :attr:`Studio.url`.

    Parameters
    ----------
    V : (n, 3) float array, MeshLike, picture path or (h, w, 3|4) uint8 array
        Rest positions, or a mesh object with ``vertices`` and ``faces`` (then leave out ``F``); or a picture (a
        PNG, JPEG or WebP file, or its pixels), which opens for the puppet warp as the page's **Open file…** opens
        one: meshed, textured with itself and bent in its plane (Rigid, Normal or Distort; see
        :mod:`arap.server.pictures`). Its ``vertices`` are then ``(x, h − y, 0)`` in pixels.
    F : (m, 3) int array or None
    name : str
        Name shown in the page and used for exports (a picture file's own name by default).
    port : int
        TCP port on 127.0.0.1; 0 picks a free one.
    show : bool
        Display the page inline when running under IPython/Jupyter (an IFrame); elsewhere open :attr:`Studio.url`.
    height : int
        Height of the inline page in pixels.
    constraints : Constraints, mapping, path or None
        Initial constraints of every page opened (the ``arap deform`` format, see :func:`arap.load_constraints`):
        the page shows the anchors, region and handle groups (one group per ``handle_groups`` entry, else one),
        and the shape solved with the handles at their targets.
    transport : {"server", "auto", "widget"}
        ``server``: a server on 127.0.0.1 and an iframe; ``widget``: a Jupyter widget through the kernel's comm
        (needs anywidget; shown where the notebook shows widgets); ``auto``: the widget when ``show`` is true, no
        ``port`` is given, the code runs in a Jupyter kernel and anywidget is installed, else the server.

    Returns
    -------
    Studio or StudioWidget
        Handle with ``url`` (None for the widget), ``vertices``, ``faces``, ``constraints`` and ``stop()`` (also a
        context manager).

    Raises
    ------
    MeshError
        The mesh is unusable (as :func:`arap.check_mesh`).
    ConstraintError
        ``constraints`` is invalid for this mesh, or holds stiffness (not edited in the studio).
    ArapError
        The studio's server stack is not installed (``pip install "arap[studio]"``), or the server did not start;
        an unusable picture.
    OSError
        The port cannot be bound.

    Example
    -------
    >>> import arap
    >>> with arap.studio(*arap.builtin_mesh("bar"), show=False) as s:
    ...     print(s.url.startswith("http://127.0.0.1:"), s.running)
    True True
    """
    if transport not in TRANSPORTS:
        raise ValueError(f"transport must be one of {', '.join(TRANSPORTS)}, got {transport!r}")
    if transport == "widget" or (transport == "auto" and show and port == 0 and _widget_works()):
        from arap.jupyter_widget import widget

        w = widget(V, F, name=name, height=height, constraints=constraints)
        if show:
            _display(w)
        return w
    try:
        from arap.server.mesh_model import MeshData
        from arap.server.runner import make_server, new_token
    except ImportError as exc:
        raise ArapError(f'the studio needs its server stack: pip install "arap[studio]" ({exc.name} is missing)'
                        ) from exc
    picture = picture_input(V, F, name)
    rest: NDArray[np.float64]
    faces: NDArray[np.int64]
    if picture is not None:
        mesh, look = picture
        rest, faces = mesh.V, mesh.F
    else:
        rest, faces = check_mesh(*mesh_arrays(V, F))
        mesh, look = MeshData.make(name, rest, faces), None
    prepare = None if constraints is None else initial_constraints(constraints, len(rest))
    token = new_token()
    server, sock, url = make_server(mesh, "127.0.0.1", port, log_level="warning", token=token)
    app: Any = server.config.app
    app.state.studio.default_look = look
    if prepare is not None:
        app.state.studio.prepare_session = prepare
    handle = Studio(server, sock, url, token, rest, faces, height)
    handle._start()
    if show:
        _display(handle)
    return handle


def _widget_works() -> bool:
    """Whether :func:`arap.widget` can be shown here: a Jupyter kernel with comms, anywidget and the built module."""
    from arap.jupyter_widget import has_comm_kernel

    if not has_comm_kernel():
        return False
    try:
        import anywidget  # noqa: F401
    except ImportError:
        return False
    from arap.server.client_files import client_dir

    return (client_dir() / "widget.js").is_file()


def _display(handle: Studio | StudioWidget) -> None:
    try:
        from IPython import get_ipython
        from IPython.display import display
    except ImportError:
        return
    if get_ipython() is not None:
        display(handle)
