"""A writable cache folder for the compiled kernels.

Every kernel is compiled with ``cache=True``, and numba picks the cache folder when a kernel is defined: the
package's ``__pycache__`` when writable, else the user's cache folder. Where neither is writable (a read-only
installation and home), defining a cached kernel would fail on import, so ``NUMBA_CACHE_DIR`` then points at a
per-user temporary folder. This module is imported by the kernel modules before they define their kernels.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numba


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError:
        return False
    return True


def ensure_writable_cache(candidates: tuple[Path, ...] | None = None) -> str | None:
    """Point ``NUMBA_CACHE_DIR`` at a temporary folder when numba would have nowhere to cache the kernels.

    Parameters
    ----------
    candidates : tuple of Path or None
        The folders numba would use (default: the package's ``__pycache__`` and numba's user cache folder).

    Returns
    -------
    str or None
        The folder set, or None when ``NUMBA_CACHE_DIR`` was already set or a candidate is writable.
    """
    if getattr(numba.config, "CACHE_DIR", ""):  # set from NUMBA_CACHE_DIR when numba starts
        return None
    if candidates is None:
        from numba.misc.appdirs import AppDirs

        candidates = (Path(__file__).resolve().parent / "__pycache__",
                      Path(AppDirs(appname="numba", appauthor=False).user_cache_dir))
    if any(_writable(folder) for folder in candidates):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else 0
    folder = str(Path(tempfile.gettempdir()) / f"arap-numba-cache-{uid}")
    os.environ["NUMBA_CACHE_DIR"] = folder
    numba.config.reload_config()
    return folder


ensure_writable_cache()
