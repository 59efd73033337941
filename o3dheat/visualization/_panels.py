"""One panel of a drawing, computed once and pictured by either renderer: :class:`Panel`, :func:`vertex_parts`.

A panel holds what it shows (colours, level sets, critical points) and the parts of the mesh where
the field is flat (:func:`flat_parts`, :func:`flattened`, :func:`without_flat`).

Notes
-----
A part of the mesh where the field is constant up to numerical error (``FLAT_RTOL``) is drawn
as constant: no level sets, no critical points of the errors (``Φ_t(e_i)`` is exactly 0 on the
parts without vertex i, a truncated kernel is constant on a part its few eigenpairs do not
reach). Markers of critical points are sized per part (``MARKER_COVER``); above
``MAX_CRITICAL_POINTS`` none are drawn.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from o3dheat import checks
from o3dheat.errors import SolverError
from o3dheat.geometry._loops import components
from o3dheat.geometry._tables import vertex_normals
from o3dheat.topology import critical_points as find_critical
from o3dheat.topology import level_sets as find_levels

from . import _render

#: Colours of the critical points (the paper's).
CRITICAL_COLORS = {"maxima": "red", "minima": "blue", "saddles": "green"}
#: Above this many critical points in a panel none are drawn (a noisy field has thousands).
MAX_CRITICAL_POINTS = 400
#: A part of the mesh on which a field varies by at most this much relative to the field's largest
#: magnitude is drawn as constant there: its "critical points" and level sets would be those of
#: numerical errors (``Φ_t(e_i)`` is exactly 0 on the parts without vertex i, but an eigensolver
#: mixes equal eigenvalues of different parts to about its tolerance: 1e-9 of the field was measured
#: there; a truncated kernel is a constant plus such errors on a part its few eigenpairs do not
#: reach). A millionth is far below what a colour shows (1/256 of the range).
FLAT_RTOL = 1e-6
#: Markers of critical points cover at most about half this fraction of the pixels of each part:
#: their radius is the smaller of 0.75% of the mesh's diagonal and what this share of the part's
#: projected area allows; a part where that is under about a pixel gets none (and the panel says so).
MARKER_COVER = 0.2


# ------------------------------------------------------------------ parts, and fields flat on a part
def vertex_parts(n, F):
    """(n,) int64: the connected part of each vertex, numbered from 0 (-1: in no face)."""
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    out = np.full(n, -1, dtype=np.int64)
    if len(F) == 0:
        return out
    label = components(F, n)[1]  # parts numbered by their smallest vertex, as below
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    out[used] = np.unique(label[used], return_inverse=True)[1]
    return out


def flat_parts(f, parts):
    """(p,) bool: the parts on which ``f`` varies by at most ``FLAT_RTOL`` times its variation over
    the whole mesh (an offset such as a georeferenced coordinate flattens nothing; one part is flat
    only when exactly constant)."""
    k = int(parts.max()) + 1 if len(parts) else 0
    used = parts >= 0
    if k == 1:  # one part: flat only when constant (its variation is the whole mesh's)
        return np.array([float(np.ptp(f[used])) == 0.0])
    lo, hi = np.full(k, np.inf), np.full(k, -np.inf)
    np.minimum.at(lo, parts[used], f[used])
    np.maximum.at(hi, parts[used], f[used])
    scale = float(np.ptp(f[used])) if used.any() else 0.0
    return hi - lo <= FLAT_RTOL * scale


def flattened(f, parts, flat):
    """``f`` with each flat part set to its mean (its numerical errors drawn as what they are: nothing)."""
    if not flat.any():
        return f
    used = parts >= 0
    mean = np.bincount(parts[used], weights=f[used], minlength=len(flat)) / np.maximum(
        np.bincount(parts[used], minlength=len(flat)), 1)
    on = used.copy()
    on[used] = flat[parts[used]]
    out = f.copy()
    out[on] = mean[parts[on]]
    return out


def without_flat(cp, parts, flat):
    """``(cp, left_out)``: the critical points not on a flat part, and how many were left out."""
    def keep(idx):
        idx = np.asarray(idx, dtype=np.int64)
        p = parts[idx] if len(idx) else np.zeros(0, np.int64)
        return (p < 0) | ~flat[np.maximum(p, 0)]

    km, ks, kM = keep(cp.minima), keep(cp.saddles), keep(cp.maxima)
    left_out = int((~km).sum() + np.asarray(cp.saddle_multiplicity)[~ks].sum() + (~kM).sum())
    if not left_out:
        return cp, 0
    return dataclasses.replace(cp, minima=np.asarray(cp.minima)[km], saddles=np.asarray(cp.saddles)[ks],
                               saddle_multiplicity=np.asarray(cp.saddle_multiplicity)[ks],
                               maxima=np.asarray(cp.maxima)[kM]), left_out


# ------------------------------------------------------------------ one panel
class Panel:
    """What one panel shows, computed once: colours, level sets, critical points."""

    def __init__(self, V, F, f, lo, hi, cmap, level_sets, critical_points, S, span=None, parts=None):
        self.parts = vertex_parts(len(V), F) if parts is None else parts
        flat = flat_parts(f, self.parts)
        self.flat_parts = int(flat.sum())
        f = flattened(f, self.parts, flat)  # errors on a flat part: no level sets, no critical points
        self.V, self.F, self.f, self.lo, self.hi, self.cmap = V, F, f, lo, hi, cmap
        self.left_out = 0  # critical points on flat parts, not drawn
        self.too_dense = 0  # critical points on parts too small for their markers, not drawn (set by render)
        self.levels = np.zeros(0)
        self.segments = np.zeros((0, 2, 3))
        if level_sets is not None and level_sets is not False:
            if np.isscalar(level_sets):
                count = checks.count(level_sets, "level_sets", maximum=1000)  # 2.5 is refused, not cut
                a, b = span if span is not None else (f.min(), f.max())  # panels compared: the same values
                self.levels = np.linspace(a, b, count + 2)[1:-1] if b > a else np.zeros(0)
            else:
                self.levels = np.atleast_1d(np.asarray(level_sets, dtype=np.float64))
            if len(self.levels):
                ls = find_levels(S if S is not None else (V, F), f, values=self.levels)
                P, L = np.asarray(ls.points), np.asarray(ls.lines)
                self.segments = P[L] if len(L) else np.zeros((0, 2, 3))
        self.critical = {}
        if critical_points is not None and critical_points is not False:
            if critical_points is True:
                cp, self.left_out = without_flat(find_critical(S if S is not None else (V, F), f), self.parts, flat)
            else:
                cp = critical_points
            self.critical = {kind: np.asarray(getattr(cp, kind)) for kind in CRITICAL_COLORS}
            m, s, M = cp.counts  # a saddle of multiplicity k counts k times, as everywhere in o3dheat
            self.counts = {"minima": m, "saddles": s, "maxima": M}
        self.n_critical = sum(self.counts.values()) if self.critical else 0
        self.draw_critical = 0 < self.n_critical <= MAX_CRITICAL_POINTS

    def rgb(self, values):
        from matplotlib import colormaps

        s = np.clip((values - self.lo) / (self.hi - self.lo), 0, 1) if self.hi > self.lo else np.full(len(values), 0.5)
        cmap = colormaps[self.cmap] if isinstance(self.cmap, str) else self.cmap
        return cmap(s)[:, :3]

    def marker_radii(self, view, point_size=1.0, pixel=None):
        """(p,) radius of the critical points' markers on each part (0: none drawn there).

        At most 0.75% of the mesh's diagonal, and small enough that a part's markers, as discs,
        cover at most ``MARKER_COVER`` of its projected area ``Σ |a_f · d| / 2`` (``a_f`` the
        faces' area vectors, ``d`` toward the viewer: the silhouette of a closed part, whose hidden
        half of the markers does not show; half that of a sheet): about half of that share of the
        part's pixels. A radius under 1.2 ``pixel`` (world units; default: a pixel of the render)
        is too small to see: that part gets no markers."""
        k = int(self.parts.max()) + 1 if len(self.parts) else 0
        V, F = self.V, self.F
        a = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]) / 2
        area = np.bincount(self.parts[F[:, 0]], weights=np.abs(a @ view.d) / 2, minlength=k)
        idx = np.concatenate([self.critical[kind] for kind in CRITICAL_COLORS]).astype(np.int64)
        count = np.bincount(self.parts[idx], minlength=k) if len(idx) else np.zeros(k)
        r = np.minimum(0.0075 * view.diagonal * point_size,
                       np.sqrt(MARKER_COVER * area / (np.pi * np.maximum(count, 1))))
        pixel = 2 * view.half / _render.RENDER_SIZE if pixel is None else pixel
        return np.where(r >= 1.2 * pixel, r, 0.0)

    def render(self, renderer, view, normals, line_width=None, point_size=1.0, pixel=None, paths=None):
        """(h, w, 3) uint8 image of the surface, its level sets and critical points;
        ``line_width`` in pixels of the render (default: a third of a percent of its size);
        ``pixel``: the size of a pixel of the final picture in world units (markers smaller than
        about one are not drawn, see :meth:`marker_radii`); ``paths``: more segments to draw
        just off the surface, ``((m, 2, 3) positions, (m, 3) colours)`` (the tracks of
        :func:`tracks`)."""
        V, F = self.V, self.F
        V = V - view.target  # about the origin: float32 keeps the detail of a scan far from it
        meshes = [_render.tmesh(V, F, self.rgb(self.f) * _render.shade(normals, view)[:, None])]
        eps = 0.0015 * view.diagonal  # level sets and points sit just off the surface, on the viewer's side
        toward = normals * np.where(normals @ view.d < 0, -1.0, 1.0)[:, None]
        lines = None
        if len(self.segments):
            from scipy.spatial import cKDTree

            P = self.segments.reshape(-1, 3) - view.target
            _, near = cKDTree(V).query(P)
            grazing = (np.abs(normals[near] @ view.d) < 0.1).reshape(-1, 2).all(axis=1)
            keep = np.repeat(~grazing, 2)  # edge-on segments would stick out of the silhouette
            P = P[keep] + eps * toward[near[keep]]
            if len(P):
                lines = (P.reshape(-1, 2, 3), np.zeros((len(P) // 2, 3)))  # solid black, as in the legend
        if paths is not None and len(paths[0]):  # tubes: shaded, hidden where the surface is in front
            from scipy.spatial import cKDTree

            P = np.asarray(paths[0], dtype=np.float64).reshape(-1, 3) - view.target
            _, near = cKDTree(V).query(P)
            P = (P + 2 * eps * toward[near]).reshape(-1, 2, 3)
            radius = 1.5 * (2 * view.half / _render.RENDER_SIZE if pixel is None else pixel)  # about 3 pixels wide
            meshes.append(_render.tubes(P, radius, np.asarray(paths[1], dtype=np.float64).reshape(-1, 3), view))
        self.too_dense = 0
        if self.draw_critical:
            from matplotlib.colors import to_rgb

            Vs, Fs = _render.sphere()
            radius = self.marker_radii(view, point_size, pixel)
            for kind, color in CRITICAL_COLORS.items():
                idx = self.critical[kind]
                r = radius[self.parts[idx]] if len(idx) else np.zeros(0)
                self.too_dense += int((r == 0).sum())
                idx, r = idx[r > 0], r[r > 0, None]
                if not len(idx):
                    continue
                centers = V[idx] + 0.5 * r * toward[idx]
                P = (centers[:, None, :] + r[:, :, None] * Vs[None]).reshape(-1, 3)
                T = (Fs[None] + len(Vs) * np.arange(len(idx))[:, None, None]).reshape(-1, 3)
                shade = _render.shade(np.tile(Vs, (len(idx), 1)), view)
                meshes.append(_render.tmesh(P, T, np.asarray(to_rgb(color))[None] * shade[:, None]))
        size = renderer.size
        width = max(2.5, size / 300 if line_width is None else line_width)  # thinner lines break up
        rows, cols = view.crop(size)
        img = renderer.image(meshes, lines, width, view)[rows, cols]
        if not (img < 250).any(axis=2).mean() > 1e-3:  # cannot happen with the rasterizer: a guard
            raise SolverError(f"the renderer drew nothing for a mesh of {len(F)} faces framed in view: "
                              "a blank picture is not written")
        return img

    def draw_matplotlib(self, ax, view_angles, view):
        """The fallback: matplotlib's 3D axes (painter's algorithm; lines and points are drawn
        only where the nearest vertex faces the viewer)."""
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

        V, F = self.V, self.F
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
        colors = np.c_[self.rgb(self.f[F].mean(axis=1)) * _render.shade(n, view)[:, None], np.ones(len(F))]
        facing = vertex_normals(V, F) @ view.d >= 0
        ax.computed_zorder = False
        ax.add_collection3d(Poly3DCollection(V[F], facecolors=colors, edgecolors="none", linewidths=0, zorder=1))
        if len(self.segments):
            from scipy.spatial import cKDTree

            _, near = cKDTree(V).query(self.segments.mean(axis=1))
            ax.add_collection3d(Line3DCollection(self.segments[facing[near]], colors="black", linewidths=0.6,
                                                 zorder=2))
        if self.draw_critical:
            for kind, color in CRITICAL_COLORS.items():
                idx = self.critical[kind]
                idx = idx[facing[idx]]
                if len(idx):
                    ax.scatter(*V[idx].T, color=color, s=14, depthshade=False, edgecolors="white",
                               linewidths=0.3, zorder=3)
        lo_v, hi_v = V.min(0), V.max(0)
        ax.set_xlim(lo_v[0], hi_v[0])
        ax.set_ylim(lo_v[1], hi_v[1])
        ax.set_zlim(lo_v[2], hi_v[2])
        ax.set_box_aspect(np.maximum(np.ptp(V, axis=0), 1e-9 * view.diagonal))  # equal scales
        ax.view_init(elev=view_angles[0], azim=view_angles[1])
        ax.set_axis_off()

