"""``arap batch``: run the deformations of a JSON Lines manifest on a process pool, Ray or Dask
(:mod:`arap.batching`)."""

from __future__ import annotations

import argparse

from arap.cli.common import EXIT_BAD_INPUT, err, out, positive_int
from arap.warmup import warm_up_kernels

__all__ = ["add_parser", "run_batch"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap batch`` and its options to the subcommands of ``arap``."""
    from arap.batching import BACKENDS

    p = commands.add_parser(
        "batch", help="run many deformations from a manifest",
        description="Run the deformations of MANIFEST.jsonl, one JSON object a line: {\"mesh\": ..., \"constraints\": "
                    "..., \"output\": ...} and optionally \"energy\", \"weights\", \"alpha\", \"tolerance\", "
                    "\"max_iterations\" (paths relative to the manifest). Jobs sharing a mesh and a constraint set "
                    "share one factorisation; finished outputs are skipped, so a second run completes the first. Every "
                    "job's files are checked before the workers start, output folders are made, and a job another "
                    "batch is running is left to it.")
    p.add_argument("manifest", metavar="MANIFEST.jsonl")
    p.add_argument("--backend", choices=BACKENDS, default="process",
                   help="where the jobs run (default: process, a pool on this machine; ray and dask need "
                        "arap[ray] or arap[dask])")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="worker processes (default: the machine's cores)")
    p.add_argument("--address", default=None,
                   help="a running cluster instead of a local one: Ray's ray://HOST:10001 or auto, Dask's "
                        "tcp://HOST:8786")
    p.add_argument("--force", action="store_true", help="run the jobs whose output exists too")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar; only failures and the summary")
    p.set_defaults(func=run_batch)


def run_batch(args: argparse.Namespace) -> int:
    """``arap batch``: 0 when every job was done or skipped, 1 when one failed."""
    from arap.batching import batch

    warm_up_kernels(args.quiet)
    report = batch(args.manifest, backend=args.backend, workers=args.workers, address=args.address,
                   skip_existing=not args.force, progress=not args.quiet)
    if report.failed and len(report.preflight_failed) == len(report.outcomes):
        reasons = {o.reason for o in report.failed}
        if len(reasons) == 1:  # every job fails alike (a missing mesh, say): one line
            err(f"arap: {args.manifest}: every job fails the pre-flight check, no worker started: {reasons.pop()}")
            return EXIT_BAD_INPUT
    for o in report.failed:
        err(f"arap: {args.manifest}, line {o.line}: {o.reason}")
    out(f"arap batch: {report.summary()}")
    return EXIT_BAD_INPUT if report.failed else 0
