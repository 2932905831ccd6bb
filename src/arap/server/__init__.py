"""ARAP Studio: a browser modeler served over a WebSocket (protocol in ``docs/protocol.md``).

>>> from arap.server import serve, studio_url
>>> serve("bunny.obj", port=8000, on_ready=print)   # doctest: +SKIP

Names are imported on first use, so ``python -m arap.server.protocol`` does not load the web stack.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__all__ = ["bind_socket", "create_app", "make_server", "serve", "studio_url"]

_LAZY = {
    "create_app": "arap.server.app",
    "bind_socket": "arap.server.runner",
    "make_server": "arap.server.runner",
    "serve": "arap.server.runner",
    "studio_url": "arap.server.runner",
}

if TYPE_CHECKING:
    from arap.server.app import create_app
    from arap.server.runner import bind_socket, make_server, serve, studio_url


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'arap.server' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
