"""Independent work items in worker processes (``frictid fit --jobs`` and ``frictid report --jobs``), and
background threads that prepare what the workers need.

:func:`map_ordered` runs ``[fn(x) for x in items]`` in a :class:`concurrent.futures.ProcessPoolExecutor`
started with the ``fork`` method: the workers inherit ``fn`` and ``items`` (closures over logs already
read, and whatever the caller patched), so nothing large is pickled on the way in; each result comes
back pickled. The results come in the items' order and do not depend on the number of workers; an
exception raised for an item reaches the caller as the same class with the same message (the exception
pickles itself, :mod:`frictid.errors`), the first failing item in order winning, as in a loop. Ctrl-C or
SIGTERM in the caller stops the workers.

This module imports only :mod:`frictid.errors` from frictid. It leaves no process-wide state changed: no
allocator, environment or garbage-collector settings; Ctrl-C and SIGTERM are only held back while the
workers are forked (then handled as before).
"""
from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import threading
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from typing import Any, Callable, Iterable, Sequence

from .errors import FrictidInputError

#: Ctrl-C and SIGTERM: held back while the workers are forked; a worker ignores the first, dies on the second.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)

#: In a worker process only: the function and items it inherited, and its BLAS thread limit.
_inherited: dict[str, Any] = {}


def n_workers(jobs: int | None, n_items: int) -> int:
    """Worker processes for ``n_items`` items: ``jobs`` (0: the cores this process may run on), at most one
    per item; 1 (run in this process) where processes cannot be forked."""
    if jobs is None or int(jobs) < 0:
        raise FrictidInputError(f"--jobs {jobs}: give 0 (one per core) or a positive number of processes")
    jobs = int(jobs)
    if jobs == 0:
        try:
            jobs = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            jobs = os.cpu_count() or 1
    if "fork" not in mp.get_all_start_methods():  # pragma: no cover - Windows
        return 1
    return max(1, min(jobs, n_items))


def map_ordered(fn: Callable, items: Sequence, workers: int) -> list:
    """``[fn(x) for x in items]``, run in ``workers`` processes (in this one when ``workers`` <= 1, when
    there is one item, or when other threads run: a fork copies the locks they hold, and a worker could
    wait on one for ever). ``fn`` may be a closure: it is inherited, never pickled."""
    items = list(items)
    if workers <= 1 or len(items) <= 1 or threading.active_count() > 1:
        return [fn(x) for x in items]
    before = set(mp.active_children())
    pool = ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=mp.get_context("fork"),
                               initializer=_start_worker, initargs=(fn, items))
    ours: list = []
    try:
        with _signals_deferred():  # the first submit forks every worker
            futures = [pool.submit(_run, k) for k in range(len(items))]
        ours = [p for p in mp.active_children() if p not in before]
        out = [f.result() for f in futures]
    except BaseException:
        # an error, Ctrl-C or SIGTERM: stop the other items now instead of waiting for them (killed: a
        # worker holds nothing to clean up, and one still starting could not take a SIGTERM yet)
        for proc in ours or [p for p in mp.active_children() if p not in before]:
            proc.kill()
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    pool.shutdown(wait=True)
    return out


@contextlib.contextmanager
def _signals_deferred():
    """Ctrl-C and SIGTERM received inside the block are raised again, with the handlers of before, when it
    ends: the workers forked inside it are all known (to be stopped) before this process acts on them, and a
    worker is born with handlers that only note them until it sets its own (:func:`_start_worker`). Only in
    the main thread (elsewhere Python cannot set handlers, and nothing is deferred)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    before = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in STOP_SIGNALS}
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(got):
            signal.raise_signal(s)


def one_blas_thread():
    """A context holding BLAS to one thread (``threadpoolctl``) for work whose matrix products are small or
    thin (the diagnosis' blocks of 4 096 samples, the robot regressor's least squares): more threads gave
    nothing there, and on a loaded machine they spun for most of their CPU time. Without threadpoolctl BLAS
    keeps its own count."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional, as in the workers (:func:`_start_worker`)
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _start_worker(fn: Callable, items: list) -> None:
    """A worker's start: it keeps the inherited ``fn`` and ``items``, ignores Ctrl-C (the caller stops the
    workers and reports the interruption once), dies on SIGTERM (not the caller's handler) and uses one BLAS
    thread (the items already share the cores)."""
    _inherited.update(fn=fn, items=items)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: without it BLAS keeps its own thread count
        return
    _inherited["blas_limit"] = threadpool_limits(limits=1, user_api="blas")


def _run(k: int):
    """Item ``k`` of what the worker inherited."""
    return _inherited["fn"](_inherited["items"][k])


class Prefetch:
    """Work that does not depend on the logs' contents, started in background threads while the caller
    reads or plans the logs: ``digest(path)`` of every path (e.g. a file's SHA-256) and ``preload()`` (the
    imports the workers will need, done once before they are forked). Reading, hashing and importing then
    overlap. :meth:`hashes` waits for both, so that no thread is left running when workers are forked."""

    def __init__(self, paths: Iterable[str], digest: Callable[[str], str | None],
                 preload: Callable[[], None] | None = None):
        self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="frictid-prefetch")
        if preload is not None:  # an import error surfaces when the import is used
            self._pool.submit(preload)
        self._hashes = {str(p): self._pool.submit(digest, str(p)) for p in dict.fromkeys(paths) if p != "-"}

    def hashes(self) -> dict[str, str | None]:
        """Each path's digest (waits for them and for the imports). A file that could not be read is left
        out: its reading reports the problem."""
        self._pool.shutdown(wait=True)
        out = {}
        for p, f in self._hashes.items():
            try:
                out[p] = f.result()
            except OSError:
                pass
        return out
