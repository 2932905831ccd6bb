"""Whether the solver's compiled kernels are cached for this environment: what the first solver announces.

numba keeps each kernel's machine code in an index and data files beside the module (``__pycache__``), in the user's
cache folder, or in ``NUMBA_CACHE_DIR`` (see :mod:`arap.warmup`); an environment without the index compiles on first
use.
"""

from __future__ import annotations

import logging
import os

__all__ = ["announce_first_compile", "first_compile_pending"]

logger = logging.getLogger("arap")

_announced = False


def first_compile_pending() -> bool:
    """True when this environment has no cached machine code for the solver's kernels yet, so that the first solve
    compiles them (ten seconds to minutes); False when they are cached, or when that cannot be told."""
    try:
        from arap.method.local_step import _local_serial

        index = _local_serial._cache._cache_file._index_path  # type: ignore[attr-defined]
    except (AttributeError, ImportError):  # caching off, or another numba layout: nothing to say
        return False
    return not os.path.exists(index)


def announce_first_compile() -> None:
    """Say once per process, as a logging warning of the ``arap`` logger, that the kernels are about to be compiled,
    when they are (:func:`first_compile_pending`): otherwise the first solver of a new environment takes tens of
    seconds without a word. ``arap warmup`` compiles them ahead."""
    global _announced
    if _announced:
        return
    _announced = True
    if first_compile_pending():
        logger.warning("compiling the solver's kernels for this environment (first run only: from ten seconds to "
                       "a few minutes on a busy machine; 'arap warmup' does it ahead and shows its progress)")
