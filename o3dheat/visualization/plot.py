"""Fields drawn on surfaces as 3D renders: :func:`field`, :func:`fields`, :func:`draw`, :func:`render`, :func:`tracks`.

:func:`draw` draws a :class:`~o3dheat.visualization.scene.Scene` (the one the interactive page
shows) as panels, in a :class:`Style`; :func:`fields` draws panels across scales, :func:`render` the picture alone, :func:`tracks` the
critical points across scales; :func:`drawn_critical_points` are those the drawings show. The
charts of :mod:`o3dheat.visualization.charts` (:func:`scale_space`, :func:`persistence_diagram`,
:func:`study`, :func:`lifetime_chart`) are reachable here too.

Notes
-----
Surfaces are real 3D renders (hidden surfaces removed) by o3dheat's own rasterizer, which needs
no display, GPU or driver and gives the same pixels on every run, with level sets (solid black
lines) and critical points (maxima red, minima blue, saddles green, as in the paper) drawn on the
visible surface and hidden behind it, a colorbar named after the field and a legend.
``renderer="matplotlib"`` (or ``O3DHEAT_RENDERER=matplotlib``) draws with matplotlib's 3D axes
instead, which cannot hide what is behind the surface. Nothing is shown on screen: save a figure
with ``fig.savefig("name.png")``; :func:`o3dheat.view` makes the interactive page. More in
``docs/details/figures.md``; the recipes are in :mod:`o3dheat.visualization.figures`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays
from o3dheat.geometry._tables import vertex_normals
from o3dheat.topology import Surface
from o3dheat.topology import critical_points as find_critical

from . import _layout, _panels, _render
from ._panels import CRITICAL_COLORS  # noqa: F401 - public here (a dict: the same object)
from ._render import renderer_available
from ._tracks import JUMP, tracks  # noqa: F401 - public here
from .charts import lifetime_chart, persistence_diagram, scale_space, study
from .scene import ScaleField, Scene

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from o3dheat.topology import CriticalPoints
    from o3dheat.typing import FieldLike, MeshLike

__all__ = ["draw", "Style", "field", "fields", "render", "renderer_available", "scale_space", "study", "drawn_critical_points",
           "persistence_diagram", "tracks", "lifetime_chart", "CRITICAL_COLORS"]

#: level sets: how many, their values, or None
Levels = int | Sequence[float] | None


def drawn_critical_points(mesh: MeshLike | Surface, f: FieldLike) -> CriticalPoints:
    """The critical points the drawings show: those of :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>` less the
    ones on a part of the mesh where ``f`` is constant up to numerical error (it varies there by at
    most ``FLAT_RTOL`` times the largest ``|f|``), whose critical points are those of the errors.

    ``Φ_t(e_i)`` is exactly 0 on the parts of a multi-part mesh without vertex i, and a truncated
    kernel is constant on a part its few eigenpairs do not reach; computed, both carry hundreds of
    "critical points" of numerical errors, which would bury the part under markers.

    Parameters
    ----------
    mesh : mesh, (V, F) or o3dheat.topology.Surface
        The surface (its parts are found from its faces).
    f : (n,) array_like
        One value per vertex.

    Returns
    -------
    CriticalPoints

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> a = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> b = a.clone().translate([3.0, 0.0, 0.0])
    >>> n = len(a.vertex.positions)
    >>> V = np.r_[a.vertex.positions.numpy(), b.vertex.positions.numpy()]
    >>> F = np.r_[a.triangle.indices.numpy(), b.triangle.indices.numpy() + n]
    >>> f = np.r_[V[:n, 2], 1e-17 * np.random.default_rng(0).standard_normal(n)]  # rounding on b
    >>> sum(o3dheat.critical_points((V, F), f).counts) > 2, plot.drawn_critical_points((V, F), f).counts
    (True, (1, 0, 1))
    """
    S = Surface.of(mesh)
    f = S.field(f)
    parts = _panels.vertex_parts(S.n, S.F)
    flat = _panels.flat_parts(f, parts)
    return _panels.without_flat(find_critical(S, _panels.flattened(f, parts, flat)), parts, flat)[0]



@dataclasses.dataclass(frozen=True)
class Style:
    """How a scene is drawn as panels (:func:`draw`): what the figure adds around the pictures.

    Attributes
    ----------
    titles : sequence of str, optional
        One per panel.
    ncols : int, optional
        Panels per row (default: all in one row, at most 5).
    critical_points : bool or CriticalPoints
        Draw the critical points (computed per panel, less those of rounding errors on flat
        parts: :func:`drawn_critical_points`), these, or none.
    shared_range : bool
        One colour range and colorbar for all panels, or one each.
    size : float
        Inches per panel.
    suptitle : str, optional
        Above the panels.
    label : str, optional
        The colorbar's label (default: the field's name).
    renderer : {"auto", "raster", "matplotlib"}
        As for :func:`field`.
    counts : bool
        The legend counts the critical points (a single panel).

    Examples
    --------
    >>> import o3dheat.visualization.plot as plot
    >>> plot.Style(titles=["t1", "t10"], size=3.0).ncols is None
    True
    """

    titles: Sequence[str] | None = None
    ncols: int | None = None
    critical_points: bool | CriticalPoints = True
    shared_range: bool = True
    size: float = 3.5
    suptitle: str | None = None
    label: str | None = None
    renderer: str = "auto"
    counts: bool = False


def draw(scene: Scene, columns: Sequence[int] | None = None, field: int | str = 0, style: Style = Style()) -> Figure:
    """Panels of a :class:`~o3dheat.visualization.scene.Scene`: its field at some scales, as PNG figures
    show it (the interactive page, :func:`o3dheat.view`, draws the same scene in a browser).

    Parameters
    ----------
    scene : Scene
        The surface as drawn, the fields over scales, ``up``, the view, level sets and colormap.
    columns : sequence of int, optional
        The scales to draw (default: all).
    field : int or str
        Which of the scene's fields (index or name).
    style : Style
        Titles, layout, colorbar and renderer.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> v = o3dheat.view(m, m.vertex.positions.numpy()[:, 0], [0.0, 0.1, 1.0], tracks=False)
    >>> fig = plot.draw(v.scene, columns=[0, 2], style=plot.Style(titles=["t = 0", "t = 1"]))
    >>> len(fig.axes)  # two pictures and their colorbar
    3
    """
    from matplotlib.figure import Figure  # no pyplot: no GUI backend, no global state

    names = [f.name for f in scene.fields]
    if isinstance(field, str):
        if field not in names:
            raise MeshError(f"the scene has no field {field!r} (its fields: {', '.join(names)})")
        field = names.index(field)
    field = checks.count(field, "field", minimum=0, maximum=len(names) - 1)
    values, label = scene.fields[field].values, style.label if style.label is not None else names[field]
    if columns is not None:
        columns = [checks.count(c, "column", minimum=0, maximum=values.shape[1] - 1) for c in columns]
        values = values[:, columns]
    _layout.check_style(scene.cmap, style.size)
    T = values.shape[1]
    if style.titles is not None and len(style.titles) != T:
        raise MeshError(f"{len(style.titles)} titles for {T} fields")
    ncols = checks.count(style.ncols, "ncols") if style.ncols is not None else None
    ncols = min(ncols or min(T, 5), T)
    nrows = -(-T // ncols)
    V, F, level_sets, cp = _render.upright(scene.V, scene.up), scene.F, scene.levels, style.critical_points
    S = Surface.from_faces(len(V), F, V) if (level_sets is not None and level_sets is not False) or cp is True else None
    frame = _render.View(V, scene.view)
    r = _render.renderer(style.renderer)
    panels = _panels_of(V, F, values, scene.cmap, level_sets, cp, S, style.shared_range)
    w, h = _layout.picture_size(frame, style.size)
    shared = style.shared_range
    extra_h = (0.35 if style.titles is not None else 0.0) + (0.45 if not shared else 0.0)
    fig = Figure(figsize=(ncols * w + (1.1 if shared else 0.2),
                          nrows * (h + extra_h) + 0.45 + (0.45 if style.suptitle else 0.0)),
                 dpi=100, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.04, h_pad=0.04, wspace=0.03, hspace=0.05)
    normals = vertex_normals(V, F)
    axes = [_panel_axes(fig, (nrows, ncols, i + 1), p, r, frame, normals, scene.view, w, style.titles, i)
            for i, p in enumerate(panels)]
    if shared:
        _layout.colorbar(fig, axes, panels[0], label, "right", values)
    else:
        for ax, p in zip(axes, panels, strict=True):
            _layout.colorbar(fig, ax, p, label, "bottom", p.f)
    _layout.legend(fig, panels, counts=style.counts)
    if style.suptitle:
        fig.suptitle(style.suptitle, fontsize=11)
    return fig


def _scene(mesh, values, view, up, level_sets, cmap, critical_points):
    """The scene of :func:`field` and :func:`fields`: the mesh as drawn, ``values`` its one field."""
    V, F = as_arrays(mesh)
    _layout.check_style(cmap)
    _render.upright(V[:1], up)  # up checked before any work
    topology = (level_sets is not None and level_sets is not False) or critical_points is True
    _, V, F, values = _layout.as_drawn(V, F, values, topology)
    T = values.shape[1]
    return Scene(V, F, (ScaleField("f", values, np.full(T, np.nan), ()),), up=up, view=view, levels=level_sets,
                 cmap=cmap)


def _panels_of(V, F, values, cmap, level_sets, critical_points, S, shared_range):
    """One :class:`~o3dheat.visualization._panels.Panel` per column of ``values``, coloured over
    one range (``shared_range``) or each over its own."""
    T = values.shape[1]
    parts = _panels.vertex_parts(len(V), F)
    flat = np.stack([_panels.flat_parts(values[:, i], parts)[np.maximum(parts, 0)] & (parts >= 0)
                     for i in range(T)], 1)
    ranges = ([_layout.color_range(values, flat)] * T if shared_range
              else [_layout.color_range(values[:, i], flat[:, i]) for i in range(T)])
    span = (values.min(), values.max()) if shared_range else None
    return [_panels.Panel(V, F, values[:, i], *ranges[i], cmap, level_sets, critical_points, S, span, parts)
            for i in range(T)]


def _panel_axes(fig, where, p, r, frame, normals, view, w, titles, i):
    """The axes of panel ``p`` at ``where`` (nrows, ncols, index) of ``fig``: its picture (by
    ``r``, or matplotlib's 3D axes without a renderer), title and notes."""
    if r is not None:
        ax = fig.add_subplot(*where)
        _layout.picture(ax, p, r, frame, normals, w)
    else:
        ax = fig.add_subplot(*where, projection="3d")
        p.draw_matplotlib(ax, view, frame)
    if titles is not None:
        ax.set_title(titles[i], fontsize=9)
    notes = []
    if p.critical and not p.draw_critical and p.n_critical:
        notes.append(f"{p.n_critical:,} critical points: too many to draw")
    if p.too_dense:
        notes.append(f"{p.too_dense:,} critical points too dense to draw at this size"
                     + (" (small parts)" if p.parts.max() > 0 else ""))
    if p.left_out:
        notes.append(f"constant on {p.flat_parts} part{'s' if p.flat_parts > 1 else ''} (to numerical "
                     f"error): {p.left_out:,} critical points of the errors not drawn")
    if notes:
        _layout.note(ax, notes, w)
    return ax


def field(mesh: MeshLike, f: FieldLike, level_sets: Levels = 10, critical_points: bool | CriticalPoints = True,
          view: tuple[float, float] = (20.0, -60.0), cmap: str = "coolwarm", title: str | None = None,
          size: float = 5.0, up: str = "z", label: str = "f", renderer: str = "auto") -> Figure:
    """A mesh coloured by a field, with its level sets and critical points (paper P16).

    A 3D render (hidden surfaces removed) with a colorbar named ``label`` and a legend of the
    critical points (red maxima, blue minima, green saddles, with their numbers). Above
    ``MAX_CRITICAL_POINTS`` critical points (a noisy field) none are drawn, and the panel says so.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
        Every part of a multi-part mesh is framed.
    f : (n,) array_like
        The field, one value per vertex.
    level_sets : int, sequence of float, or None
        Number of level sets evenly spaced strictly between the field's minimum and maximum,
        their values, or None for none. They are marked on the colorbar too.
    critical_points : bool or CriticalPoints
        True computes them; False draws none.
    view : (elevation, azimuth) in degrees
        The direction the surface is seen from, ``up`` being vertical (orthographic view).
    cmap : str
        Matplotlib colormap; the range is the 2nd–98th percentile of f (the colorbar's arrows
        show values beyond it).
    title : str, optional
        Written above the panel.
    size : float
        Inches (the picture's longer side).
    up : {"z", "y", "x"}
        The axis drawn vertical (scans often have y up).
    label : str
        The field's name, written on the colorbar.
    renderer : {"auto", "raster", "matplotlib"}
        "raster": o3dheat's rasterizer (hidden surfaces removed); "matplotlib": 3D axes without
        hidden-surface removal; "auto" follows the environment variable ``O3DHEAT_RENDERER``
        (default "raster"). "open3d" is an old spelling of "raster" (deprecated).

    Returns
    -------
    matplotlib.figure.Figure
        Its first axes holds the picture, the next the colorbar.

    Examples
    --------
    >>> import open3d as o3d, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> fig = plot.field(m, m.vertex.positions.numpy()[:, 2], title="height", label="z")
    >>> fig.axes[1].get_ylabel()
    'z'
    """
    f = _layout.field_values(f, len(as_arrays(mesh)[0]))
    scene = _scene(mesh, f[:, None], view, up, level_sets, cmap, critical_points)
    return draw(scene, style=Style([title] if title else None, 1, critical_points, True, size, None, label, renderer,
                                   counts=True))


def fields(mesh: MeshLike, F_values: FieldLike, titles: Sequence[str] | None = None, ncols: int | None = None,
           level_sets: Levels = 10, critical_points: bool = True, view: tuple[float, float] = (20.0, -60.0),
           cmap: str = "coolwarm", shared_range: bool = True, size: float = 3.5, suptitle: str | None = None,
           up: str = "z", label: str = "f", renderer: str = "auto") -> Figure:
    """Several fields on one mesh side by side (for example ``Φ_t f`` at several scales).

    Parameters
    ----------
    mesh : mesh or (V, F)
        The surface, as for :func:`field`.
    F_values : (n, T) array_like
        One column per panel.
    titles : sequence of str, optional
        One per panel.
    ncols : int, optional
        Panels per row (default: all in one row, at most 5).
    level_sets, critical_points, view, cmap, up, label, renderer
        As for :func:`field` (``critical_points`` True or False).
    shared_range : bool
        One colour range, one colorbar and the same level-set values for all panels (compare
        values across scales); False gives each panel its own range, colorbar and level sets.
    size : float
        Inches per panel.
    suptitle : str, optional
        Written above all the panels.

    Returns
    -------
    matplotlib.figure.Figure
        The T pictures' axes first, then the colorbars'.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> V = m.vertex.positions.numpy()
    >>> fig = plot.fields(m, V, titles=["x", "y", "z"], critical_points=False, suptitle="coordinates")
    >>> len(fig.axes)  # three pictures and one shared colorbar
    4
    """
    G = np.asarray(F_values, dtype=np.float64)
    if G.ndim == 1:
        G = G[:, None]
    G = _layout.field_values(G, len(as_arrays(mesh)[0]))
    if G.shape[1] == 0:
        raise MeshError("no field to draw: F_values has 0 columns")
    scene = _scene(mesh, G, view, up, level_sets, cmap, critical_points)
    return draw(scene, style=Style(titles, ncols, critical_points, shared_range, size, suptitle, label, renderer))


def render(mesh: MeshLike, f: FieldLike, level_sets: Levels = 10, critical_points: bool | CriticalPoints = True,
           view: tuple[float, float] = (20.0, -60.0), cmap: str = "coolwarm", up: str = "z",
           vrange: tuple[float, float] | None = None) -> np.ndarray:
    """The 3D render alone, as an image array (what :func:`field` shows, without colorbar).

    Parameters
    ----------
    mesh, f, level_sets, critical_points, view, cmap, up
        As for :func:`field`.
    vrange : (float, float), optional
        The values mapped to the ends of the colormap (default: 2nd–98th percentile).

    Returns
    -------
    (h, w, 3) uint8 ndarray
        White background; every vertex inside the frame.

    Raises
    ------
    MeshError
        Where Open3D's offscreen renderer cannot start (the message says what to install).

    Examples
    --------
    >>> import open3d as o3d, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> img = plot.render(m, m.vertex.positions.numpy()[:, 0])
    >>> img.dtype, img.shape[2], bool((img[0] == 255).all())  # white around the sphere
    (dtype('uint8'), 3, True)
    """
    V, F = as_arrays(mesh)
    f = _layout.field_values(f, len(V))
    V = _render.upright(V, up)
    if vrange is not None:
        try:
            vr = np.asarray(checks.values(vrange), dtype=np.float64).ravel()
        except (TypeError, ValueError):
            vr = np.zeros(0)
        if len(vr) != 2 or not np.all(np.isfinite(vr)) or not vr[0] < vr[1]:
            raise MeshError(f"vrange must be two finite numbers (low, high), low < high, got {vrange!r}")
    _layout.check_style(cmap)
    topology = (level_sets is not None and level_sets is not False) or critical_points is True
    S, V, F, f = _layout.as_drawn(V, F, f, topology)
    parts = _panels.vertex_parts(len(V), F)
    flat = _panels.flat_parts(f, parts)[np.maximum(parts, 0)] & (parts >= 0)
    lo, hi = _layout.color_range(f, flat) if vrange is None else (float(vr[0]), float(vr[1]))  # of what is drawn, as field's
    frame = _render.View(V, view)
    r = _render.renderer("raster")
    panel = _panels.Panel(V, F, f, lo, hi, cmap, level_sets, critical_points, S, None, parts)
    return panel.render(r, frame, vertex_normals(V, F))
