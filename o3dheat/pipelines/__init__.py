"""Pipelines: filters and their registry, batches of files, robustness studies on Dask."""

from .batch import named_error, run, summary
from .filters import apply, one_column
from .study import load_config, robustness_study

# isort: split
# the modules, as attributes of the package
from . import batch, cluster, filters, study, workers  # noqa: E402

__all__ = ["apply", "one_column", "named_error", "run", "summary", "load_config", "robustness_study", "filters", "batch", "cluster", "workers", "study"]
