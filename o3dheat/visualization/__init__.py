"""Visualization, the last stage: drawings (``plot``), charts (``charts``), recipes (``figures``).

:mod:`~o3dheat.visualization.plot` draws fields on surfaces, :mod:`~o3dheat.visualization.charts`
plain matplotlib charts, and :mod:`~o3dheat.visualization.figures` holds the figure recipes
(:func:`~o3dheat.visualization.figures.paper_figures`, :func:`~o3dheat.visualization.figures.study_figures`).
"""

from .figures import paper_figures, study_figures

# isort: split
# the modules, as attributes of the package
from . import charts, figures, plot  # noqa: E402

__all__ = ["paper_figures", "study_figures", "plot", "charts", "figures"]
