"""A scale space to look at, in a browser or a notebook: :func:`view`, :class:`View`.

:func:`view` builds the :class:`~o3dheat.visualization.scene.Scene` of a field's scale space (the
exact heat flow by default) and returns a :class:`View`, which writes it as one offline HTML page
(:mod:`o3dheat.visualization.page`: a slider over ``t``, critical points, tracks, level sets) and
shows it inline in Jupyter. The ``o3dheat view`` command does the same from the shell.
"""

from __future__ import annotations

import html
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.io import atomic_write_text

from .page import page_html
from .scene import Recipe, Scene, build

if TYPE_CHECKING:
    from o3dheat.typing import FieldLike, MeshLike, PathLike, TimesLike

__all__ = ["View", "view"]


class View:
    """An interactive page of a :class:`~o3dheat.visualization.scene.Scene` (from :func:`view`).

    Attributes
    ----------
    scene : Scene
        What the page shows.
    times : (T,) float64 ndarray
        The scales of the field shown first (NaN for columns of unknown time).

    Examples
    --------
    See :func:`view`.
    """

    def __init__(self, scene: Scene):
        if not isinstance(scene, Scene):
            raise MeshError(f"View needs a Scene, got {type(scene).__name__}")
        self.scene = scene
        self._html = None

    @property
    def times(self) -> np.ndarray:
        """(T,) float64: the scales of the field shown first (a copy)."""
        return np.asarray(self.scene.fields[0].times, dtype=np.float64).copy()

    def __repr__(self):
        fields = ", ".join(f"{f.name} ({f.values.shape[1]} scales)" for f in self.scene.fields)
        return f"View({self.scene.name}: {len(self.scene.V):,} vertices; {fields})"

    def html(self) -> str:
        """The whole page as text (made once).

        Examples
        --------
        See :func:`view`.
        """
        if self._html is None:
            self._html = page_html(self.scene)
        return self._html

    def save(self, path: PathLike, overwrite: bool = False) -> Path:
        """Write the page to ``path`` (one self-contained ``.html`` file), atomically.

        Parameters
        ----------
        path : str or Path
            The file to write.
        overwrite : bool
            Replace an existing file (default: refuse, with a MeshError, before anything is written).

        Returns
        -------
        pathlib.Path

        Examples
        --------
        >>> import os, tempfile, open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
        >>> v = o3dheat.view(m, m.vertex.positions.numpy()[:, 2], [0.0, 0.1], tracks=False)
        >>> path = v.save(os.path.join(tempfile.mkdtemp(), "sphere.html"))
        >>> path.read_text().startswith("<!DOCTYPE html>")
        True
        """
        checks.flag(overwrite, "overwrite")
        path = Path(path)
        if path.is_dir():
            raise MeshError(f"{path} is a folder: give the page's file name (e.g. {path / 'view.html'})")
        if path.exists() and not overwrite:
            raise MeshError(f"{path} exists: pass overwrite=True (--overwrite) to replace it")
        atomic_write_text(path, self.html())
        return path

    def _repr_html_(self):
        """The page in an ``<iframe srcdoc=...>``: Jupyter shows it inline, offline, isolated."""
        return (f'<iframe srcdoc="{html.escape(self.html(), quote=True)}" style="width:100%;height:640px;'
                'border:1px solid #ddd" sandbox="allow-scripts"></iframe>')


def view(mesh: MeshLike, field: FieldLike | str | None = None, t: TimesLike | None = None, *,
         method: str = "exact", up: str = "auto", max_faces: int | None = 400_000, column: int | None = None,
         source: PathLike | None = None, echo: Callable[[str], None] | None = None, **recipe) -> View:
    """A field's scale space as an interactive page: slide through ``t``, turn the shape.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface (an ``o3d.t`` mesh may carry the field as a vertex attribute).
    field : str, (n,) or (n, T) array_like, optional
        A vertex attribute's name or the values: (n,) is smoothed at the times ``t``; the columns
        of (n, T) are shown as the scales. Default: the mesh's (n, T) attributes (``f_smooth``,
        ``f_exact``, ``hks`` ... with a chooser), or where it has none the noisy height along
        ``up`` (as in the demo), smoothed.
    t : float or (T,) array_like, optional
        Times (paper convention ``exp(−λ t / 2)``). Default: 20 log-spaced scales over the whole
        multi-scale range and the paper's 10, two fields of the page.
    method : {"exact", "spectral"}
        The full heat kernel (:func:`o3dheat.heat_flow <o3dheat.spectral.heatflow.heat_flow>`) or the truncated one.
    up : {"auto", "x", "y", "z"}
        The vertical axis; "auto" by the rule of :func:`o3dheat.geometry.up.up_axis` (a ``source``
        .obj/.ply file: y; otherwise z).
    max_faces : int or None
        Larger meshes are shown on a decimated copy, the fields transferred (the page says so).
    column : int, optional
        Of an (n, c) field, the column to smooth.
    source : str or Path, optional
        The file the mesh came from (the up rule, the title).
    echo : callable, optional
        Called with a line of progress per stage.
    **recipe
        More of :class:`~o3dheat.visualization.scene.Recipe`: ``k``, ``noise``, ``seed``,
        ``tracks``, ``levels``, ``cmap``.

    Returns
    -------
    View
        ``.save("page.html")`` writes the page; in Jupyter it shows inline.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> v = o3dheat.view(m, m.vertex.positions.numpy()[:, 0], np.geomspace(0.01, 1.0, 5))
    >>> v.times.round(3).tolist(), v.scene.fields[0].critical[-1].counts
    ([0.01, 0.032, 0.1, 0.316, 1.0], (1, 2, 1))
    >>> v.html().startswith("<!DOCTYPE html>")
    True
    """
    unknown = set(recipe) - set(Recipe.__dataclass_fields__)
    if unknown:
        raise MeshError(f"unknown option(s) of view: {', '.join(sorted(unknown))}")
    r = Recipe(method=method, up=up, max_faces=max_faces, column=column, source=source, **recipe)
    return View(build(mesh, field, t, r, echo))
