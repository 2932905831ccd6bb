"""Handing freed memory back to the operating system."""

from __future__ import annotations

import ctypes
import ctypes.util
import gc
from collections.abc import Callable

__all__ = ["release_memory"]

_trim: Callable[[int], int] | None = None
_looked_up = False


def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None where the C library has none (macOS, Windows, musl)."""
    global _trim, _looked_up
    if not _looked_up:
        _looked_up = True
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            _trim = libc.malloc_trim
        except (OSError, AttributeError, TypeError):
            _trim = None
    return _trim


def release_memory() -> None:
    """Collect garbage and return freed heap pages to the operating system (glibc's ``malloc_trim``, where present).

    Large NumPy arrays are returned by ``free`` at once, but the many mid-sized blocks of a session (factor, cells,
    history) and of a decoded message stay in the allocator's arenas; without trimming, a server that served many
    sessions keeps their peak.
    """
    gc.collect()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)
