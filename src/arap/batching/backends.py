"""Where batch chunks run: this process, a process pool, Ray tasks or Dask tasks.

Each backend runs :func:`arap.batching.worker.run_chunk` on every chunk and gathers the outcomes as chunks finish,
advancing a progress bar. Workers on this machine get ``cores / workers`` threads each (at least one), so that the
kernels of workers side by side do not fight over the cores. A chunk whose worker dies (killed for memory, say)
fails its jobs with that reason; the other chunks go on. Ray and Dask are optional (``arap[ray]``, ``arap[dask]``)
and are imported only when asked for.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from contextlib import contextmanager
from typing import Any

from arap.batching.jobs import Job, JobOutcome
from arap.batching.worker import environment, run_chunk, start_worker, worker_environment
from arap.errors import OptionError

__all__ = ["BACKENDS", "run_chunks"]

BACKENDS = ("process", "ray", "dask", "serial")
"""Backend names of :func:`arap.batch` and ``arap batch --backend``."""


def _crashed(chunk: list[Job], exc: BaseException) -> list[JobOutcome]:
    reason = f"the worker running it ended: {type(exc).__name__}: {exc}"[:500]
    return [JobOutcome(line=j.line, output=j.output, status="failed", reason=reason) for j in chunk]


@contextmanager
def _bar(total: int, enabled: bool) -> Iterator[Callable[[list[JobOutcome]], None]]:
    from tqdm import tqdm

    # On a terminal only (tqdm's None), so that logs and captured output get no bar.
    with tqdm(total=total, disable=None if enabled else True, unit="job", desc="arap batch", dynamic_ncols=True) as bar:
        def update(outcomes: list[JobOutcome]) -> None:
            bar.update(len(outcomes))
            failed = sum(o.status == "failed" for o in outcomes)
            if failed:
                bar.set_postfix_str(f"{failed} failed", refresh=False)
        yield update


def _threads(workers: int) -> dict[str, str]:
    return worker_environment((os.cpu_count() or 1) // max(workers, 1))


def _serial(chunks: list[list[Job]], skip_existing: bool,
            update: Callable[[list[JobOutcome]], None]) -> list[JobOutcome]:
    outcomes: list[JobOutcome] = []
    for chunk in chunks:
        done = run_chunk(chunk, skip_existing)
        update(done)
        outcomes += done
    return outcomes


def _process(chunks: list[list[Job]], workers: int, skip_existing: bool,
             update: Callable[[list[JobOutcome]], None]) -> list[JobOutcome]:
    # "spawn": a fresh interpreter per worker, never a fork of a process whose kernel threads are running. Each worker
    # ends with this process, even when it is killed, and stops its job when this process sets ``stop`` (start_worker).
    count = min(workers, len(chunks))
    outcomes: list[JobOutcome] = []
    context = multiprocessing.get_context("spawn")
    stop = context.Event()
    pool = ProcessPoolExecutor(max_workers=count, mp_context=context, initializer=start_worker,
                               initargs=(os.getpid(), stop))
    try:
        # The workers start inside, with these thread counts and ignoring Ctrl-C: one ended by a Ctrl-C while it
        # started would break the pool, which then kills the other workers in the middle of their jobs, leaving their
        # lock and temporary files. This process stops them instead (``stop``).
        with environment(_threads(count)), _interrupts_ignored():
            pending: dict[Future[list[JobOutcome]], list[Job]] = {
                pool.submit(run_chunk, c, skip_existing): c for c in chunks}
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                chunk = pending.pop(future)
                try:
                    done = future.result()
                except Exception as exc:  # noqa: BLE001 - a dead worker fails its chunk, not the batch
                    done = _crashed(chunk, exc)
                update(done)
                outcomes += done
    except BaseException:
        # Interrupted (a Ctrl-C, or a SIGINT to this process alone): each worker ends its job under way at the end of
        # a solver iteration, nothing written, and takes no other chunk; this process waits for them, so that no job
        # is left half done (a worker ends with this process).
        stop.set()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown()
    return outcomes


@contextmanager
def _interrupts_ignored() -> Iterator[None]:
    """SIGINT ignored for the block, where the main thread has Python's handler: the processes started inside begin
    with it ignored (an ignored signal stays ignored in a new program). This process misses a Ctrl-C in the block, the
    milliseconds that starting the workers takes."""
    if threading.current_thread() is not threading.main_thread() or not callable(signal.getsignal(signal.SIGINT)):
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _ray(chunks: list[list[Job]], workers: int, address: str | None, skip_existing: bool,
         update: Callable[[list[JobOutcome]], None]) -> list[JobOutcome]:
    try:
        import ray
    except ImportError:
        raise OptionError("the ray backend needs Ray: pip install 'arap[ray]'") from None
    started = not ray.is_initialized()
    if started:
        options: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False,
                                   "runtime_env": {"env_vars": _threads(workers)}}
        if address is None:
            options["num_cpus"] = workers
        ray.init(address=address, **options)
    try:
        remote: Any = ray.remote(num_cpus=1, max_retries=0)(run_chunk)
        pending = {remote.remote(c, skip_existing): c for c in chunks}
        outcomes: list[JobOutcome] = []
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                chunk = pending.pop(ref)
                try:
                    done = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a dead worker fails its chunk, not the batch
                    done = _crashed(chunk, exc)
                update(done)
                outcomes += done
        return outcomes
    finally:
        if started:
            ray.shutdown()


def _dask(chunks: list[list[Job]], workers: int, address: str | None, skip_existing: bool, quiet: bool,
          update: Callable[[list[JobOutcome]], None]) -> list[JobOutcome]:
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise OptionError("the dask backend needs Dask's distributed scheduler: pip install 'arap[dask]'") from None
    level = logging.ERROR if quiet else logging.WARNING
    with _log_level(_DASK_LOGGERS, level):
        return _dask_run(chunks, workers, address, skip_existing, level, update, Client, LocalCluster, as_completed)


_DASK_LOGGERS = ("distributed", "bokeh", "tornado")
"""Loggers of Dask's distributed scheduler and what it runs on; their info lines (the cluster starting, every worker
and connection) are not shown."""


@contextmanager
def _log_level(names: tuple[str, ...], level: int) -> Iterator[None]:
    """Loggers ``names`` set to ``level`` at least for the block."""
    loggers = [logging.getLogger(name) for name in names]
    saved = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(max(level, lg.getEffectiveLevel()))
    try:
        yield
    finally:
        for lg, value in zip(loggers, saved, strict=True):
            lg.setLevel(value)


def _dask_run(chunks: list[list[Job]], workers: int, address: str | None, skip_existing: bool, level: int,
              update: Callable[[list[JobOutcome]], None], Client: Any, LocalCluster: Any,
              as_completed: Any) -> list[JobOutcome]:
    cluster = None
    if address is None:
        with environment(_threads(workers)):
            # silence_logs: the level of the cluster's loggers, in the worker processes too
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, silence_logs=level,
                                   dashboard_address=None)
    client = Client(address if address is not None else cluster)
    try:
        futures = client.map(run_chunk, chunks, skip_existing=skip_existing, pure=False, retries=0)
        chunk_of = {f.key: c for f, c in zip(futures, chunks, strict=True)}
        outcomes: list[JobOutcome] = []
        for future in as_completed(futures):
            try:
                done = future.result()
            except Exception as exc:  # noqa: BLE001 - a dead worker fails its chunk, not the batch
                done = _crashed(chunk_of[future.key], exc)
            update(done)
            outcomes += done
        return outcomes
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def run_chunks(chunks: list[list[Job]], backend: str, workers: int, address: str | None, progress: bool,
               total: int, skip_existing: bool = True) -> list[JobOutcome]:
    """Run every chunk on ``backend`` with ``workers`` workers; the outcomes of all their jobs. Without ``progress``,
    the cluster backends log nothing but errors either."""
    if not chunks:
        return []
    with _bar(total, progress) as update:
        if backend == "serial":
            return _serial(chunks, skip_existing, update)
        if backend == "process":
            return _process(chunks, workers, skip_existing, update)
        if backend == "ray":
            return _ray(chunks, workers, address, skip_existing, update)
        if backend == "dask":
            return _dask(chunks, workers, address, skip_existing, not progress, update)
    raise OptionError(f"unknown backend {backend!r}; expected one of {BACKENDS}")
