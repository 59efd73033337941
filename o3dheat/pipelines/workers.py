"""Worker plugins of o3dheat's local Dask clusters (:func:`o3dheat.pipelines.cluster.local_cluster`).

Apart from :mod:`o3dheat.pipelines.cluster` because they subclass Dask's ``WorkerPlugin``: importing
``distributed`` costs half a second, which ``import o3dheat`` does not pay. Worker processes
import this module to unpickle the plugins.
"""

from __future__ import annotations

import logging
import os
import typing
from collections.abc import Sequence

from distributed.diagnostics.plugin import WorkerPlugin

from ._dask_logs import DaskLogs, dask_logs

__all__ = ["PinToCore", "OneLineLogs"]


class PinToCore(WorkerPlugin):
    """Pin worker ``i`` (its name in a local cluster) and every thread it starts to the i-th of
    the given CPUs.

    Two workers that the kernel moves between two cores lose their caches at each move; pinned,
    an 18-task study ran 1.76x faster than sequentially instead of 1.67x (medians of four runs,
    ``scripts/bench_study.py``). Threads started later inherit the pinning of the thread that
    starts them.

    Parameters
    ----------
    cpus : sequence of int
        The CPUs this process may use (``os.sched_getaffinity(0)``), one per worker.

    Examples
    --------
    >>> from o3dheat.pipelines.workers import PinToCore
    >>> PinToCore([0, 1]).cpus
    [0, 1]
    """

    name = "o3dheat-pin-to-core"

    def __init__(self, cpus: Sequence[int]):
        self.cpus = sorted(int(c) for c in cpus)

    def setup(self, worker: typing.Any) -> None:
        """Pin this worker process's threads (Dask calls it when the worker starts).

        Examples
        --------
        >>> import os, types
        >>> from o3dheat.pipelines.workers import PinToCore
        >>> cpus = sorted(os.sched_getaffinity(0))
        >>> PinToCore(cpus).setup(types.SimpleNamespace(name="not a local worker"))  # left alone
        >>> sorted(os.sched_getaffinity(0)) == cpus
        True
        """
        try:
            i = int(worker.name)
        except (TypeError, ValueError):  # not a worker of a local cluster
            return
        cpu = self.cpus[i % len(self.cpus)]
        for tid in os.listdir("/proc/self/task"):
            try:
                os.sched_setaffinity(int(tid), {cpu})
            except OSError:  # a thread that ended meanwhile
                pass


class OneLineLogs(WorkerPlugin):
    """In a worker process of a local cluster, Dask's log records on one line each (no
    traceback) while it runs, and none below CRITICAL once it closes (:func:`o3dheat.pipelines.cluster.session`
    does the same in this process): a task's failure is its result, a worker's shutdown is
    nothing the user can act on.

    Examples
    --------
    >>> import logging
    >>> from o3dheat.pipelines.workers import OneLineLogs
    >>> plugin = OneLineLogs()
    >>> left = lambda: [f for h in logging.getLogger().handlers for f in h.filters if type(f).__name__ == "DaskLogs"]
    >>> before = left()                  # (those of an o3dheat command run earlier in this process)
    >>> plugin.setup(None); plugin.teardown(None)
    >>> left() == before
    True
    """

    name = "o3dheat-one-line-logs"

    def setup(self, worker: typing.Any) -> None:
        """Dask's records on one line each while the worker runs (Dask calls it at the start).

        Examples
        --------
        See the class.
        """
        self._running = dask_logs(logging.WARNING)
        self._running.__enter__()

    def teardown(self, worker: typing.Any) -> None:
        """No Dask record below CRITICAL from now to the end of the worker's process (Dask calls
        it when the worker closes; ``worker=None``: undone at once, for the class's example).

        Examples
        --------
        See the class.
        """
        running = getattr(self, "_running", None)
        if running is not None:
            running.__exit__(None, None, None)
            self._running = None
        closing = DaskLogs(logging.CRITICAL)  # to the end of the process
        for name in ("", "distributed", "tornado", "asyncio"):
            for h in logging.getLogger(name).handlers:
                h.addFilter(closing)
        self._closing = closing
        if worker is None:  # (the example's own process: put back)
            for name in ("", "distributed", "tornado", "asyncio"):
                for h in logging.getLogger(name).handlers:
                    h.removeFilter(closing)
