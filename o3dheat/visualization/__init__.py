"""Visualization, the last stage: one scene drawn two ways, as PNG figures and as an interactive page.

:mod:`~o3dheat.visualization.scene` builds the :class:`~o3dheat.visualization.scene.Scene` of a
scale space; :mod:`~o3dheat.visualization.plot` draws fields and scenes as static panels,
:mod:`~o3dheat.visualization.page` writes a scene as one offline HTML page and
:mod:`~o3dheat.visualization.interactive` wraps both (:func:`~o3dheat.visualization.interactive.view`);
:mod:`~o3dheat.visualization.charts` has plain matplotlib charts and
:mod:`~o3dheat.visualization.figures` the figure recipes
(:func:`~o3dheat.visualization.figures.paper_figures`, :func:`~o3dheat.visualization.figures.study_figures`).
"""

from .figures import paper_figures, study_figures
from .interactive import View, view

# isort: split
# the modules, as attributes of the package
from . import charts, figures, interactive, page, plot, scene  # noqa: E402

__all__ = ["paper_figures", "study_figures", "View", "view", "plot", "charts", "figures", "interactive", "page",
           "scene"]
