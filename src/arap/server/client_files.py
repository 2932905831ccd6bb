"""Where the built browser client lies (the studio's page and the notebook widget's module) and what to do when it is
missing. Nothing of the web stack is imported here, so the notebook widget, which reads the module from this folder,
needs neither starlette nor uvicorn."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["CLIENT_ENV", "STATIC_DIR", "client_dir", "client_missing_advice"]

STATIC_DIR = Path(__file__).resolve().parent.parent / "static"
"""The built client: packaged in the wheel, or built there by ``./dev setup`` (``npm run build`` in ``web/``)."""
CLIENT_ENV = "ARAP_STUDIO_CLIENT"
"""Environment variable naming another built client to serve, e.g. the browser tests' build with their hook
(``npm run build:e2e`` in ``web/``, into ``build/studio-e2e``)."""


def client_dir() -> Path:
    """The folder of the client the studio serves and the widget loads: :data:`STATIC_DIR`, unless
    :data:`CLIENT_ENV` names another."""
    other = os.environ.get(CLIENT_ENV)
    return Path(other) if other else STATIC_DIR


def client_missing_advice(static_dir: Path = STATIC_DIR) -> str | None:
    """None when the built client is in ``static_dir``; else what is missing and what to do, for this install.

    A repository checkout (``web/`` beside ``src/``) builds it with ``./dev setup``; an installed package was built
    without it (no Node.js at build time) and needs a package that carries it.
    """
    if (static_dir / "index.html").is_file():
        return None
    missing = f"The studio's browser client is missing: no index.html in {static_dir}."
    root = STATIC_DIR.parents[2]
    if (root / "web" / "package.json").is_file():
        return f"{missing} Build it with ./dev setup in {root} (Node.js >= 20 with npm), then reload the page."
    return (f"{missing} This installation of arap was built without it (Node.js was not available when its wheel "
            "was built). Install a package that includes it, e.g. pip install --force-reinstall 'arap[studio]' "
            "from PyPI, or build the wheel from the source with Node.js >= 20 and npm on PATH.")
