"""A figure of panels: the drawn mesh (:func:`welded`, :func:`oriented`), colour range, colorbars, legends.

The mesh as the drawings see it (:func:`welded`, :func:`surface`, :func:`repaired`,
:func:`oriented`), the colour range (:func:`color_range`), colorbars, legends, notes and sizes,
and the checks of the drawings' arguments (:func:`check_style`, :func:`check_tracks`).
"""

from __future__ import annotations

import logging
import textwrap

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, prepare, repair
from o3dheat.geometry._loops import components
from o3dheat.topology import Surface, Tracks

from ._panels import CRITICAL_COLORS

#: The colour of a track of each kind (:data:`o3dheat.topology.tracking.KINDS`): the critical points' colours.
KIND_COLORS = {"minimum": CRITICAL_COLORS["minima"], "saddle": CRITICAL_COLORS["saddles"],
               "maximum": CRITICAL_COLORS["maxima"]}
PLURAL = {"minimum": "minima", "saddle": "saddles", "maximum": "maxima"}


# ------------------------------------------------------------------ composing figures
def field_values(f, n):
    return checks.field(f, n, "the field")


def welded(V, F, values):
    """``(V, F, values)`` as every o3dheat function sees the mesh (:func:`o3dheat.geometry.welding.prepare`):
    exactly coincident vertices welded (an STL file's per-triangle copies: otherwise every
    triangle is a part of its own, with its own critical points, and the shading is faceted),
    degenerate faces and unreferenced vertices dropped; a welded vertex's value is the mean of
    its copies'."""
    used = np.unique(np.asarray(F).reshape(-1))
    if 0 < len(used) < len(V):  # said here: prepare's message (value 0 in every result) is not a picture's
        logging.getLogger("o3dheat").warning("%d vertices are in no face: not drawn", len(V) - len(used))
        index = np.zeros(len(V), dtype=np.int64)
        index[used] = np.arange(len(used))
        V, F, values = V[used], index[F], values[used]
    p = prepare((V, F))
    return p.V, p.F, p.restrict(values)


def surface(V, F, values, level_sets, critical_points):
    """``(S, V, F, values)``: the checked surface, built once per mesh, when level sets or critical
    points are drawn (else None). A mesh that is not a 2-manifold (a scan with non-manifold edges
    or vertices) is drawn as :func:`o3dheat.repair <o3dheat.geometry.repairs.repair>` makes it, with a warning: the same surface,
    each fan of faces with its own copy of a shared vertex (the copy keeps the vertex's value)."""
    wanted = (level_sets is not None and level_sets is not False) or critical_points is True
    if not wanted:
        return None, V, F, values
    try:
        return Surface.from_faces(len(V), F, V), V, F, values
    except MeshError as e:
        if "manifold" not in str(e):
            raise
        V2, F2, values = repaired(V, F, values, str(e).split(":")[0], "level sets and critical points are drawn")
        return Surface.from_faces(len(V2), F2, V2), V2, F2, values


def as_drawn(V, F, values, topology):
    """``(S, V, F, values)``: the mesh as every drawing sees it (:func:`welded`, then :func:`surface`
    when ``topology`` — level sets or critical points — is drawn, else S is None; then
    :func:`oriented`), the values following their vertices."""
    V, F, values = welded(V, F, values)
    S, V, F, values = surface(V, F, values, topology, topology)
    return S, V, oriented(V, F), values


def repaired(V, F, values, why, what):
    """``(V, F, values)`` of a non-manifold mesh as :func:`o3dheat.repair <o3dheat.geometry.repairs.repair>` makes it (split, not
    reoriented), each copy of a vertex with its value, and a warning saying ``why`` and ``what``
    is made on it: the one repair of the drawings and the figure recipes."""
    r = repair((V, F), orient=False)
    V2, F2 = as_arrays(r.mesh)
    logging.getLogger("o3dheat").warning("%s: %s on the mesh as o3dheat.repair makes it (%s)", why, what, r)
    return V2, F2, values[r.source]


def oriented(V, F):
    """F with every component's faces wound consistently (Open3D's ``orient_triangles``, only where
    some directed edge is repeated: a mesh wound consistently has each directed edge once) and
    each closed component's normals outward (positive signed volume): the drawing's shading, level-set
    lifting and the matplotlib fallback's hidden points all read vertex normals, which an
    inward or mixed winding (common in OBJ/STL exports) would turn around or cancel. A mesh with
    non-manifold edges is returned as it is."""
    import open3d as o3d

    F = np.asarray(F, dtype=np.int64)
    if len(F) == 0:
        return F
    n = len(V)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    directed = np.sort(E[:, 0] * n + E[:, 1])
    if (directed[1:] == directed[:-1]).any():  # not wound consistently (or an edge of 3+ faces): Open3D's BFS
        legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V),
                                           o3d.utility.Vector3iVector(F.astype(np.int32)))
        if not legacy.is_edge_manifold(allow_boundary_edges=True):
            return F
        if legacy.orient_triangles():
            F = np.asarray(legacy.triangles, dtype=np.int64)
            E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    label = components(F, n)[1]  # the same parts as E's graph has
    face = label[F[:, 0]]
    c = V.mean(axis=0)
    volume = np.einsum("ij,ij->i", V[F[:, 0]] - c, np.cross(V[F[:, 1]] - c, V[F[:, 2]] - c))
    undirected = np.sort(E, axis=1)
    _, inverse, counts = np.unique(undirected[:, 0] * n + undirected[:, 1], return_inverse=True, return_counts=True)
    open_component = np.zeros(label.max() + 1, bool)
    open_component[face[np.flatnonzero(counts[inverse] == 1) % len(F)]] = True
    flip = (np.bincount(face, weights=volume, minlength=len(open_component)) < 0) & ~open_component
    if flip.any():
        F = np.where(flip[face][:, None], F[:, ::-1], F)
    return F


def color_range(values, flat=None):
    """The colour range: the 2nd–98th percentile of the values; with ``flat`` (a mask of the same
    shape: the vertices of parts where the field is constant) of the others only, widened to the
    flat parts' values (a small part holding all the variation is not clipped away by the
    constant ones)."""
    if flat is not None and flat.any() and not flat.all():
        lo, hi = color_range(values[~flat])
        return min(lo, float(values[flat].min())), max(hi, float(values[flat].max()))
    lo, hi = np.percentile(values, [2, 98])
    if not hi > lo:
        lo, hi = float(np.min(values)), float(np.max(values))
    return float(lo), float(hi)


def colorbar(fig, ax, panel, label, location, values):
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.ticker import MaxNLocator, ScalarFormatter

    lo, hi = (panel.lo, panel.hi) if panel.hi > panel.lo else (panel.lo - 0.5, panel.lo + 0.5)
    extend = {(False, False): "neither", (True, False): "min", (False, True): "max", (True, True): "both"}[
        (bool(values.min() < lo), bool(values.max() > hi))]
    fmt = ScalarFormatter(useMathText=True)
    fmt.set_powerlimits((-2, 3))
    horizontal = location == "bottom"
    cb = fig.colorbar(ScalarMappable(Normalize(lo, hi), panel.cmap), ax=ax, location=location, extend=extend,
                      format=fmt, shrink=0.85 if horizontal else 0.8, aspect=22 if horizontal else 25,
                      pad=0.02)
    cb.set_ticks(MaxNLocator(4 if horizontal else 6))
    cb.set_label(label, fontsize=9)
    cb.ax.tick_params(labelsize=8)
    levels = panel.levels[(panel.levels >= lo) & (panel.levels <= hi)]
    if len(levels) and len(levels) <= 50:
        cb.add_lines(levels, colors=["black"] * len(levels), linewidths=[0.6] * len(levels))
    return cb


def legend(fig, panels, counts):
    from matplotlib.lines import Line2D

    handles = []
    if any(len(p.segments) for p in panels):
        n = max(len(p.levels) for p in panels)
        handles.append(Line2D([], [], color="black", lw=1.0, label=f"level sets ({n})"))
    if any(p.critical for p in panels):
        for kind, color in CRITICAL_COLORS.items():
            label = kind + (f" ({panels[0].counts[kind]:,})" if counts else "")
            handles.append(Line2D([], [], ls="", marker="o", ms=6, color=color, markeredgecolor="white",
                                  label=label))
    if handles:
        # one row when it fits the figure's width (about 0.065 inch per character at 8 points, plus
        # the marker and the spacing), else as many rows as needed (a narrow mesh's single figure)
        widths = [0.065 * len(h.get_label()) + 0.45 for h in handles]
        ncols = len(handles)
        while ncols > 1 and max(sum(widths[i:i + ncols]) for i in range(0, len(widths), ncols)) > fig.get_figwidth() - 0.2:
            ncols -= 1
        fig.legend(handles=handles, loc="outside lower center", ncols=ncols, fontsize=8, frameon=False,
                   handletextpad=0.3, columnspacing=1.2)


def check_style(cmap, size=1.0):
    """A matplotlib colormap name and a positive size, or a MeshError naming them."""
    from matplotlib import colormaps

    if not isinstance(cmap, str) or cmap not in colormaps:
        raise MeshError(f"cmap must be the name of a matplotlib colormap (e.g. 'coolwarm', 'viridis'), got {cmap!r}")
    if isinstance(size, bool) or not isinstance(size, (int, float, np.integer, np.floating)) or not 0 < size <= 100:
        raise MeshError(f"size must be a number of inches in (0, 100], got {size!r}")



def check_tracks(tr):
    if not isinstance(tr, Tracks):
        raise MeshError(f"expected Tracks (from o3dheat.track_critical_points), got {type(tr).__name__}")
    return tr


def by_lifetime(tr):
    """Track indices, the longest-lived first: lifetime (living at the last scale: longest), then
    the number of scales lived at, then the earlier start, then the index."""
    first, last = tr.first, tr.last
    return np.lexsort((np.arange(len(tr)), first, -(last - first), -tr.lifetime))



def picture_size(frame, size):
    """``(w, h)`` inches of a picture of ``frame`` whose longer side is ``size``."""
    aspect = float(np.clip(np.ptp(frame.u) / np.ptp(frame.v), 0.25, 4.0))  # width / height of a picture
    w = size * min(1.0, aspect) if aspect < 1 else size
    return w, w / aspect


def picture(ax, panel, r, frame, normals, w, paths=None):
    """``panel`` rendered by ``r`` into ``ax``, a picture ``w`` inches wide (``paths``: see
    :meth:`Panel.render <o3dheat.visualization._panels.Panel.render>`)."""
    # level sets 1.6 pixels wide in the saved figure (100 dpi), whatever the downsampling
    shrink = r.size * np.ptp(frame.u) / (2 * frame.half) / (w * 100)
    image = panel.render(r, frame, normals, line_width=1.6 * shrink, pixel=np.ptp(frame.u) / (w * 100), paths=paths)
    ax.imshow(_binned(image, int(image.shape[1] // (w * 100))), interpolation="antialiased")
    ax.set_axis_off()


def _binned(image, k):
    """``image`` (h, w, c) uint8 averaged over k x k blocks (k >= 2; else as it is): the render's
    supersampling brought near the figure's pixels by a box filter, so that matplotlib's
    antialiasing filter (its cost grows with the input's pixels) only bridges the last step."""
    if k < 2:
        return image
    h, w = image.shape[0] // k * k, image.shape[1] // k * k
    blocks = image[:h, :w].reshape(h // k, k, w // k, k, -1).astype(np.float32)
    return np.rint(blocks.mean(axis=(1, 3))).astype(np.uint8)


def note(ax, notes, w, each=True):
    """Write ``notes`` (str) in grey under a panel ``w`` inches wide: each wrapped on its own
    lines, or (``each=False``) joined by "; " and wrapped together."""
    width = max(20, int(w / 0.055))  # characters of 7 points across the panel
    if each:
        text = "\n".join(line for n in notes for line in textwrap.wrap(n, width))
    else:
        text = "\n".join(textwrap.wrap("; ".join(notes), width))
    put = getattr(ax, "text2D", ax.text)  # 3D axes' text takes (x, y, z, s)
    put(0.5, 0.0, text, transform=ax.transAxes, ha="center", va="top", fontsize=7, color="0.35")


def washed(cmap):
    """The colormap mixed halfway with white: the surface under the tracks, which keep the pure
    critical-point colours (a saturated colormap's red and blue ends would hide them)."""
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap

    base = colormaps[cmap](np.linspace(0.0, 1.0, 256))[:, :3]
    return ListedColormap(0.45 + 0.55 * base, name=f"{cmap}_washed")
