"""Dask clients for o3dheat's many-task jobs (studies, batches), in-process or on a cluster, and the progress bar.

Entry points: :func:`session` (the ``scheduler`` argument made a client, closed after the job),
:func:`local_cluster`, :func:`connect`, :func:`register_warm_up`, :func:`task_error`,
:func:`progress_bar`, :func:`unguarded_main`.

Notes
-----
The ``scheduler`` argument of :func:`o3dheat.robustness_study <o3dheat.pipelines.study.robustness_study>` and :func:`o3dheat.pipelines.batch.run`:

* ``None``: a local Dask cluster started for the job and closed after it: one worker process per
  core (``os.cpu_count()``), one thread each, each pinned to a core of its own, no dashboard
  (:func:`local_cluster`);
* ``"sequential"``: in this process, without Dask;
* an address (``"tcp://host:8786"``): a running cluster, connected to and disconnected from,
  never shut down;
* a ``distributed.Client``: used as it is and left open.

Worker memory: Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536`` (its
``distributed.nanny.pre-spawn-environ``), which also fixes glibc's mmap threshold at 128 KB: every
numpy array above 128 KB is then a fresh ``mmap`` whose pages fault in one by one, and freed
arrays go straight back to the system. On o3dheat's tasks (many arrays of n × 10 to n × 100
floats) that costs 25-35 % more CPU time than the same work in-process. :func:`local_cluster`
starts its workers without it (glibc's default, adaptive thresholds), even when this process's
environment has it (a nanny started here before puts it there). For a cluster of your own, set
``distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_`` to null in its Dask configuration
(and do not export the variable) to get the same speed.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import typing

from o3dheat import geometry, topology
from o3dheat.errors import MeshError, SolverError

from ._dask_logs import dask_logs

__all__ = ["local_cluster", "connect", "session", "register_warm_up", "progress_bar", "task_error", "unguarded_main"]

_TRIM_ENV = "MALLOC_TRIM_THRESHOLD_"
_TRIM = f"distributed.nanny.pre-spawn-environ.{_TRIM_ENV}"


def local_cluster(n_workers: int | None = None, pin: bool = True) -> typing.Any:
    """A local Dask cluster of single-threaded worker processes, without a dashboard.

    The workers keep glibc's adaptive memory thresholds: they start without
    ``MALLOC_TRIM_THRESHOLD_`` (see the module notes).

    Parameters
    ----------
    n_workers : int, optional
        Worker processes (default ``os.cpu_count()``).
    pin : bool
        Pin each worker process to a CPU of its own (:class:`o3dheat.pipelines.workers.PinToCore`),
        when there are at least as many CPUs available to this process as workers (Linux): the
        kernel then does not move them between cores, which costs their caches. False lets the
        kernel place them (better when other work shares the machine).

    Returns
    -------
    distributed.LocalCluster
        Close it (or use it in a ``with`` block) when done.

    Raises
    ------
    MeshError
        Called from the top-level code of a script outside ``if __name__ == "__main__":``: Dask
        starts its workers by running the script again (multiprocessing's "spawn"), and each
        would start a cluster of its own (:func:`unguarded_main`). Nothing is started then.

    Examples
    --------
    >>> from o3dheat.pipelines.cluster import local_cluster
    >>> from distributed import Client
    >>> with local_cluster(1) as cluster, Client(cluster) as client:   # doctest: +SKIP
    ...     client.submit(sum, [1, 2]).result()
    3
    """
    import dask  # here and below: importing distributed costs ~0.5 s, which `import o3dheat` avoids
    from distributed import LocalCluster

    n = (os.cpu_count() or 1) if n_workers is None else n_workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise MeshError(f"n_workers must be a positive integer, got {n_workers!r}")
    script = unguarded_main() if dask.config.get("distributed.worker.multiprocessing-method", "spawn") != "fork" \
        else None
    if script is not None:
        raise MeshError(f"{script} starts a local Dask cluster from its top level: put that code under "
                        "'if __name__ == \"__main__\":' (Dask's worker processes run the script again), or "
                        "pass scheduler=\"sequential\"")
    from .workers import OneLineLogs, PinToCore  # here: workers imports distributed (~0.5 s), see its docstring

    plugins = (OneLineLogs(),)
    cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
    if pin and n <= len(cpus):
        plugins += (PinToCore(cpus[:n]),)
    # the nannies read the setting when they are made, and the workers inherit this process's
    # environment when they are spawned: both happen here
    saved = os.environ.pop(_TRIM_ENV, None)
    try:
        with dask.config.set({_TRIM: None}):
            return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                plugins=plugins)
    finally:
        if saved is not None:
            os.environ[_TRIM_ENV] = saved


def unguarded_main() -> str | None:
    """The main script's path when the code calling this runs at its top level, outside an
    ``if __name__ == "__main__":`` block; else None (guarded, interactive, ``python -c``).

    Worker processes started by "spawn" or "forkserver" (Dask's default) run the main script
    again before they do anything: unguarded, the script's call that started them runs again in
    each, which fails (a process that starts processes while it starts) and Dask reports it in
    pages of tracebacks, then a timeout. Found from the main script's source (its ``ast``) and
    the line of its top-level code being run.

    Examples
    --------
    >>> from o3dheat.pipelines.cluster import unguarded_main
    >>> unguarded_main() is None          # a doctest runs from pytest's guarded main
    True
    """
    import ast

    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if path is None:
        return None
    frame = sys._getframe(1)
    while frame is not None and not (frame.f_code.co_name == "<module>" and frame.f_globals is vars(main)):
        frame = frame.f_back
    if frame is None:  # not called from the main script's code
        return None
    line = frame.f_lineno
    try:
        with open(frame.f_code.co_filename, encoding="utf-8") as fh:
            tree = ast.parse(fh.read())
    except (OSError, SyntaxError, ValueError):  # cannot tell: no false alarm
        return None

    def is_main_test(test):
        if not (isinstance(test, ast.Compare) and len(test.ops) == 1 and isinstance(test.ops[0], ast.Eq)):
            return False
        sides = [test.left, test.comparators[0]]
        return any(isinstance(x, ast.Name) and x.id == "__name__" for x in sides) and \
            any(isinstance(x, ast.Constant) and x.value == "__main__" for x in sides)

    for node in ast.walk(tree):
        if isinstance(node, ast.If) and node.body and is_main_test(node.test) and \
                node.body[0].lineno <= line <= node.body[-1].end_lineno:
            return None
    return path


def connect(scheduler: typing.Any, warm_up: bool = False) -> tuple:
    """A Dask client for a ``scheduler`` argument (see the module notes).

    Parameters
    ----------
    scheduler : None, "sequential", str or distributed.Client
        None: a new local cluster (one single-threaded worker per core, closed with the client);
        "sequential": no client, the caller computes in this process; an address
        ("tcp://host:port"): the running scheduler there; a Client: used as it is.
    warm_up : bool
        Pay each worker's one-time costs at start: pymeshlab's first call in its main thread
        (:func:`o3dheat.geometry.sampling.warm_up`; for jobs that resample meshes) and the topology's
        compiled loops (:func:`o3dheat.topology.warm_up <o3dheat.topology.critical.warm_up>`). With "sequential", in this process.

    Returns
    -------
    (client, owned)
        ``client`` is None for "sequential"; ``owned`` says whether the caller must close it
        (and its cluster): :func:`session` does.

    Raises
    ------
    MeshError
        Any other ``scheduler``.

    Examples
    --------
    >>> from distributed import Client
    >>> from o3dheat.pipelines.cluster import connect
    >>> connect("sequential")                     # no client: the caller computes in-process
    (None, False)
    >>> with Client(processes=False, n_workers=1, dashboard_address=None) as c:
    ...     client, owned = connect(c)            # the caller's client: the caller closes it
    ...     client is c, owned
    (True, False)
    """
    if scheduler == "sequential":
        if warm_up:
            _warm_up()
        return None, False
    from distributed import Client

    if scheduler is None:
        cluster = local_cluster()
        try:
            client, owned = Client(cluster), True
        except BaseException:
            cluster.close()
            raise
    elif isinstance(scheduler, Client):
        client, owned = scheduler, False
    elif isinstance(scheduler, str):
        try:
            client, owned = Client(scheduler), True
        except (OSError, ValueError, TypeError) as e:
            raise MeshError(f"cannot connect to the Dask scheduler {scheduler!r} ({type(e).__name__}: {e}); "
                            "give 'sequential', a running scheduler's address, or nothing for a local "
                            "cluster") from None
    else:
        raise MeshError(f"scheduler must be None, 'sequential', an address or a distributed.Client, "
                        f"got {scheduler!r}")
    if warm_up:
        try:
            register_warm_up(client)
        except BaseException:
            close(client, owned)
            raise
    return client, owned


def close(client: typing.Any, owned: bool) -> None:
    """Close a client from :func:`connect` and, when it started one, its local cluster.

    The shutdown of a cluster started here is silent: what Dask logs then (comms closed under
    it, a busy or restarting worker process killed: "Worker process still alive ... killing")
    says nothing the caller can act on; the tasks' results already say what failed."""
    if client is None or not owned:
        return
    cluster = getattr(client, "cluster", None)
    with dask_logs(logging.CRITICAL):
        try:
            client.close()
        finally:
            if cluster is not None:
                cluster.close()


@contextlib.contextmanager
def session(scheduler: typing.Any, warm_up: bool = False) -> typing.Iterator:
    """``with session(scheduler) as client:`` :func:`connect`, then :func:`close` on the way out.

    With a local cluster started here (``scheduler=None``), Dask's log records are one line each
    while it runs (a worker that dies is reported by its task, :func:`task_error`), and its
    shutdown is silent.

    Examples
    --------
    >>> from o3dheat.pipelines.cluster import session
    >>> with session("sequential") as client:
    ...     client is None
    True
    """
    if scheduler is not None:
        client, owned = connect(scheduler, warm_up=warm_up)
        try:
            yield client
        finally:
            close(client, owned)
        return
    with dask_logs(logging.WARNING):
        try:
            client, owned = connect(scheduler, warm_up=warm_up)
        except MeshError:
            raise
        except Exception as e:  # e.g. its workers died while starting (out of memory)
            raise SolverError(f"the local Dask cluster failed to start: {task_error(e)}") from None
        try:
            yield client
        finally:
            close(client, owned)


def _warm_up():
    """The one-time costs of a process, paid now: pymeshlab's first call (in the main thread, see
    :func:`o3dheat.geometry.sampling.warm_up`) and loading the topology's compiled loops
    (:func:`o3dheat.topology.warm_up <o3dheat.topology.critical.warm_up>`, 0.3 s per process: in a study it made every worker's first
    task slower)."""
    geometry.warm_up()
    topology.warm_up()


def register_warm_up(client: typing.Any) -> None:
    """``pymeshlab``'s first call in each worker's main thread and the topology's compiled loops
    loaded, now and in workers that join later (see :func:`o3dheat.geometry.sampling.warm_up` and
    :func:`o3dheat.topology.warm_up <o3dheat.topology.critical.warm_up>`).

    Examples
    --------
    For clusters of worker processes (``connect(..., warm_up=True)`` calls it):

    >>> from distributed import Client
    >>> from o3dheat.pipelines.cluster import local_cluster, register_warm_up
    >>> with local_cluster(1) as cluster, Client(cluster) as client:   # doctest: +SKIP
    ...     register_warm_up(client)
    ...     "o3dheat-pymeshlab-warm-up" in client.run(lambda dask_worker: list(dask_worker.plugins)).popitem()[1]
    True
    """
    from distributed.diagnostics.plugin import WorkerPlugin

    class WarmUp(WorkerPlugin):
        name = "o3dheat-pymeshlab-warm-up"

        def setup(self, worker):
            # in the worker: this class travels by value (cloudpickle), the function by its module's name
            from .cluster import _warm_up

            _warm_up()

    register = getattr(client, "register_plugin", None) or client.register_worker_plugin
    register(WarmUp())


def task_error(e: BaseException) -> str:
    """An exception raised by a Dask task's future, as one line; a worker's death says what most
    often causes it.

    Dask retries a task whose worker died (``distributed.scheduler.allowed-failures`` times), then
    raises ``KilledWorker``, whose text names the task's key and not the cause. o3dheat's
    eigensolves refuse work that a Dask worker's memory limit cannot hold
    (:func:`o3dheat.memory.memory_limits`), but other steps, or other processes, can still
    exhaust it.

    Examples
    --------
    >>> from o3dheat.pipelines.cluster import task_error
    >>> task_error(ValueError("bad   value"))
    'ValueError: bad value'
    >>> class KilledWorker(Exception): pass
    >>> print(task_error(KilledWorker("Attempted to run task 'x' on 4 different workers")))
    KilledWorker: the Dask workers that ran it died (most often: out of memory; see the workers' logs): give each worker more memory (fewer workers) or process a smaller mesh
    """
    if type(e).__name__ == "KilledWorker":
        return ("KilledWorker: the Dask workers that ran it died (most often: out of memory; see the workers' "
                "logs): give each worker more memory (fewer workers) or process a smaller mesh")
    return f"{type(e).__name__}: {' '.join(str(e).split()) or repr(e)}"


def progress_bar(total: int, progress: bool | None = None, unit: str = "task") -> typing.Any:
    """A tqdm bar on stderr, or None.

    Parameters
    ----------
    total : int
        Number of steps the bar counts to.
    progress : bool, optional
        True or False; None (default): when stderr is a terminal.
    unit : str
        What a step is called on the bar ("task" by default).

    Examples
    --------
    >>> from o3dheat.pipelines.cluster import progress_bar
    >>> progress_bar(10, progress=False) is None
    True
    """
    show = sys.stderr.isatty() if progress is None else bool(progress)
    if not show:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit=unit, file=sys.stderr)
