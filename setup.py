"""Packaging hook: build the studio's browser client (``web/``, Vite) into ``src/arap/static`` before packaging.

The metadata lives in ``pyproject.toml``; this file only adds the client build to ``build_py`` (wheels) and
``sdist``. The build runs ``npm ci`` (when ``web/node_modules`` does not match ``web/package-lock.json``) and
``npm run build``, and records a hash of the ``web/`` sources next to the built client, so an up-to-date client
(for instance the one an sdist carries) is not built again and needs no Node.js. Editable installs skip the build
(``./dev setup`` builds the client in a checkout). ``ARAP_SKIP_CLIENT_BUILD=1`` packages without building it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist
from setuptools.errors import SetupError

ROOT = Path(__file__).resolve().parent
WEB = ROOT / "web"
STATIC = ROOT / "src" / "arap" / "static"
SOURCE_HASH = STATIC / ".source-hash"
"""Hash of the ``web/`` sources the client in ``src/arap/static`` was built from (carried by the sdist)."""


def _log(message: str) -> None:
    print(f"arap build: {message}", flush=True)  # noqa: T201 - build output


def web_sources_hash() -> str:
    """SHA-256 over the relative paths and contents of every file under ``web/`` except ``node_modules``."""
    digest = hashlib.sha256()
    files = sorted(p for p in WEB.rglob("*") if p.is_file() and "node_modules" not in p.relative_to(WEB).parts)
    for path in files:
        digest.update(path.relative_to(WEB).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def _npm(*args: str) -> None:
    npm = shutil.which("npm")
    if npm is None:
        raise SetupError(
            "building the studio client needs Node.js >= 20 with npm, which is not on PATH. Install Node.js, or "
            "set ARAP_SKIP_CLIENT_BUILD=1 to build a package without the browser client (`arap studio` will then "
            "say that the client is missing)."
        )
    _log(f"npm {' '.join(args)} (in web/)")
    subprocess.run([npm, *args], cwd=WEB, check=True)


def build_client() -> None:
    """Build the client into ``src/arap/static`` unless it is already built from the current ``web/`` sources."""
    if os.environ.get("ARAP_SKIP_CLIENT_BUILD", "") not in ("", "0"):
        _log("ARAP_SKIP_CLIENT_BUILD is set: packaging without building the studio client")
        return
    built = (STATIC / "index.html").is_file()
    if not (WEB / "package.json").is_file():
        if built:
            _log("no web/ sources here; packaging the studio client already in src/arap/static")
        else:
            _log("WARNING: no web/ sources and no built client: the package will have no studio client")
        return
    want = web_sources_hash()
    have = SOURCE_HASH.read_text().strip() if SOURCE_HASH.is_file() else ""
    if built and have == want:
        _log("studio client already built and up to date (src/arap/static); skipping the Node.js build")
        return
    lock_stamp = WEB / "node_modules" / ".stamp"
    lock_hash = hashlib.sha256((WEB / "package-lock.json").read_bytes()).hexdigest()[:16]
    if not lock_stamp.is_file() or lock_stamp.read_text().strip() != lock_hash:
        _npm("ci", "--no-audit", "--no-fund", "--loglevel=error")
        lock_stamp.write_text(lock_hash + "\n")
    _npm("run", "--silent", "build")
    if not (STATIC / "index.html").is_file():
        raise SetupError(f"the client build wrote no index.html into {STATIC}")
    SOURCE_HASH.write_text(want + "\n")


class BuildPyWithClient(build_py):
    """``build_py`` that builds the browser client first (not for editable installs)."""

    def run(self) -> None:
        if getattr(self, "editable_mode", False):
            _log("editable install: the studio client is served from src/arap/static (built by ./dev setup)")
        else:
            build_client()
        super().run()


class SdistWithClient(sdist):
    """``sdist`` that carries the built client (and its source hash) next to the ``web/`` sources."""

    def run(self) -> None:
        build_client()
        super().run()


setup(cmdclass={"build_py": BuildPyWithClient, "sdist": SdistWithClient})
