"""``arap studio``: serve the browser modeler, with the URL to open (and its token on a network) printed.

The server stack (starlette, uvicorn, websockets) is imported only when the studio starts: the other commands run
without it.
"""

from __future__ import annotations

import argparse
import threading

from arap.cli.common import EXIT_USAGE, err, origin_value, out, positive_int, token_value
from arap.warmup import warm_up_kernels

__all__ = ["STUDIO_EXTRA_HINT", "add_parser", "run_studio"]

STUDIO_EXTRA_HINT = "pip install 'arap[studio]'"
"""How to install the studio's server stack (starlette, uvicorn, websockets)."""


SHORT_TOKEN = 16
"""Tokens shorter than this are warned about when the studio serves a network."""
DEFAULT_MAX_EXPORT_MB = 2048
"""Default of ``--max-export-mb`` (``arap.server.app.DEFAULT_MAX_EXPORT_BYTES``, in MiB)."""


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap studio`` and its options to the subcommands of ``arap``."""
    p = commands.add_parser("studio", help="start the browser modeler",
                            description="Serve ARAP Studio; open the printed URL in a browser.")
    p.add_argument("mesh", metavar="MESH", nargs="?", default=None,
                   help="mesh every session starts with: a file, a picture (PNG, JPEG, WebP) for the puppet warp, "
                        "or a built-in name (default: the first built-in)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to bind (default: 127.0.0.1, this machine only); any other address serves the "
                        "network and requires a token")
    p.add_argument("--port", type=int, default=8000, help="TCP port (default: 8000; 0 picks a free one)")
    p.add_argument("--open", action="store_true", help="open the studio in the default browser")
    p.add_argument("--max-sessions", type=positive_int, default=32, metavar="N",
                   help="most sessions (browser tabs) at once; more are refused (default: 32)")
    p.add_argument("--max-export-mb", type=positive_int, default=DEFAULT_MAX_EXPORT_MB, metavar="MB",
                   help="memory the animation exports of all sessions may take at once: a larger export is refused, "
                        f"one that does not fit beside those running waits (default: {DEFAULT_MAX_EXPORT_MB})")
    p.add_argument("--allow-origin", action="append", default=[], type=origin_value, metavar="ORIGIN",
                   help="let pages from ORIGIN (http(s)://host[:port]) use the studio; repeatable (default: only "
                        "the studio's own pages)")
    p.add_argument("--token", type=token_value, default=None, metavar="TOKEN",
                   help="secret every page and client must present (?token=TOKEN in the printed URL); default: a "
                        "random one when --host is not a loopback address, none on this machine only")
    p.set_defaults(func=run_studio)


def run_studio(args: argparse.Namespace) -> int:
    """``arap studio``: serve until Ctrl-C; the exit status (2 when the server stack is not installed)."""
    try:
        import starlette  # noqa: F401
        import uvicorn  # noqa: F401
        import websockets  # noqa: F401

        from arap.server import serve
    except ImportError as exc:
        missing = exc.name or ""
        if missing.split(".")[0] in ("", "arap"):
            raise
        err(f"arap: error: the studio needs its server packages, and {missing} is not installed: "
            f"{STUDIO_EXTRA_HINT}")
        return EXIT_USAGE
    from arap.server.guard import is_loopback_host

    if args.token is not None and len(args.token) < SHORT_TOKEN and not is_loopback_host(args.host):
        err(f"arap: warning: a token of {len(args.token)} characters is easy to guess on a network; leave --token out "
            f"for a random one, or give at least {SHORT_TOKEN} characters (wrong tokens are refused for a minute "
            "after ten from one address)")
    _warm_up_behind()  # the page is served at once; the kernels compile (first run) or load meanwhile

    def announce(url: str) -> None:
        if is_loopback_host(args.host):
            out(f"ARAP Studio running at {url}  (Ctrl-C to stop)")
            return
        network = _network_url(url, args.host)
        out(f"ARAP Studio serving the network at {network}  (Ctrl-C to stop)")
        if network != url:
            out(f"  on this machine: {url}")
        out("  The token in this URL is required: requests without it are refused. Anyone who has the URL can use "
            "the studio and read its meshes; share it only with them, and stop the studio when done "
            "(plain HTTP: the network can see it).")

    try:
        serve(args.mesh, host=args.host, port=args.port, open_browser=args.open, max_sessions=args.max_sessions,
              allow_origins=args.allow_origin, on_ready=announce, token=args.token,
              max_export_bytes=args.max_export_mb * 2**20)
    except KeyboardInterrupt:
        err("stopped")
    return 0


def _warm_up_behind() -> threading.Thread:
    """Compile (first run) or load the kernels on a thread of their own while the server starts and serves the page;
    a session that needs them first waits for the compilation (numba compiles one kernel at a time). Says so when it
    compiles."""
    from arap.solve.kernel_cache import first_compile_pending
    from arap.warmup import FIRST_KERNELS, KERNELS_READY, LATER_KERNELS

    if first_compile_pending():
        err(f"arap: compiling the solver's {len(FIRST_KERNELS) + len(LATER_KERNELS)} kernels in the background (first "
            "run only: from ten seconds to a few minutes on a busy machine; progress follows); the page is served "
            f"meanwhile, shows the progress, and can edit once the first {len(FIRST_KERNELS)} are ready")
    KERNELS_READY.clear()  # the server greets connections once the kernels a session needs first are ready

    def run() -> None:
        try:
            warm_up_kernels(quiet=False, first_ready=KERNELS_READY.set)
        except Exception as exc:  # noqa: BLE001 - a failed warm-up only delays the first solve, which compiles itself
            err(f"arap: the kernels were not compiled ahead ({type(exc).__name__}: {exc}); the first solve will")
        finally:
            KERNELS_READY.set()

    thread = threading.Thread(target=run, name="arap-kernel-warm-up", daemon=True)
    thread.start()
    return thread


def _network_url(url: str, host: str) -> str:
    """The studio's URL as other machines reach it: for a wildcard address (whose ``url`` names loopback), this
    machine's address on its default route, when one is found."""
    import socket
    from urllib.parse import urlsplit, urlunsplit

    bound = host.strip("[]")
    if bound not in ("", "0.0.0.0", "::"):
        return url
    family, probe = (socket.AF_INET6, "2001:db8::1") if bound == "::" else (socket.AF_INET, "192.0.2.1")
    try:
        with socket.socket(family, socket.SOCK_DGRAM) as s:
            s.connect((probe, 9))  # no packet is sent: this only picks the outgoing interface
            address = str(s.getsockname()[0])
    except OSError:
        return url
    if address.startswith(("127.", "::1")) or address in ("0.0.0.0", "::"):
        return url
    parts = urlsplit(url)
    netloc = f"[{address}]" if ":" in address else address
    return urlunsplit(parts._replace(netloc=f"{netloc}:{parts.port}"))
