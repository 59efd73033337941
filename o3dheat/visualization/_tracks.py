"""The critical points' tracks across scales drawn on the surface: :func:`tracks` (public as
:func:`o3dheat.visualization.plot.tracks`)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays
from o3dheat.geometry._tables import vertex_normals

from . import _layout, _panels, _render

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from o3dheat.topology import Tracks
    from o3dheat.typing import FieldLike, MeshLike

__all__ = ["tracks", "JUMP"]

#: A track's move between two scales longer than this fraction of the mesh's diagonal is not drawn
#: (an extremum that flows far, a saddle matched far away): a straight line would cut across the surface.
JUMP = 0.05


def tracks(mesh: MeshLike, tracks: Tracks, f: FieldLike | None = None, longest: int | None = None,
           view: tuple[float, float] = (20.0, -60.0), cmap: str = "Greys", title: str | None = None,
           size: float = 6.0, up: str = "z", label: str = "f", renderer: str = "auto") -> Figure:
    """The critical points' tracks across scales on the surface (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`).

    One polyline per track through its positions at the scales it lives at (minima blue, saddles
    green, maxima red: :data:`CRITICAL_COLORS`), and a marker where it ends (for a track alive at
    the last scale: its position there). The surface is drawn as by :func:`~o3dheat.visualization.plot.field` (the same
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
        As for :func:`o3dheat.visualization.plot.field`.

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
    segments, colors, jumps, jump = _paths(tr, P, chosen, kinds, V, F)
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


def longest_move(V, F):
    """The longest move of a track between two scales that is drawn, in the mesh's units: ``JUMP``
    of the diagonal, or 2.5 mean edge lengths if longer (a move along an edge or two lies on the
    surface; a longer straight line would cut across it). The static figures and the page use it."""
    F = np.asarray(F)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    edge = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean()) if len(E) else 0.0
    return max(JUMP * float(np.linalg.norm(np.ptp(V, axis=0))), 2.5 * edge)


def _paths(tr, P, chosen, kinds, V, F):
    """``(segments, colors, jumps, jump)``: the tracks' paths, consecutive living positions that
    differ and are at most ``jump`` apart, in their kinds' colours, and how many moves were longer."""
    from matplotlib.colors import to_rgb

    jump = longest_move(V, F)
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
