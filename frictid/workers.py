"""Independent per-joint work in forked worker processes (``frictid fit`` and ``frictid report``).

The workers are forked (``concurrent.futures.ProcessPoolExecutor`` with the ``fork`` start method): they
inherit the logs already read and the function to run copy-on-write, so nothing large is pickled on the
way in; only each result comes back pickled. Results come in the items' order and do not depend on the
number of workers; an exception raised for an item is raised again in the parent as the same class with
the same message (the first failing item in order wins, as a loop would), and Ctrl-C or SIGTERM in the
parent stops the workers at once.
"""
from __future__ import annotations

import contextlib
import functools
import gc
import os
import pickle
import signal
import threading
from typing import Any, Callable, Iterable, Sequence

from .errors import FrictidInputError

#: What the forked workers inherit: the function and the items (set only while a pool runs).
_TASK: dict[str, Any] = {}


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
    import multiprocessing as mp

    if "fork" not in mp.get_all_start_methods():  # pragma: no cover - Windows
        return 1
    return max(1, min(jobs, n_items))


def map_forked(fn: Callable, items: Sequence, workers: int) -> list:
    """``[fn(x) for x in items]``, run in ``workers`` forked processes (in this one when ``workers`` <= 1
    or there is one item). ``fn`` may be a closure: it is inherited, never pickled."""
    items = list(items)
    if workers <= 1 or len(items) <= 1 or threading.active_count() > 1:
        # a fork copies the locks other threads hold, locked, and the child may wait on one forever (the
        # manager thread of a pool stopped without waiting, a caller's threads): fork only a lone thread
        return [fn(x) for x in items]
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    _TASK.update(fn=fn, items=items, parent=os.getpid())
    before = set(mp.active_children())
    # the objects that exist now are left out of the workers' garbage collections: a collection writes
    # to every object it visits, and each page written is copied from the parent (a worker's first item
    # cost about a second of system time more without this)
    gc.freeze()
    _release_free_heap()
    pool = ProcessPoolExecutor(max_workers=min(workers, len(items)), mp_context=mp.get_context("fork"),
                               initializer=_worker_init)
    ours: list = []
    try:
        # the workers are forked by the first submit; Ctrl-C or SIGTERM meanwhile is held back until every
        # worker is known to the pool (stopped below) and has its own handling (no worker's traceback)
        with _signals_deferred():
            futures = [pool.submit(_call, k) for k in range(len(items))]
        ours = [p for p in mp.active_children() if p not in before]
        out = []
        for fut in futures:
            status, value = fut.result()
            if status == "error":
                raise _rebuild_exception(value)
            out.append(value)
        pool.shutdown(wait=True)
        return out
    except BaseException:
        # an error, Ctrl-C or SIGTERM: stop the other items now instead of waiting for them
        ours = ours or [p for p in mp.active_children() if p not in before]
        for proc in ours:
            proc.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        gc.unfreeze()
        _TASK.clear()
        _reap(ours)


def _release_free_heap() -> None:
    """Give the pages of this process's freed heap memory back to the system before forking (glibc's
    ``malloc_trim``; nothing elsewhere). A worker's allocator hands out the chunks freed here first: kept,
    each page it writes there is copied from this process's (copy-on-write) instead of given fresh, and a
    copy costs more than a zeroed page. The report's parent holds 30-40 MB of such chunks at the fork (the
    parameter file parsed, the joint column read); trimmed, a worker's first joint took 0.49-0.81 s of
    system time instead of 0.63-1.65 s in three alternating pairs (docs/benchmarks.md, session 7)."""
    trim = _libc("malloc_trim")
    if trim is not None:  # nothing elsewhere than glibc
        trim(0)


def _reap(procs) -> None:
    """Wait for the pool's processes and kill any still alive. A worker terminated while it held the pool's
    queue lock leaves a sibling waiting on that lock for ever, and the interpreter's exit would then wait
    for the sibling (seen once in a test run: pytest hung after its last test)."""
    for proc in procs:
        proc.join(timeout=2.0)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout=2.0)


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT and SIGTERM received inside the block are raised again, with the handlers of before, when it
    ends (main thread only: elsewhere Python cannot set handlers, and nothing is deferred)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    sigs = (signal.SIGINT, signal.SIGTERM)
    before = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in sigs}
    try:
        yield
    finally:
        for s, h in before.items():
            signal.signal(s, h)
        for s in dict.fromkeys(got):
            signal.raise_signal(s)


def _worker_init() -> None:
    """A worker: one BLAS thread (the items already share the cores), no Ctrl-C or SIGTERM handling of its
    own (the parent stops the workers and reports an interruption once), and stopped with its parent
    (a worker left waiting on the pool's queue would wait forever)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    prctl = _libc("prctl")
    if prctl is not None:  # Linux
        prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    if os.getppid() != _TASK.get("parent"):  # the parent died before the line above
        os._exit(1)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: without it BLAS keeps its own thread count
        return
    _TASK["blas_limit"] = threadpool_limits(limits=1, user_api="blas")


def _call(k: int):
    """Item ``k`` of the inherited task: ("ok", result) or ("error", the exception as data)."""
    try:
        return "ok", _TASK["fn"](_TASK["items"][k])
    except Exception as exc:  # noqa: BLE001 - raised again, as the same class, in the parent
        return "error", _exception_data(exc)


def _exception_data(exc: BaseException) -> tuple:
    """An exception as (class, message, attributes): it pickles even when the class's ``__init__`` takes
    other arguments than the message (:class:`~frictid.errors.LogFormatError`)."""
    cls, attrs = type(exc), dict(getattr(exc, "__dict__", {}))
    try:
        pickle.dumps(cls)
    except Exception:  # noqa: BLE001 - a class the parent could not find
        return RuntimeError, f"{cls.__name__}: {exc}", {}
    try:
        pickle.dumps(attrs)
    except Exception:  # noqa: BLE001 - keep the message
        attrs = {}
    return cls, str(exc), attrs


def _rebuild_exception(data: tuple) -> BaseException:
    cls, msg, attrs = data
    exc = cls.__new__(cls)
    exc.args = (msg,)
    exc.__dict__.update(attrs)
    return exc


def keep_freed_memory() -> bool:
    """Ask glibc's allocator to serve arrays up to 32 MB (a joint-hour of float64 at 1 kHz is 29 MB) from
    its heap and to keep up to 512 MB freed there for the next array, instead of mapping fresh zeroed
    pages for every temporary (segments, derivatives, fits, replays, figures) and unmapping them after:
    this VM charges 1-2.5 s of system time per GB a process touches first. On six joint-hours it saves
    0.6-0.9 s CPU of the report's 17 s (docs/report.md) and 10 s of system time of the fit's 57 s CPU
    (docs/benchmarks.md), for 0.3-0.5 GB more peak memory. Process-wide: meant for the ``frictid fit``
    and ``frictid report`` commands, whose process ends with their output; the workers they fork inherit
    it. False where the C library is not glibc.

    One heap for every thread (``M_ARENA_MAX`` 1): glibc gives each thread that allocates its own heap
    (arena), and the Parquet reader's decoding threads left a worker's read buffers there, freed but out
    of reach of the arrays numpy then allocates in the main thread: a report worker's first joint held
    803-883 MB of private memory with them, 575-679 MB without (0.85-2.28 -> 0.29-0.81 s of system time;
    docs/benchmarks.md, session 7). The decoding threads allocate few, large buffers: one heap's lock costs
    them nothing measurable."""
    mallopt = _libc("mallopt")
    if mallopt is None:
        return False
    M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_ARENA_MAX = -1, -3, -8
    if not (mallopt(M_MMAP_THRESHOLD, 32 << 20) and mallopt(M_TRIM_THRESHOLD, 512 << 20)
            and mallopt(M_ARENA_MAX, 1)):
        return False
    import sys

    if "pyarrow" not in sys.modules:
        # Arrow's C++ parts that do not take pyarrow's pool (the Parquet reader's page buffers) allocate
        # from its process-wide default, chosen from this variable when pyarrow loads: with its own
        # allocator (mimalloc), a worker's first read held 100-160 MB in mimalloc's huge pages that numpy
        # could not reuse afterwards (the read's private memory 528-591 -> 426-459 MB). A value the user
        # set is kept.
        os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    import pyarrow as pa

    # Arrow's buffers (the row groups read, the arrays the reader fills) from the same heap: its own
    # allocator returns freed pages to the system after a few milliseconds, and each joint's read in a
    # worker then faulted them in again (0.3-0.5 s per joint-hour on this VM)
    pa.set_memory_pool(pa.system_memory_pool())
    return True


def huge_pages(a) -> None:
    """Ask the kernel to back a large array with transparent huge pages, as numpy does for the arrays it
    allocates itself (4 MB and more, unless ``NUMPY_MADVISE_HUGEPAGE=0``): for arrays allocated elsewhere
    (Arrow's allocator, which the log reader's columns come from). One fault then maps 2 MB instead of
    4 kB: a report worker's first joint took 56-60 k page faults instead of 109-117 k, and after idling
    0.1-0.4 s less system time in three of four pairs (docs/benchmarks.md, session 8). Nothing where the
    system has no such advice."""
    import ctypes
    import mmap

    advice = getattr(mmap, "MADV_HUGEPAGE", None)
    if advice is None or a.nbytes < (4 << 20) or os.environ.get("NUMPY_MADVISE_HUGEPAGE", "1") == "0":
        return
    start = a.__array_interface__["data"][0]
    first = -(-start // mmap.PAGESIZE) * mmap.PAGESIZE  # madvise takes whole pages
    end = (start + a.nbytes) // mmap.PAGESIZE * mmap.PAGESIZE
    madvise = _libc("madvise", (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int))  # an address: declared
    if end > first and madvise is not None:
        madvise(first, end - first, advice)  # advice only: a refusal changes nothing


@functools.cache
def _libc(name: str, argtypes: tuple = ()):
    """A function of the process's C library (its own symbols: ``find_library`` would run ldconfig), with
    its ``argtypes`` declared when given (an argument wider than a C int, e.g. an address, needs them), or
    None where there is no such function (not glibc, not Linux)."""
    import ctypes

    try:
        fn = getattr(ctypes.CDLL(None, use_errno=True), name)
    except (OSError, AttributeError):  # pragma: no cover - not a Unix C library, or not this function
        return None
    if argtypes:
        fn.argtypes = list(argtypes)
    return fn


class Prefetch:
    """Work that does not depend on the logs' contents, started in background threads while the caller
    reads or plans the logs: the SHA-256 of every file (:func:`frictid.io.logs.file_sha256`) and the
    imports of ``preload`` (what the workers will need, imported once before they are forked). Reading,
    hashing (both release the GIL) and importing then overlap. :meth:`hashes` waits for both, so that no
    thread is left running when the workers are forked."""

    def __init__(self, paths: Iterable[str], preload: Callable[[], None] | None = None):
        from concurrent.futures import ThreadPoolExecutor

        from frictid.io.logs import file_sha256

        self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="frictid-prefetch")
        if preload is not None:  # an import error surfaces when the import is used
            self._pool.submit(preload)
        self._hashes = {str(p): self._pool.submit(file_sha256, str(p)) for p in dict.fromkeys(paths) if p != "-"}

    def hashes(self) -> dict[str, str | None]:
        """The files' SHA-256 (waits for them and for the imports). A file that could not be read is left
        out: its reading reports the problem."""
        self._pool.shutdown(wait=True)
        out = {}
        for p, f in self._hashes.items():
            try:
                out[p] = f.result()
            except OSError:
                pass
        return out
