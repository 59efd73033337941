"""Visualization: field renderings, charts and the paper's figure recipes."""

from .figures import paper_figures, study_figures

# isort: split
# the modules, as attributes of the package
from . import figures, plot  # noqa: E402

__all__ = ["paper_figures", "study_figures", "plot", "figures"]
