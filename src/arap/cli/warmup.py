"""``arap warmup``: compile the solver's kernels now (or load them from the cache) and say where they are kept."""

from __future__ import annotations

import argparse

from arap.cli.common import out

__all__ = ["add_parser", "run_warmup"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap warmup`` to the subcommands of ``arap``."""
    p = commands.add_parser("warmup", help="compile the solver's kernels ahead of the first use",
                            description="Compile the solver's kernels for this environment (the first run of arap "
                                        "does it otherwise, for tens of seconds to minutes), or load them from the "
                                        "cache: those of every energy and acceleration, for surfaces, planar "
                                        "meshes and tetrahedra, serial and threaded. Says how many are ready, by "
                                        "name, while it compiles.")
    p.set_defaults(func=run_warmup)


def run_warmup(args: argparse.Namespace) -> int:
    """``arap warmup``: 0."""
    from arap.warmup import compile_reporter, warm_up_kernels

    warm = warm_up_kernels(progress=compile_reporter(), every_energy=True)
    where = f" (cached in {warm.cache_dir})" if warm.cache_dir else " (caching is off: NUMBA_DISABLE_JIT or no cache)"
    if warm.compiled:
        out(f"arap: compiled {warm.compiled} kernels in {warm.seconds:.1f} s{where}")
    else:
        out(f"arap: kernels ready, loaded from the cache in {warm.seconds:.1f} s{where}")
    return 0
