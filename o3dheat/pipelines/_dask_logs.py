"""Dask's log records, one line each: :class:`DaskLogs` (the filter), :func:`dask_logs` (the context
that installs it), :data:`DASK_LOGGERS`; shared by the cluster (:mod:`o3dheat.pipelines.cluster`, in
this process), the worker plugins (:mod:`o3dheat.pipelines.workers`, in the workers) and the command,
without importing Dask."""

from __future__ import annotations

import contextlib
import logging

#: the loggers of Dask and its web stack (one list: the cluster, the workers and the command filter them)
DASK_LOGGERS = ("distributed", "dask", "bokeh", "tornado", "asyncio")


class DaskLogs(logging.Filter):
    """Records of Dask and its web stack below ``level`` dropped, the others on one line (no
    traceback): a worker's death is a task's result (:func:`task_error`), not pages of stack."""

    def __init__(self, level):
        super().__init__()
        self.level = level

    def filter(self, record):
        if not record.name.startswith(DASK_LOGGERS):
            return True
        if record.levelno < self.level:
            return False
        text = record.getMessage().strip().splitlines()
        record.msg, record.args = (text[0] if text else ""), None
        record.exc_info = record.exc_text = record.stack_info = None
        return True


@contextlib.contextmanager
def dask_logs(level):
    """The handlers that Dask's records reach (the root's and Dask's own) filtered by
    :class:`DaskLogs` for the duration."""
    handlers = {h for name in ("", *DASK_LOGGERS) for h in logging.getLogger(name).handlers}
    flt = DaskLogs(level)
    for h in handlers:
        h.addFilter(flt)
    try:
        yield
    finally:
        for h in handlers:
            h.removeFilter(flt)
