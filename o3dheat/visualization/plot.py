"""Fields drawn on surfaces as 3D renders: :func:`field`, :func:`fields`, :func:`render`, :func:`tracks`.

:func:`fields` draws panels across scales, :func:`render` the picture alone, :func:`tracks` the
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

from collections.abc import Sequence
from types import SimpleNamespace
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
from .charts import lifetime_chart, persistence_diagram, scale_space, study

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from o3dheat.topology import CriticalPoints, Tracks
    from o3dheat.typing import FieldLike, MeshLike

__all__ = ["field", "fields", "render", "renderer_available", "scale_space", "study", "drawn_critical_points",
           "persistence_diagram", "tracks", "lifetime_chart", "CRITICAL_COLORS"]

#: A track's move between two scales longer than this fraction of the mesh's diagonal is not drawn
#: (an extremum that flows far, a saddle matched far away): a straight line would cut across the surface.
JUMP = 0.05
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



def _compose(V, F, values, titles, ncols, level_sets, critical_points, view, cmap, shared_range, size,
             suptitle, up, label, renderer, single):
    """The figure of :func:`field` and :func:`fields`: one panel per column of ``values``."""
    from matplotlib.figure import Figure  # no pyplot: no GUI backend, no global state

    _layout.check_style(cmap, size)
    V = _render.upright(V, up)
    T = values.shape[1]
    if titles is not None and len(titles) != T:
        raise MeshError(f"{len(titles)} titles for {T} fields")
    if ncols is not None:
        ncols = checks.count(ncols, "ncols")
    ncols = min(ncols or min(T, 5), T)
    nrows = -(-T // ncols)
    V, F, values = _layout.welded(V, F, values)
    S, V, F, values = _layout.surface(V, F, values, level_sets, critical_points)
    F = _layout.oriented(V, F)
    frame = _render.View(V, view)
    r = _render.renderer(renderer)  # here: its warning names the caller of field or fields
    panels = _panels_of(V, F, values, cmap, level_sets, critical_points, S, shared_range)
    w, h = _layout.picture_size(frame, size)
    extra_h = (0.35 if titles is not None else 0.0) + (0.45 if not shared_range else 0.0)
    fig = Figure(figsize=(ncols * w + (1.1 if shared_range else 0.2),
                          nrows * (h + extra_h) + 0.45 + (0.45 if suptitle else 0.0)),
                 dpi=100, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.04, h_pad=0.04, wspace=0.03, hspace=0.05)
    normals = vertex_normals(V, F)
    axes = [_panel_axes(fig, (nrows, ncols, i + 1), p, r, frame, normals, view, w, titles, i)
            for i, p in enumerate(panels)]
    if shared_range:
        _layout.colorbar(fig, axes, panels[0], label, "right", values)
    else:
        for ax, p in zip(axes, panels, strict=True):
            _layout.colorbar(fig, ax, p, label, "bottom", p.f)
    _layout.legend(fig, panels, counts=single)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    return fig


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
    V, F = as_arrays(mesh)
    f = _layout.field_values(f, len(V))
    return _compose(V, F, f[:, None], [title] if title else None, 1, level_sets, critical_points, view, cmap,
                    True, size, None, up, label, renderer, single=True)


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
    V, Fc = as_arrays(mesh)
    G = np.asarray(F_values, dtype=np.float64)
    if G.ndim == 1:
        G = G[:, None]
    G = _layout.field_values(G, len(V))
    if G.shape[1] == 0:
        raise MeshError("no field to draw: F_values has 0 columns")
    return _compose(V, Fc, G, titles, ncols, level_sets, critical_points, view, cmap, shared_range, size,
                    suptitle, up, label, renderer, single=False)


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
    V, F, f = _layout.welded(V, F, f)
    S, V, F, f = _layout.surface(V, F, f, level_sets, critical_points)
    parts = _panels.vertex_parts(len(V), F)
    flat = _panels.flat_parts(f, parts)[np.maximum(parts, 0)] & (parts >= 0)
    lo, hi = _layout.color_range(f, flat) if vrange is None else (float(vr[0]), float(vr[1]))  # of what is drawn, as field's
    F = _layout.oriented(V, F)
    frame = _render.View(V, view)
    r = _render.renderer("raster")
    panel = _panels.Panel(V, F, f, lo, hi, cmap, level_sets, critical_points, S, None, parts)
    return panel.render(r, frame, vertex_normals(V, F))



def tracks(mesh: MeshLike, tracks: Tracks, f: FieldLike | None = None, longest: int | None = None,
           view: tuple[float, float] = (20.0, -60.0), cmap: str = "Greys", title: str | None = None,
           size: float = 6.0, up: str = "z", label: str = "f", renderer: str = "auto") -> Figure:
    """The critical points' tracks across scales on the surface (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`).

    One polyline per track through its positions at the scales it lives at (minima blue, saddles
    green, maxima red: :data:`CRITICAL_COLORS`), and a marker where it ends (for a track alive at
    the last scale: its position there). The surface is drawn as by :func:`field` (the same
    renderer, hidden surfaces removed: a track behind the surface does not show), coloured by
    ``f`` at the first scale (default in greys, so that no colour of the surface is a track's)
    in a colormap washed halfway to white so that the tracks stand out, or plain grey without
    ``f``. A move between two scales longer than ``JUMP`` of the mesh's diagonal (and than 2.5
    mean edge lengths) is left out of the line (the panel counts them): a straight line would cut across the surface. Markers are sized per part as the critical points' are
    (``MARKER_COVER``); above ``MAX_CRITICAL_POINTS`` ends none are drawn (the panel says so).

    Parameters
    ----------
    mesh : mesh or (V, F)
        The mesh the tracks were made on (same vertices).
    tracks : Tracks
        With vertex positions (as :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>` makes them).
    f : (n,) or (n, T) array_like, optional
        The field; of (n, T) (one column per scale, as given to the tracking) the first column.
    longest : int, optional
        Draw only this many tracks, the longest-lived (alive at the last scale first, then by
        lifetime and the number of scales lived at): a noisy field has thousands that live at
        one or two scales. Default: all.
    view, cmap, title, size, up, label, renderer
        As for :func:`field`.

    Returns
    -------
    matplotlib.figure.Figure
        Its first axes holds the picture (then the colorbar, with ``f``); a legend counts the
        tracks drawn of each kind.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> x = m.vertex.positions.numpy()[:, 0]
    >>> t = [0.0, 0.1, 0.2]
    >>> tr = o3dheat.track_critical_points(m, np.c_[x, 2 * x, 3 * x], t)
    >>> fig = plot.tracks(m, tr, x, title="x on a torus")
    >>> [t.get_text() for t in fig.legends[0].get_texts()][:3]
    ['minima (1 track)', 'saddles (2 tracks)', 'maxima (1 track)']
    """
    from matplotlib.figure import Figure

    tr = _layout.check_tracks(tracks)
    V, F = as_arrays(mesh)
    if tr.positions_of is None or len(tr.positions_of) != len(V):
        raise MeshError(f"the tracks are not of this mesh ({len(V)} vertices): pass the mesh given to "
                        "o3dheat.track_critical_points")
    _layout.check_style(cmap, size)
    if longest is not None:
        longest = checks.count(longest, "longest")
    g = np.zeros(len(V)) if f is None else _first_scale(f, len(V))
    V = _render.upright(V, up)
    P = tr.positions[..., _render.UP[up]] if len(tr) else np.zeros((0, len(tr.times), 3))
    order = _layout.by_lifetime(tr)
    chosen = order if longest is None else order[:longest]
    V, F, g = _layout.welded(V, F, g)
    F = _layout.oriented(V, F)
    frame = _render.View(V, view)
    r = _render.renderer(renderer)  # here: its warning names the caller of tracks
    parts = _panels.vertex_parts(len(V), F)
    kinds = np.asarray(tr.kind)[chosen]
    segments, colors, jumps, jump = _paths(tr, P, chosen, kinds, V, F, frame)
    panel, counts = _ends_panel(tr, P, chosen, kinds, V, F, g, parts, None if f is None else cmap)
    w, h = _layout.picture_size(frame, size)
    fig = Figure(figsize=(w + (1.1 if f is not None else 0.2), h + 0.9 + (0.35 if title else 0.0)), dpi=100,
                 layout="constrained")
    fig.get_layout_engine().set(w_pad=0.04, h_pad=0.04)
    ax = _tracks_axes(fig, panel, r, frame, V, F, view, w, segments, colors)
    if title:
        ax.set_title(title, fontsize=10)
    notes = []
    if longest is not None and len(chosen) < len(tr):
        notes.append(f"the {len(chosen):,} longest-lived of {len(tr):,} tracks")
    if jumps:
        notes.append(f"{jumps:,} move{'s' if jumps > 1 else ''} between two scales longer than "
                     f"{100 * jump / frame.diagonal:.2g}% of the mesh's size not drawn (a line across would not "
                     "lie on the surface)")
    if panel.critical and not panel.draw_critical and panel.n_critical:
        notes.append(f"{panel.n_critical:,} track ends: too many to mark")
    if panel.too_dense:
        notes.append(f"{panel.too_dense:,} track ends too dense to mark at this size")
    if notes:
        _layout.note(ax, notes, w, each=False)
    if f is not None:
        _layout.colorbar(fig, ax, panel, label + " (first scale)", "right", panel.f)
    _tracks_legend(fig, tr, counts)
    return fig


def _first_scale(f, n):
    """The field of :func:`tracks`: of (n, T) values (one column per scale) the first column."""
    G = np.asarray(checks.values(f), dtype=np.float64)
    return _layout.field_values(G[:, 0] if G.ndim == 2 else G, n)


def _paths(tr, P, chosen, kinds, V, F, frame):
    """``(segments, colors, jumps, jump)``: the tracks' paths, consecutive living positions that
    differ and are at most ``jump`` apart, in their kinds' colours, and how many moves were longer."""
    from matplotlib.colors import to_rgb

    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    edge = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean()) if len(E) else 0.0
    jump = max(JUMP * frame.diagonal, 2.5 * edge)  # a move along an edge or two lies on the surface
    jumps = 0
    segs, cols = [], []
    for i, kind in zip(chosen, kinds, strict=True):
        Q = P[i, tr.first[i]:tr.last[i] + 1]
        length = np.linalg.norm(Q[1:] - Q[:-1], axis=1)
        jumps += int((length > jump).sum())
        step = (length > 0) & (length <= jump)
        if step.any():
            segs.append(np.stack([Q[:-1][step], Q[1:][step]], 1))
            cols.append(np.tile(to_rgb(_layout.KIND_COLORS[kind]), (int(step.sum()), 1)))
    segments = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
    colors = np.concatenate(cols) if cols else np.zeros((0, 3))
    return segments, colors, jumps, jump


def _ends_panel(tr, P, chosen, kinds, V, F, g, parts, cmap):
    """``(panel, counts)``: the surface coloured by ``g`` (``cmap`` washed; None: plain grey) with
    a marker at each chosen track's end (a vertex each: exact positions), and the tracks of each kind."""
    from scipy.spatial import cKDTree

    if cmap is None:
        lo, hi, colormap = -0.6, 1.4, "Greys"  # g = 0: a light grey
    else:
        flat = _panels.flat_parts(g, parts)[np.maximum(parts, 0)] & (parts >= 0)
        lo, hi = _layout.color_range(g, flat)
        colormap = _layout.washed(cmap)
    ends = P[chosen, tr.last[chosen]] if len(chosen) else np.zeros((0, 3))
    end_vertex = cKDTree(V).query(ends)[1] if len(ends) else np.zeros(0, np.int64)
    counts = {k: int((kinds == k).sum()) for k in _layout.KIND_COLORS}
    cp = SimpleNamespace(**{_layout.PLURAL[k]: end_vertex[kinds == k] for k in _layout.KIND_COLORS},
                         counts=(counts["minimum"], counts["saddle"], counts["maximum"]))
    return _panels.Panel(V, F, g, lo, hi, colormap, None, cp, None, None, parts), counts


def _tracks_axes(fig, panel, r, frame, V, F, view, w, segments, colors):
    """The axes of the tracks' picture: the surface and its end markers with the paths as tubes (by
    ``r``), or matplotlib's 3D axes with the paths as lines where they face the viewer."""
    normals = vertex_normals(V, F)
    if r is not None:
        ax = fig.add_subplot(1, 1, 1)
        _layout.picture(ax, panel, r, frame, normals, w, paths=(segments, colors))
        return ax
    from mpl_toolkits.mplot3d.art3d import Line3DCollection
    from scipy.spatial import cKDTree

    ax = fig.add_subplot(1, 1, 1, projection="3d")
    panel.draw_matplotlib(ax, view, frame)
    if len(segments):
        _, near = cKDTree(V).query(segments.mean(axis=1))
        facing = normals[near] @ frame.d >= 0
        ax.add_collection3d(Line3DCollection(segments[facing], colors=colors[facing], linewidths=1.6, zorder=2))
    return ax


def _tracks_legend(fig, tr, counts):
    from matplotlib.lines import Line2D

    K, plural = _layout.KIND_COLORS, _layout.PLURAL
    handles = [Line2D([], [], color=K[k], lw=2.0, marker="o", ms=5, markeredgecolor="white",
                      label=f"{plural[k]} ({counts[k]:,} track{'s' if counts[k] != 1 else ''})") for k in K]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False,
               title=f"tracks over {len(tr.times)} scales, ● where each ends (or at the last scale)",
               title_fontsize=8)
