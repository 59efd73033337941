"""Pipelines: filters and their registry, batches of files, robustness studies on Dask.

Entry points: :func:`~o3dheat.pipelines.filters.apply` and :func:`~o3dheat.pipelines.columns.one_column`
(:mod:`o3dheat.pipelines.filters`; the filter SDK is :mod:`o3dheat.pipelines.site`),
:func:`~o3dheat.pipelines.batch.run`, :func:`~o3dheat.pipelines.batch.summary` and
:func:`~o3dheat.pipelines.batch.named_error` (:mod:`o3dheat.pipelines.batch`),
:func:`~o3dheat.pipelines.study.robustness_study` and :func:`~o3dheat.pipelines.study.load_config`
(:mod:`o3dheat.pipelines.study`)."""

import importlib

from .batch import named_error, run, summary
from .filters import apply, one_column
from .study import load_config, robustness_study

# isort: split
# the modules, as attributes of the package
from . import batch, cluster, columns, filters, site, study  # noqa: E402

__all__ = ["apply", "one_column", "named_error", "run", "summary", "load_config", "robustness_study", "filters",
           "columns", "site", "batch", "cluster", "workers", "study"]


def __getattr__(name):
    # workers subclasses Dask's WorkerPlugin: importing distributed costs ~0.5 s, which `import o3dheat`
    # does not pay; o3dheat.pipelines.workers is imported when first asked for
    if name == "workers":
        return importlib.import_module(".workers", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
