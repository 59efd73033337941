"""o3dheat's own threads: :func:`threads` and :func:`get_threads` (how many), :func:`run` and
:func:`background` (one shared pool), :func:`row_parts` (row-parallel loops with reproducible sums).

Why our own threads: the solves on a CHOLMOD factor and the passes over a Lanczos basis are
memory- or latency-bound loops that numpy/BLAS and CHOLMOD run on one core (or, for BLAS, on
threads that keep spinning between calls and then steal the core from everything else). o3dheat
runs them on a pool of threads instead (numpy, BLAS, scipy's sparse products and CHOLMOD through
``ctypes`` all release the GIL), with BLAS pinned to one thread meanwhile (:func:`blas_one_thread`).

Reproducibility: a row-parallel reduction (for example ``X.T @ Y`` over the rows) is cut into
parts that depend only on the number of rows (:func:`row_parts`: at most :data:`CHUNK` rows, a
multiple of 4 parts), whatever the number of threads, and the partial results are added in the
order of the parts: results are bit-identical for every thread count.

The number of threads is :func:`get_threads`: the value set by :func:`threads` in the calling
thread, else the environment variable ``O3DHEAT_NUM_THREADS``, else the CPUs this process may run
on (at most 8).
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from o3dheat.errors import MeshError

__all__ = ["CHUNK", "aside", "background", "blas_one_thread", "get_threads", "row_parts", "run", "threads"]

#: most rows per part of a row-parallel loop (:func:`row_parts`; the parts depend on the number of
#: rows only, so sums do not depend on the threads)
CHUNK = 1 << 14
_MAX_THREADS = 8
_LOCAL = threading.local()  # .threads: set by threads() for the calling thread
_PREFIX = "o3dheat-pool"
_POOL_LOCK = threading.Lock()  # made anew in a forked child (another thread may hold it at the fork)


def _new_lock_after_fork():
    global _POOL_LOCK
    _POOL_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_new_lock_after_fork)
_POOL = None  # (pid, ThreadPoolExecutor or None, its threads, capped): recreated in a forked child
# (threads do not survive a fork)


def get_threads() -> int:
    """Number of threads o3dheat's parallel loops use.

    The value set by :func:`threads` in the calling thread if any, else the environment variable
    ``O3DHEAT_NUM_THREADS``, else the number of CPUs this process may run on (at most 8).

    Returns
    -------
    int

    Raises
    ------
    MeshError
        ``O3DHEAT_NUM_THREADS`` is not a positive integer.

    Examples
    --------
    >>> from o3dheat.parallel import get_threads, threads
    >>> with threads(1):
    ...     get_threads()
    1
    """
    value = getattr(_LOCAL, "threads", None)
    if value is not None:
        return value
    env = os.environ.get("O3DHEAT_NUM_THREADS", "").strip()
    if env:
        return _check(env, "O3DHEAT_NUM_THREADS")
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cpus = os.cpu_count() or 1
    return max(1, min(cpus, _MAX_THREADS))


def _check(n, what):
    try:
        value = int(n)
    except (TypeError, ValueError):
        value = 0
    if isinstance(n, bool) or value < 1 or (not isinstance(n, str) and value != n):
        raise MeshError(f"{what} must be a positive integer, got {n!r}")
    return min(value, _MAX_THREADS)


@contextlib.contextmanager
def threads(n: int) -> Iterator[None]:
    """Run o3dheat's parallel loops on ``n`` threads inside a ``with`` block, for the loops the
    calling thread starts (other threads keep their own setting: a Dask worker thread can ask for
    one thread without affecting its neighbours).

    Results do not depend on ``n`` (see the module notes); ``n = 1`` runs everything in the
    calling thread.

    Parameters
    ----------
    n : int
        At least 1 (at most 8 are used).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from o3dheat.spectral.linalg import factorize
    >>> from o3dheat.parallel import threads
    >>> f = factorize(sp.diags([4.0, 16.0]).tocsc())
    >>> with threads(1):
    ...     f.solve(np.ones((2, 3))).tolist()
    [[0.25, 0.25, 0.25], [0.0625, 0.0625, 0.0625]]
    """
    value = _check(n, "the number of threads")
    old = getattr(_LOCAL, "threads", None)
    _LOCAL.threads = value
    try:
        yield
    finally:
        _LOCAL.threads = old


def _pool(need=None):
    """The process's worker threads, at least ``need`` of them (default ``get_threads() - 1``) if
    they can be started, or None when none could be; recreated in a forked child and when more
    are needed (each thread maps a stack and a malloc arena: only as many as used are started);
    see :func:`_started_pool`."""
    return _pool_and_size(need)[0]


def _pool_and_size(need=None):
    """``(pool, its threads)`` of :func:`_pool`, read together (under a lock: two threads never
    start two pools)."""
    global _POOL
    need = max(get_threads() - 1 if need is None else need, 1)
    with _POOL_LOCK:
        if _POOL is None or _POOL[0] != os.getpid() or (_POOL[1] is not None and _POOL[2] < need and not _POOL[3]):
            # an older, smaller pool is dropped, not shut down: a caller may still be submitting to it
            pool, m = _started_pool(need)
            _POOL = (os.getpid(), pool, m, m < need)  # the last: fewer could start, do not try again
        return _POOL[1], _POOL[2]


def _started_pool(m):
    """A thread pool with its ``m`` threads started now, so that a later ``submit`` never starts
    one: under an address-space limit (``ulimit -v``: each thread reserves a stack and a malloc
    arena) or a thread limit, starting a thread fails ("can't start new thread") and a work item
    queued by that ``submit`` could then run twice. When fewer start, the pool has as many as did
    (None: none, everything runs in the calling thread), with a warning once."""
    while m > 0:
        pool = ThreadPoolExecutor(max_workers=m, thread_name_prefix=_PREFIX)
        go = threading.Event()
        started = 0
        try:
            for _ in range(m):  # each blocks a thread until go: every submit starts a new one
                pool.submit(go.wait)
                started += 1
        except RuntimeError as e:
            if "can't start new thread" not in str(e):
                raise
            go.set()
            pool.shutdown(wait=True)
            logging.getLogger("o3dheat").warning(
                "could start only %d of %d worker threads (%s: an address-space limit, ulimit -v, or a thread "
                "limit): running on %d", started, m, e, started + 1)
            m = started
            continue
        go.set()
        return pool, m
    return None, 0


def row_parts(n: int, chunk: int | None = None) -> list[tuple[int, int]]:
    """The half-open row ranges ``(a, z)`` of a row-parallel loop over ``n`` rows (or of any
    ``n`` items, for example the columns of an array).

    Parameters
    ----------
    n : int
        Number of rows (or items), >= 0.
    chunk : int, optional
        Rows per part. By default the parts are equal, at most :data:`CHUNK` rows, and a multiple
        of 4 of them (one part below ``CHUNK / 4`` rows): 2 or 4 threads get as many rows each
        (16384-row parts left 20,000 rows cut 16384 + 3616: one thread did 82% of the work).

    Returns
    -------
    list of (int, int)

    Examples
    --------
    >>> row_parts(40000)
    [(0, 10000), (10000, 20000), (20000, 30000), (30000, 40000)]
    >>> row_parts(1000, 400)
    [(0, 400), (400, 800), (800, 1000)]
    """
    if chunk is None:
        parts = 1 if n < CHUNK // 4 else 4 * -(-n // (4 * CHUNK))
        chunk = max(1, -(-n // parts))
    return [(a, min(a + chunk, n)) for a in range(0, max(n, 1), chunk)]


def run(fn: Callable[[Any], Any], items: Iterable[Any], threads: int | None = None) -> list[Any]:
    """``[fn(*item) for item in items]``, the items shared out in contiguous groups among threads.

    The calling thread takes the first group. The results come back in the order of ``items``;
    the first exception raised is re-raised once every thread has finished. Called from one of
    the pool's own threads, it runs everything in that thread (no nesting, no deadlock).

    Parameters
    ----------
    fn : callable
        Must release the GIL to gain anything (numpy, BLAS, sparse products, ctypes calls do).
    items : sequence of tuples
        Arguments of each call.
    threads : int, optional
        At most this many threads (default :func:`get_threads`).

    Returns
    -------
    list

    Examples
    --------
    >>> run(lambda a, z: z - a, row_parts(40000))
    [10000, 10000, 10000, 10000]
    """
    items = list(items)
    t = min(get_threads() if threads is None else threads, len(items))
    if t <= 1 or threading.current_thread().name.startswith(_PREFIX):  # never nested in the pool
        return [fn(*item) for item in items]

    def group(g):
        return [fn(*item) for item in items[cuts[g]:cuts[g + 1]]]

    pool, size = _pool_and_size(t - 1)
    if pool is None:
        return [fn(*item) for item in items]
    t = min(t, size + 1)
    cuts = [round(i * len(items) / t) for i in range(t + 1)]
    futures = [pool.submit(group, g) for g in range(1, t)]
    error, out = None, []
    try:
        out = group(0)
    except BaseException as e:  # noqa: BLE001 - re-raised below, after the other threads
        error = e
    for f in futures:
        try:
            out += f.result()
        except BaseException as e:  # noqa: BLE001
            error = error or e
    if error is not None:
        raise error
    return out


def background(fn: Callable[..., Any], *args: Any) -> Future:
    """``fn(*args)`` started on one of the pool's threads, while the caller goes on: a
    ``concurrent.futures.Future`` (``.result()`` waits, and re-raises what ``fn`` raised). For
    work that releases the GIL (a ctypes call, a compiled loop) and does not need the caller's
    result. With one thread (:func:`get_threads`) it runs at once, in the calling thread.

    Examples
    --------
    >>> from o3dheat.parallel import background
    >>> background(sum, [1, 2, 3]).result()
    6
    """
    pool = _pool() if get_threads() > 1 and not threading.current_thread().name.startswith(_PREFIX) else None
    if pool is not None:
        return pool.submit(fn, *args)
    return _at_once(fn, args)


def aside(fn: Callable[..., Any], *args: Any, name: str = "o3dheat-aside") -> Future:
    """``fn(*args)`` started on a thread of its own (named ``name``), while the caller goes on: a
    ``concurrent.futures.Future``, as :func:`background` gives, for longer work that would hold one
    of the pool's threads while the caller's :func:`run` needs them all (a decimation beside a
    flow). With one thread (:func:`get_threads`) it runs at once, in the calling thread.

    Examples
    --------
    >>> from o3dheat.parallel import aside
    >>> aside(sum, [1, 2, 3]).result()
    6
    """
    if get_threads() == 1:
        return _at_once(fn, args)
    pool = ThreadPoolExecutor(1, thread_name_prefix=name)
    try:
        return pool.submit(fn, *args)
    finally:
        pool.shutdown(wait=False)  # the thread ends with its one task


def _at_once(fn, args):
    """A finished Future of ``fn(*args)``, run in the calling thread (its exception kept for ``result()``)."""
    done = Future()
    try:
        done.set_result(fn(*args))
    except Exception as e:  # noqa: BLE001 - handed over to the caller's result()
        done.set_exception(e)
    return done


@contextlib.contextmanager
def blas_one_thread() -> Iterator[None]:
    """BLAS (numpy's and scipy's OpenBLAS, MKL, ...) limited to one thread inside a ``with``.

    For loops that o3dheat parallelizes itself: two thread pools on the same cores slow each
    other down, and OpenBLAS threads spin for a while after each call. And for reproducible
    results: BLAS sums depend on its thread count. Through threadpoolctl (>= 3.8).

    The setting is the process's (OpenBLAS has one thread pool), so the blocks of all threads
    share one limit, counted: the first block to enter sets one thread, the last to leave
    restores what the first found (unless something else changed it meanwhile). Every block
    runs on one BLAS thread from start to end, whatever other threads do, and concurrent solves
    give the serial results. (Plain ``threadpool_limits`` blocks in several threads did not: the
    first to leave put the threads back under the others, the last left one thread for good.) A
    caller's own ``threadpool_limits`` block in another thread keeps its setting while it lasts
    (threadpoolctl lets one thread at a time set OpenBLAS' count).

    Examples
    --------
    >>> import numpy as np
    >>> with blas_one_thread():
    ...     float(np.ones((2, 2)) @ np.ones(2) @ np.ones(2))
    4.0
    """
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # a dependency; without it BLAS keeps its threads
        yield
        return
    with _BLAS_LOCK:
        if _BLAS["depth"] == 0:
            blas = ThreadpoolController().select(user_api="blas")
            _BLAS["limiter"] = (blas, blas.limit(limits=1, user_api="blas"))
            _release_blas_control()  # the last block to leave may run in another thread
        _BLAS["depth"] += 1
        _LOCAL.blas = getattr(_LOCAL, "blas", 0) + 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _BLAS["depth"] -= 1
            _LOCAL.blas -= 1
            if _BLAS["depth"] == 0:
                held, _BLAS["limiter"] = _BLAS["limiter"], None
                if held is not None and {i["num_threads"] for i in held[0].info()} <= {1}:  # still ours
                    held[1].restore_original_limits()
                    _release_blas_control()


#: the blocks of :func:`blas_one_thread` inside, in every thread, and the limit they share (the
#: BLAS libraries' controller and its limiter)
_BLAS: dict[str, Any] = {"depth": 0, "limiter": None}
_BLAS_LOCK = threading.Lock()  # made anew in a forked child, like _POOL_LOCK


def _release_blas_control():
    """Give up threadpoolctl's control of OpenBLAS if this thread holds it: threadpoolctl (>= 3.8)
    lets one thread at a time set OpenBLAS' process-wide thread count (the last that set it), and
    the last block of :func:`blas_one_thread` to leave, in any thread, must restore the count."""
    try:
        from threadpoolctl import OpenBLASController
    except ImportError:  # an older threadpoolctl: any thread sets the count
        return
    OpenBLASController.clear_controlling_thread()


def _blas_after_fork():
    global _BLAS_LOCK
    _BLAS_LOCK = threading.Lock()
    _BLAS["depth"] = getattr(_LOCAL, "blas", 0)  # only the forking thread's blocks go on in the child
    if _BLAS["depth"] == 0:
        _BLAS["limiter"] = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_blas_after_fork)
