"""Visualization, the last stage: fields drawn on surfaces (:mod:`~o3dheat.visualization.plot`),
charts (:mod:`~o3dheat.visualization.charts`) and the figure recipes
(:mod:`~o3dheat.visualization.figures`: :func:`paper_figures`, :func:`study_figures`)."""

from .figures import paper_figures, study_figures

# isort: split
# the modules, as attributes of the package
from . import charts, figures, plot  # noqa: E402

__all__ = ["paper_figures", "study_figures", "plot", "charts", "figures"]
