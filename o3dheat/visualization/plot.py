"""Drawing only: fields on surfaces as real 3D renders, and charts.

Surfaces are rendered with Open3D's offscreen renderer (Filament, software Vulkan through Mesa's
lavapipe: no display and no GPU needed), with depth: level sets and critical points are drawn on
the visible surface and hidden behind it. The renders are composed into a
``matplotlib.figure.Figure`` with a colorbar named after the field and a legend of the critical
points (maxima red, minima blue, saddles green, as in the paper). Charts (:func:`scale_space`,
:func:`study`) are plain matplotlib. Nothing is shown on screen: save a figure with
``fig.savefig("name.png")``. Figure recipes (the paper's figures, the demo's) are in
:mod:`o3dheat.visualization.figures`.

The renderer needs the system packages ``libvulkan1`` and ``mesa-vulkan-drivers`` (Debian names;
``scripts/setup.sh`` installs them). Where it cannot start, the functions warn once
(``RuntimeWarning``) and draw with matplotlib's 3D axes instead, which cannot hide what is behind
the surface. ``renderer="matplotlib"`` (or the environment variable ``O3DHEAT_RENDERER=matplotlib``)
picks that drawing on purpose, without the warning.

One renderer is kept per process (Open3D cannot destroy one safely); call these functions from
one thread at a time.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import threading
import warnings

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError, SolverError
from o3dheat.geometry import as_arrays
from o3dheat.geometry._tables import vertex_normals

__all__ = ["field", "fields", "render", "renderer_available", "scale_space", "study", "drawn_critical_points",
           "persistence_diagram", "tracks", "lifetime_chart", "CRITICAL_COLORS"]

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
RENDER_SIZE = 1200  # pixels of the (square) offscreen render; panels are crops of it
_UP = {"z": [0, 1, 2], "y": [2, 0, 1], "x": [1, 2, 0]}  # cyclic: keeps the orientation
_RENDERERS = ("auto", "open3d", "matplotlib")
_MISSING = ("Open3D's offscreen renderer cannot start here: it needs Vulkan, which a machine without "
            "a GPU gets from Mesa's software driver (lavapipe). Install the system packages libvulkan1 "
            "and mesa-vulkan-drivers (Debian/Ubuntu: sudo apt-get install libvulkan1 mesa-vulkan-drivers; "
            "scripts/setup.sh does it)")


# ------------------------------------------------------------------ the renderer (one per process)
_lock = threading.RLock()
_state = {"probe": None, "renderer": None, "warned": False}

_PROBE = """
import numpy as np, open3d as o3d
R = o3d.visualization.rendering
r = R.OffscreenRenderer(16, 16)
mat = R.MaterialRecord()
mat.shader = "defaultUnlit"
r.scene.add_geometry("s", o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4), mat)
r.setup_camera(60.0, [0, 0, 0], [0, 0, 4], [0, 1, 0])
print("O3DHEAT_RENDER_OK", np.asarray(r.render_to_image()).shape)
"""


def _probe():
    """Can Open3D's offscreen renderer start? Tried once per process in a child process: where
    Vulkan has no driver, Filament aborts the whole process instead of raising."""
    if _state["probe"] is None:
        import subprocess

        try:
            r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=180)
            ok = r.returncode == 0 and "O3DHEAT_RENDER_OK" in r.stdout
            lines = [s for s in (r.stderr + r.stdout).splitlines() if s.strip() and "O3DHEAT" not in s]
            why = "" if ok else (f" (exit status {r.returncode}: {lines[-1].strip()})" if lines
                                 else f" (exit status {r.returncode})")
        except (OSError, subprocess.SubprocessError) as e:
            ok, why = False, f" ({e})"
        _state["probe"] = (ok, "" if ok else _MISSING + why)
    return _state["probe"]


def renderer_available():
    """Whether fields are drawn as real 3D renders here, and if not, why.

    Returns
    -------
    ok : bool
        True when Open3D's offscreen renderer works in this process (checked once, in a child
        process, about a second).
    reason : str
        Empty when ``ok``; else what is missing and how to install it.

    Examples
    --------
    >>> import o3dheat.visualization.plot as plot
    >>> ok, reason = plot.renderer_available()
    >>> ok or "libvulkan1" in reason
    True
    """
    with _lock:
        return _probe()


@contextlib.contextmanager
def _quiet_output():
    """Filament prints its start-up log on the process's stdout: keep it out of ours."""
    for stream in (sys.stdout, sys.stderr):
        if stream is not None:
            stream.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no standard streams to protect
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        try:  # C stdio buffers its lines when stdout is not a terminal: out with them, to /dev/null
            import ctypes

            ctypes.CDLL(None).fflush(None)
        except (OSError, AttributeError):
            pass
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved + [devnull]:
            os.close(fd)


class _Renderer:
    """Open3D's OffscreenRenderer set up for exact colours: unlit materials (the shading is baked
    into the vertex colours), no post-processing (Filament's tone mapping, ambient occlusion and
    anti-aliasing change the colours and cost seconds a frame in software), white background."""

    def __init__(self, size):
        import open3d as o3d

        R = o3d.visualization.rendering
        self.size = size
        with _quiet_output(), o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            self.r = R.OffscreenRenderer(size, size)
            view = self.r.scene.view
            view.set_post_processing(False)
            view.set_antialiasing(False)
            view.set_ambient_occlusion(False)
            view.set_shadowing(False)
            self.r.scene.show_skybox(False)
            self.r.scene.set_background([1.0, 1.0, 1.0, 1.0])
            self.r.render_to_image()  # the first frame logs too
        self.surface = R.MaterialRecord()
        self.surface.shader = "defaultUnlit"
        self.line = R.MaterialRecord()
        self.line.shader = "unlitLine"

    def image(self, meshes, lines, line_width, target, eye, up, half, near, far):
        import open3d as o3d

        R = o3d.visualization.rendering
        with _lock:
            scene = self.r.scene
            scene.clear_geometry()
            for i, m in enumerate(meshes):
                scene.add_geometry(f"mesh{i}", m, self.surface)
            if lines is not None:
                self.line.line_width = float(line_width)
                scene.add_geometry("lines", lines, self.line)
            scene.camera.set_projection(R.Camera.Projection.Ortho, -half, half, -half, half, near, far)
            scene.camera.look_at(target, eye, up)
            img = np.asarray(self.r.render_to_image()).copy()
            scene.clear_geometry()
        return img


def _renderer(choice):
    """The renderer to use: an ``_Renderer``, or None for matplotlib (warning once when "auto"
    had to fall back)."""
    if choice not in _RENDERERS:
        raise MeshError(f"renderer must be one of {', '.join(_RENDERERS)}, got {choice!r}")
    if choice == "auto":
        choice = os.environ.get("O3DHEAT_RENDERER", "auto").strip().lower() or "auto"
        if choice not in _RENDERERS:
            raise MeshError(f"O3DHEAT_RENDERER must be one of {', '.join(_RENDERERS)}, got {choice!r}")
        fallback = choice == "auto"
    else:
        fallback = False
    if choice == "matplotlib":
        return None
    with _lock:
        if _state["renderer"] is None:
            ok, reason = _probe()
            if not ok:
                if not fallback:
                    raise MeshError(reason + "; or pass renderer='matplotlib'")
                if not _state["warned"]:
                    warnings.warn(reason + ". Drawing with matplotlib instead (no hidden-surface removal); "
                                  "set O3DHEAT_RENDERER=matplotlib to choose that without this warning.",
                                  RuntimeWarning, stacklevel=4)
                    _state["warned"] = True
                return None
            _state["renderer"] = _Renderer(RENDER_SIZE)
        return _state["renderer"]


# ------------------------------------------------------------------ geometry of a view
def _upright(V, up):
    if up not in _UP:
        raise MeshError(f"up must be 'x', 'y' or 'z', got {up!r}")
    return V[:, _UP[up]]


def _camera(view):
    """Unit vectors (toward the eye, right, up) for (elevation, azimuth) in degrees, z up."""
    try:
        elev, azim = np.radians(np.asarray(view, dtype=np.float64).reshape(2))
    except (TypeError, ValueError):
        raise MeshError(f"view must be (elevation, azimuth) in degrees, got {view!r}") from None
    d = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.999 else np.array([-np.cos(azim), -np.sin(azim), 0.0])
    right = np.cross(-d, up)
    right /= np.linalg.norm(right)
    return d, right, np.cross(right, -d)


class _View:
    """An orthographic view framing every vertex (all parts of a multi-part mesh), with a margin."""

    def __init__(self, V, view, margin=0.04):
        self.d, self.right, self.up = _camera(view)
        c = (V.min(0) + V.max(0)) / 2
        u, v = (V - c) @ self.right, (V - c) @ self.up
        self.radius = max(float(np.linalg.norm(V - c, axis=1).max()), 1e-12)
        pad = margin * max(np.ptp(u), np.ptp(v), 1e-9 * self.radius)
        self.u = (u.min() - pad, u.max() + pad)
        self.v = (v.min() - pad, v.max() + pad)
        self.target = c + np.mean(self.u) * self.right + np.mean(self.v) * self.up
        self.half = max(np.ptp(self.u), np.ptp(self.v)) / 2
        self.diagonal = float(np.linalg.norm(np.ptp(V, axis=0)))

    def crop(self, size):
        """Pixel rows and columns of the square render that hold the framed geometry."""
        w = int(np.ceil(size * np.ptp(self.u) / (2 * self.half)))
        h = int(np.ceil(size * np.ptp(self.v) / (2 * self.half)))
        c0, r0 = (size - w) // 2, (size - h) // 2
        return slice(r0, r0 + h), slice(c0, c0 + w)


def _shade(normals, view):
    """Lambert shading by a key light above and left of the viewer (normals turned toward the
    viewer, so the orientation of the faces does not matter)."""
    light = view.d + 0.55 * view.up - 0.35 * view.right
    light /= np.linalg.norm(light)
    n = normals * np.where(normals @ view.d < 0, -1.0, 1.0)[:, None]
    return 0.38 + 0.62 * np.clip(n @ light, 0.0, 1.0)


_SPHERE = None


def _sphere():
    global _SPHERE
    if _SPHERE is None:
        import open3d as o3d

        s = o3d.geometry.TriangleMesh.create_sphere(1.0, 8)
        _SPHERE = np.asarray(s.vertices), np.asarray(s.triangles)
    return _SPHERE


def _tmesh(V, F, rgb):
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh()  # tensor meshes: Open3D's legacy path is erratically slow here
    m.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(V, dtype=np.float32))
    m.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(F, dtype=np.int32))
    m.vertex.colors = o3d.core.Tensor(np.ascontiguousarray(np.clip(rgb, 0, 1), dtype=np.float32))
    return m


def _tubes(P, radius, rgb, view, sides=6):
    """One tube mesh for segments ``P`` (m, 2, 3), each of its colour ``rgb`` (m, 3), shaded."""
    d = P[:, 1] - P[:, 0]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    e = np.eye(3)[np.argmin(np.abs(d), axis=1)]  # the axis least along d
    u = np.cross(d, e)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(d, u)
    a = 2 * np.pi * np.arange(sides) / sides
    ring = np.cos(a)[None, :, None] * u[:, None] + np.sin(a)[None, :, None] * w[:, None]  # (m, sides, 3)
    Vt = np.concatenate([P[:, :1] + radius * ring, P[:, 1:] + radius * ring], axis=1)  # (m, 2 sides, 3)
    j = np.arange(sides)
    k = (j + 1) % sides
    quad = np.r_[np.c_[j, k, sides + j], np.c_[k, sides + k, sides + j]]  # (2 sides, 3)
    T = (quad[None] + 2 * sides * np.arange(len(P))[:, None, None]).reshape(-1, 3)
    normals = np.concatenate([ring, ring], axis=1).reshape(-1, 3)
    colors = np.repeat(rgb, 2 * sides, axis=0) * _shade(normals, view)[:, None]
    return _tmesh(Vt.reshape(-1, 3), T, colors)


# ------------------------------------------------------------------ parts, and fields flat on a part
def _parts(n, F):
    """(n,) int64: the connected part of each vertex, numbered from 0 (-1: in no face)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    out = np.full(n, -1, dtype=np.int64)
    if len(F) == 0:
        return out
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    _, label = connected_components(coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)), directed=False)
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    out[used] = np.unique(label[used], return_inverse=True)[1]
    return out


def _flat_parts(f, parts):
    """(p,) bool: the parts on which ``f`` varies by at most ``FLAT_RTOL`` times its variation over
    the whole mesh (an offset such as a georeferenced coordinate flattens nothing; one part is flat
    only when exactly constant)."""
    k = int(parts.max()) + 1 if len(parts) else 0
    used = parts >= 0
    lo, hi = np.full(k, np.inf), np.full(k, -np.inf)
    np.minimum.at(lo, parts[used], f[used])
    np.maximum.at(hi, parts[used], f[used])
    scale = float(np.ptp(f[used])) if used.any() else 0.0
    return hi - lo <= FLAT_RTOL * scale


def _flattened(f, parts, flat):
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


def _without_flat(cp, parts, flat):
    """``(cp, left_out)``: the critical points not on a flat part, and how many were left out."""
    import dataclasses

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


def drawn_critical_points(mesh, f):
    """The critical points the drawings show: those of :func:`o3dheat.critical_points` less the
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
    from o3dheat.topology import Surface, critical_points

    S = Surface.of(mesh)
    f = S.field(f)
    parts = _parts(S.n, S.F)
    flat = _flat_parts(f, parts)
    return _without_flat(critical_points(S, _flattened(f, parts, flat)), parts, flat)[0]


# ------------------------------------------------------------------ one panel
class _Panel:
    """What one panel shows, computed once: colours, level sets, critical points."""

    def __init__(self, V, F, f, lo, hi, cmap, level_sets, critical_points, S, span=None, parts=None):
        from o3dheat.topology import critical_points as find_critical
        from o3dheat.topology import level_sets as find_levels

        self.parts = _parts(len(V), F) if parts is None else parts
        flat = _flat_parts(f, self.parts)
        self.flat_parts = int(flat.sum())
        f = _flattened(f, self.parts, flat)  # errors on a flat part: no level sets, no critical points
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
                cp, self.left_out = _without_flat(find_critical(S if S is not None else (V, F), f), self.parts, flat)
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
        pixel = 2 * view.half / RENDER_SIZE if pixel is None else pixel
        return np.where(r >= 1.2 * pixel, r, 0.0)

    def render(self, renderer, view, normals, line_width=None, point_size=1.0, pixel=None, paths=None):
        """(h, w, 3) uint8 image of the surface, its level sets and critical points;
        ``line_width`` in pixels of the render (default: a third of a percent of its size);
        ``pixel``: the size of a pixel of the final picture in world units (markers smaller than
        about one are not drawn, see :meth:`marker_radii`); ``paths``: more segments to draw
        just off the surface, ``((m, 2, 3) positions, (m, 3) colours)`` (the tracks of
        :func:`tracks`)."""
        import open3d as o3d

        V, F = self.V, self.F
        V = V - view.target  # about the origin: float32 keeps the detail of a scan far from it
        meshes = [_tmesh(V, F, self.rgb(self.f) * _shade(normals, view)[:, None])]
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
                lines = o3d.t.geometry.LineSet()
                lines.point.positions = o3d.core.Tensor(P.astype(np.float32))
                lines.line.indices = o3d.core.Tensor(np.arange(len(P), dtype=np.int32).reshape(-1, 2))
                lines.line.colors = o3d.core.Tensor(np.zeros((len(P) // 2, 3), np.float32))
        if paths is not None and len(paths[0]):  # tubes: Filament draws lines one pixel wide, whatever the width
            from scipy.spatial import cKDTree

            P = np.asarray(paths[0], dtype=np.float64).reshape(-1, 3) - view.target
            _, near = cKDTree(V).query(P)
            P = (P + 2 * eps * toward[near]).reshape(-1, 2, 3)
            radius = 1.5 * (2 * view.half / RENDER_SIZE if pixel is None else pixel)  # about 3 pixels wide
            meshes.append(_tubes(P, radius, np.asarray(paths[1], dtype=np.float64).reshape(-1, 3), view))
        self.too_dense = 0
        if self.draw_critical:
            from matplotlib.colors import to_rgb

            Vs, Fs = _sphere()
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
                shade = _shade(np.tile(Vs, (len(idx), 1)), view)
                meshes.append(_tmesh(P, T, np.asarray(to_rgb(color))[None] * shade[:, None]))
        eye = 4.0 * view.radius * view.d
        size = renderer.size
        width = max(2.5, size / 300 if line_width is None else line_width)  # thinner lines break up
        rows, cols = view.crop(size)
        for _ in range(2):  # the framed surface always shows: a blank frame is drawn again, then refused
            img = renderer.image(meshes, lines, width, np.zeros(3), eye, view.up,
                                 view.half, 2.5 * view.radius, 5.5 * view.radius)[rows, cols]
            if (img < 250).any(axis=2).mean() > 1e-3:
                return img
        raise SolverError(f"Open3D's offscreen renderer drew nothing for a mesh of {len(F)} faces framed in "
                          f"view: a blank picture is not written; try renderer='matplotlib' "
                          f"(O3DHEAT_RENDERER=matplotlib)")

    def draw_matplotlib(self, ax, view_angles, view):
        """The fallback: matplotlib's 3D axes (painter's algorithm; lines and points are drawn
        only where the nearest vertex faces the viewer)."""
        from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

        V, F = self.V, self.F
        n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
        n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
        colors = np.c_[self.rgb(self.f[F].mean(axis=1)) * _shade(n, view)[:, None], np.ones(len(F))]
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


# ------------------------------------------------------------------ composing figures
def _field_values(f, n):
    return checks.field(f, n, "the field")


def _welded(V, F, values):
    """``(V, F, values)`` as every o3dheat function sees the mesh (:func:`o3dheat.geometry.welding.prepare`):
    exactly coincident vertices welded (an STL file's per-triangle copies: otherwise every
    triangle is a part of its own, with its own critical points, and the shading is faceted),
    degenerate faces and unreferenced vertices dropped; a welded vertex's value is the mean of
    its copies'."""
    from o3dheat.geometry import prepare

    used = np.unique(np.asarray(F).reshape(-1))
    if 0 < len(used) < len(V):  # said here: prepare's message (value 0 in every result) is not a picture's
        logging.getLogger("o3dheat").warning("%d vertices are in no face: not drawn", len(V) - len(used))
        index = np.zeros(len(V), dtype=np.int64)
        index[used] = np.arange(len(used))
        V, F, values = V[used], index[F], values[used]
    p = prepare((V, F))
    return p.V, p.F, p.restrict(values)


def _surface(V, F, values, level_sets, critical_points):
    """``(S, V, F, values)``: the checked surface, built once per mesh, when level sets or critical
    points are drawn (else None). A mesh that is not a 2-manifold (a scan with non-manifold edges
    or vertices) is drawn as :func:`o3dheat.repair` makes it, with a warning: the same surface,
    each fan of faces with its own copy of a shared vertex (the copy keeps the vertex's value)."""
    from o3dheat.topology import Surface

    wanted = (level_sets is not None and level_sets is not False) or critical_points is True
    if not wanted:
        return None, V, F, values
    try:
        return Surface.from_faces(len(V), F, V), V, F, values
    except MeshError as e:
        if "manifold" not in str(e):
            raise
        V2, F2, values = _repaired(V, F, values, str(e).split(":")[0], "level sets and critical points are drawn")
        return Surface.from_faces(len(V2), F2, V2), V2, F2, values


def _repaired(V, F, values, why, what):
    """``(V, F, values)`` of a non-manifold mesh as :func:`o3dheat.repair` makes it (split, not
    reoriented), each copy of a vertex with its value, and a warning saying ``why`` and ``what``
    is made on it: the one repair of the drawings and the figure recipes."""
    from o3dheat.geometry import repair

    r = repair((V, F), orient=False)
    V2, F2 = as_arrays(r.mesh)
    logging.getLogger("o3dheat").warning("%s: %s on the mesh as o3dheat.repair makes it (%s)", why, what, r)
    return V2, F2, values[r.source]


def _oriented(V, F):
    """F with every component's faces wound consistently (Open3D's ``orient_triangles``) and each
    closed component's normals outward (positive signed volume): the drawing's shading, level-set
    lifting and the matplotlib fallback's hidden points all read vertex normals, which an
    inward or mixed winding (common in OBJ/STL exports) would turn around or cancel. A mesh with
    non-manifold edges is returned as it is."""
    import open3d as o3d
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    F = np.asarray(F, dtype=np.int64)
    if len(F) == 0:
        return F
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    if not legacy.is_edge_manifold(allow_boundary_edges=True):
        return F
    if legacy.orient_triangles():
        F = np.asarray(legacy.triangles, dtype=np.int64)
    n = len(V)
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, label = connected_components(coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n)), directed=False)
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


def _range(values, flat=None):
    """The colour range: the 2nd–98th percentile of the values; with ``flat`` (a mask of the same
    shape: the vertices of parts where the field is constant) of the others only, widened to the
    flat parts' values (a small part holding all the variation is not clipped away by the
    constant ones)."""
    if flat is not None and flat.any() and not flat.all():
        lo, hi = _range(values[~flat])
        return min(lo, float(values[flat].min())), max(hi, float(values[flat].max()))
    lo, hi = np.percentile(values, [2, 98])
    if not hi > lo:
        lo, hi = float(np.min(values)), float(np.max(values))
    return float(lo), float(hi)


def _colorbar(fig, ax, panel, label, location, values):
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


def _legend(fig, panels, counts):
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


def _check_style(cmap, size=1.0):
    """A matplotlib colormap name and a positive size, or a MeshError naming them."""
    from matplotlib import colormaps

    if not isinstance(cmap, str) or cmap not in colormaps:
        raise MeshError(f"cmap must be the name of a matplotlib colormap (e.g. 'coolwarm', 'viridis'), got {cmap!r}")
    if isinstance(size, bool) or not isinstance(size, (int, float, np.integer, np.floating)) or not 0 < size <= 100:
        raise MeshError(f"size must be a number of inches in (0, 100], got {size!r}")


def _compose(V, F, values, titles, ncols, level_sets, critical_points, view, cmap, shared_range, size,
             suptitle, up, label, renderer, single):
    from matplotlib.figure import Figure  # no pyplot: no GUI backend, no global state

    _check_style(cmap, size)
    V = _upright(V, up)
    T = values.shape[1]
    if titles is not None and len(titles) != T:
        raise MeshError(f"{len(titles)} titles for {T} fields")
    if ncols is not None:
        ncols = checks.count(ncols, "ncols")
    ncols = min(ncols or min(T, 5), T)
    nrows = -(-T // ncols)
    V, F, values = _welded(V, F, values)
    S, V, F, values = _surface(V, F, values, level_sets, critical_points)
    F = _oriented(V, F)
    frame = _View(V, view)
    r = _renderer(renderer)
    parts = _parts(len(V), F)
    flat = np.stack([_flat_parts(values[:, i], parts)[np.maximum(parts, 0)] & (parts >= 0) for i in range(T)], 1)
    ranges = ([_range(values, flat)] * T if shared_range
              else [_range(values[:, i], flat[:, i]) for i in range(T)])
    span = (values.min(), values.max()) if shared_range else None
    panels = [_Panel(V, F, values[:, i], *ranges[i], cmap, level_sets, critical_points, S, span, parts)
              for i in range(T)]
    aspect = float(np.clip(np.ptp(frame.u) / np.ptp(frame.v), 0.25, 4.0))  # width / height of a picture
    w = size * min(1.0, aspect) if aspect < 1 else size
    h = w / aspect
    extra_h = (0.35 if titles is not None else 0.0) + (0.45 if not shared_range else 0.0)
    fig = Figure(figsize=(ncols * w + (1.1 if shared_range else 0.2),
                          nrows * (h + extra_h) + 0.45 + (0.45 if suptitle else 0.0)),
                 dpi=100, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.04, h_pad=0.04, wspace=0.03, hspace=0.05)
    axes = []
    normals = vertex_normals(V, F)
    for i, p in enumerate(panels):
        if r is not None:
            ax = fig.add_subplot(nrows, ncols, i + 1)
            # level sets 1.6 pixels wide in the saved figure (100 dpi), whatever the downsampling
            shrink = r.size * np.ptp(frame.u) / (2 * frame.half) / (w * 100)
            ax.imshow(p.render(r, frame, normals, line_width=1.6 * shrink, pixel=np.ptp(frame.u) / (w * 100)),
                      interpolation="antialiased")
            ax.set_axis_off()
        else:
            ax = fig.add_subplot(nrows, ncols, i + 1, projection="3d")
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
            text = getattr(ax, "text2D", ax.text)  # 3D axes' text takes (x, y, z, s)
            import textwrap

            width = max(20, int(w / 0.055))  # characters of 7 points across the panel
            text(0.5, 0.0, "\n".join(line for n in notes for line in textwrap.wrap(n, width)), transform=ax.transAxes,
                 ha="center", va="top", fontsize=7, color="0.35")
        axes.append(ax)
    if shared_range:
        _colorbar(fig, axes, panels[0], label, "right", values)
    else:
        for ax, p in zip(axes, panels, strict=True):
            _colorbar(fig, ax, p, label, "bottom", p.f)
    _legend(fig, panels, counts=single)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    return fig


def field(mesh, f, level_sets=10, critical_points=True, view=(20.0, -60.0), cmap="coolwarm",
          title=None, size=5.0, up="z", label="f", renderer="auto"):
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
    renderer : {"auto", "open3d", "matplotlib"}
        "auto": Open3D's offscreen renderer, or matplotlib with a warning where it cannot start;
        "open3d" raises :class:`o3dheat.MeshError` there instead; "matplotlib": 3D axes without
        hidden-surface removal. "auto" follows the environment variable ``O3DHEAT_RENDERER``.

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
    f = _field_values(f, len(V))
    return _compose(V, F, f[:, None], [title] if title else None, 1, level_sets, critical_points, view, cmap,
                    True, size, None, up, label, renderer, single=True)


def fields(mesh, F_values, titles=None, ncols=None, level_sets=10, critical_points=True,
           view=(20.0, -60.0), cmap="coolwarm", shared_range=True, size=3.5, suptitle=None, up="z",
           label="f", renderer="auto"):
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
    G = _field_values(G, len(V))
    if G.shape[1] == 0:
        raise MeshError("no field to draw: F_values has 0 columns")
    return _compose(V, Fc, G, titles, ncols, level_sets, critical_points, view, cmap, shared_range, size,
                    suptitle, up, label, renderer, single=False)


def render(mesh, f, level_sets=10, critical_points=True, view=(20.0, -60.0), cmap="coolwarm", up="z",
           vrange=None):
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
    f = _field_values(f, len(V))
    V = _upright(V, up)
    if vrange is not None:
        try:
            vr = np.asarray(checks.values(vrange), dtype=np.float64).ravel()
        except (TypeError, ValueError):
            vr = np.zeros(0)
        if len(vr) != 2 or not np.all(np.isfinite(vr)) or not vr[0] < vr[1]:
            raise MeshError(f"vrange must be two finite numbers (low, high), low < high, got {vrange!r}")
    _check_style(cmap)
    V, F, f = _welded(V, F, f)
    S, V, F, f = _surface(V, F, f, level_sets, critical_points)
    parts = _parts(len(V), F)
    flat = _flat_parts(f, parts)[np.maximum(parts, 0)] & (parts >= 0)
    lo, hi = _range(f, flat) if vrange is None else (float(vr[0]), float(vr[1]))  # of what is drawn, as field's
    F = _oriented(V, F)
    frame = _View(V, view)
    r = _renderer("open3d")
    panel = _Panel(V, F, f, lo, hi, cmap, level_sets, critical_points, S, None, parts)
    return panel.render(r, frame, vertex_normals(V, F))


# ------------------------------------------------------------------ charts
def _scale_ticks(ax, t):
    """Ticks at the scales themselves (at most ~6 labelled), no minor labels: a log axis over
    less than a decade otherwise writes overlapping minor labels ('0.00010.0002')."""
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    step = max(1, -(-len(t) // 6))
    ticks = t[::step]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xticks(ticks, [f"{x:.2g}" for x in ticks], rotation=30, ha="right", fontsize=8)


def scale_space(ss, title=None):
    """The variation of ``Φ_t f`` and the number of critical points across scales (Fig. 1c,d).

    Parameters
    ----------
    ss : ScaleSpace
        From :func:`o3dheat.scale_space`.
    title : str, optional
        Written above the chart.

    Returns
    -------
    matplotlib.figure.Figure
        Left: ``‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞`` and ε∞ against t; right: minima, saddles,
        maxima and their total against t. The stop scale is marked when a criterion held.
        The t axis is logarithmic on a log grid of times; ticks sit at the scales.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(m, k=20))
    >>> fig = plot.scale_space(o3dheat.scale_space(K, m.vertex.positions.numpy()[:, 0]))
    >>> len(fig.axes)
    2
    """
    from matplotlib.figure import Figure

    from o3dheat.topology import ScaleSpace

    if not isinstance(ss, ScaleSpace):
        raise MeshError(f"expected a ScaleSpace (from o3dheat.scale_space), got {type(ss).__name__}")
    fig = Figure(figsize=(9.0, 3.9), dpi=100, layout="constrained")
    a1, a2 = fig.subplots(1, 2)
    t = ss.scales
    if len(t) > 1:
        a1.plot(t[1:], ss.variation, "o-", color="black",
                label=r"$\|\Phi_{t_{i+1}} f - \Phi_{t_i} f\|_\infty$ (at $t_{i+1}$)")
    a1.plot(t, ss.errors, "s--", color="gray", label=r"$\epsilon_\infty$ (relative)")
    a1.set_title(r"variation of $\Phi_t f$", fontsize=10)
    a1.legend(fontsize=8)
    c = ss.critical_counts
    if np.all(c >= 0):
        for j, (name, color) in enumerate([("minima", "blue"), ("saddles", "green"), ("maxima", "red")]):
            a2.plot(t, c[:, j], "o-", color=color, label=name)
        a2.plot(t, c.sum(axis=1), "k:", label="total")
        a2.legend(fontsize=8)
        from matplotlib.ticker import MaxNLocator

        a2.yaxis.set_major_locator(MaxNLocator(integer=True))
    a2.set_title(r"critical points of $\Phi_t f$", fontsize=10)
    if ss.stopped:
        for a in (a1, a2):
            a.axvline(t[ss.stop_index], color="orange", lw=1, label="stop")
    for a in (a1, a2):
        if t[0] > 0 and t[-1] > 20 * t[0]:  # a log grid of times
            a.set_xscale("log")
        _scale_ticks(a, t)
        a.set_xlabel("t")
        a.tick_params(axis="y", labelsize=8)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def persistence_diagram(diagram, f=None, title=None):
    """The persistence diagram of a field's sublevel sets, every point on or above the diagonal.

    One filtration throughout, the sublevel sets ``{f <= c}`` as ``c`` grows, and each point is
    ``(birth, death)`` of one homology class in it:

    - dimension 0 (blue): a component born at a minimum, dying at the saddle where it merges
      with an older one;
    - dimension 1 (red): a loop born at a saddle, dying at the maximum that fills it in. The
      diagram stores these pairs as ``(maximum, saddle)`` (:class:`o3dheat.topology.PersistenceDiagram`:
      read on superlevel sets, a maximum's cap born at its value and merged at the saddle's,
      birth above death); by the duality of a surface that is the same pair, and drawn here as
      ``(saddle, maximum)``, birth and death exchanged back, it is the 1-dimensional sublevel
      persistence (as gudhi gives it): above the diagonal, at the same distance from it.

    Points near the diagonal are short-lived (noise); the features lie far from it. With ``f``
    the classes that never die (the global minimum of each component, the saddles of its genus
    and boundary, the maximum of a closed component: dimension 2, black) are drawn on a row "∞"
    above the others.

    Parameters
    ----------
    diagram : PersistenceDiagram
        From :func:`o3dheat.persistence`.
    f : (n,) array_like, optional
        The field, to place the essential classes (their values are not in the diagram).
    title : str, optional
        Written above the diagram.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: birth horizontally, death vertically, the diagonal, a legend saying how each
        dimension reads.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> f = V[:, 0] + 0.05 * np.random.default_rng(0).standard_normal(len(V))
    >>> d = o3dheat.persistence(m, f)
    >>> fig = plot.persistence_diagram(d, f)
    >>> pts = fig.axes[0].collections[1].get_offsets()      # dimension 1, as drawn
    >>> bool(np.all(pts[:, 1] >= pts[:, 0])), bool(np.all(d.intervals(1)[:, 1] <= d.intervals(1)[:, 0]))
    (True, True)
    """
    from matplotlib.figure import Figure

    from o3dheat.topology import PersistenceDiagram

    if not isinstance(diagram, PersistenceDiagram):
        raise MeshError(f"expected a PersistenceDiagram (from o3dheat.persistence), got {type(diagram).__name__}")
    d0 = diagram.intervals(0)
    d1 = diagram.intervals(1)[:, ::-1]  # (maximum, saddle) -> (saddle, maximum): sublevel persistence
    values = np.concatenate([d0.ravel(), d1.ravel()])
    essential = np.zeros((0, 2))
    if f is not None:
        f = np.asarray(checks.values(f), dtype=np.float64).ravel()
        idx = np.asarray(diagram.essential, dtype=np.int64)
        if len(idx) and (idx.max() >= len(f) or not np.all(np.isfinite(f[idx]))):
            raise MeshError("f must be the field of the diagram: one finite value per vertex")
        essential = np.c_[f[idx], np.asarray(diagram.essential_dimension)] if len(idx) else essential
        values = np.concatenate([values, essential[:, 0]])
    lo, hi = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
    pad = 0.04 * (hi - lo or 1.0)
    top = hi + 3 * pad  # the row of the classes that never die
    fig = Figure(figsize=(4.6, 4.6), dpi=100, layout="constrained")
    ax = fig.subplots()
    ax.scatter(d0[:, 0], d0[:, 1], s=10, c="tab:blue", label="dim 0: born at a minimum, dies at a saddle")
    ax.scatter(d1[:, 0], d1[:, 1], s=10, c="tab:red",
               label="dim 1: born at a saddle, dies at a maximum\n(stored as (maximum, saddle): exchanged)")
    ax.plot([lo - pad, top], [lo - pad, top], "k-", lw=0.8)
    ax.set_xlim(lo - pad, top + pad)
    ax.set_ylim(lo - pad, top + pad)
    if len(essential):
        label = "never dies (row ∞; dim 2 black)"
        for dim, color in ((0, "tab:blue"), (1, "tab:red"), (2, "black")):
            e = essential[essential[:, 1] == dim]
            if len(e):
                ax.scatter(e[:, 0], np.full(len(e), top), s=24, c=color, marker="v", label=label)
                label = None
        ax.axhline(top, color="0.6", lw=0.6, ls="--")
        ticks = [t for t in ax.get_yticks() if lo - pad <= t <= hi + pad]
        ax.set_yticks(ticks + [top], [f"{t:.3g}" for t in ticks] + ["∞"])
    ax.set_aspect("equal")
    ax.set(xlabel="birth (f)", ylabel="death (f)")
    ax.set_title(title or "persistence of the sublevel sets of f", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    return fig


def study(table, descriptor="hks_density", metric="rel_l2", title=None):
    """Discrepancy against the reference sampling vs scale, one line per kernel and one panel per
    resampling kind (averaged over meshes and resamplings of that kind), from
    :func:`o3dheat.robustness_study`.

    Line panels share one logarithmic y range (the kinds compare at a glance) and put their
    ticks on the integer scale indices; when some discrepancies are exactly 0 the axis is
    "symlog" (0 at the bottom, linear up to the decade of the smallest non-zero value) so that
    they stay on the chart. "eigenvalues" (scale 0 only) are bars on a linear axis shared by all
    panels. Kernels are coloured in the order of :data:`o3dheat.spectral.kernel.VARIANTS` (the paper's
    weighted kernel black).

    Parameters
    ----------
    table : pandas.DataFrame
        The study's table.
    descriptor : str
        Which descriptor to draw ("eigenvalues": one bar per kernel).
    metric : {"rel_l2", "rel_linf"}
        The column drawn: the relative L2 or L∞ discrepancy.
    title : str, optional
        Written above the panels.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import pandas as pd, o3dheat.visualization.plot as plot
    >>> rows = [dict(descriptor="hks_density", error="", kind=k, kernel=kern, scale=s, rel_l2=0.01 * s + e)
    ...         for k in ("decimate", "jitter") for kern, e in (("weighted", 0.0), ("linear", 0.02))
    ...         for s in range(1, 11)]
    >>> fig = plot.study(pd.DataFrame(rows))
    >>> [a.get_yscale() for a in fig.axes], fig.axes[0].get_ylim() == fig.axes[1].get_ylim()
    (['log', 'log'], True)
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    if metric not in ("rel_l2", "rel_linf"):
        raise MeshError(f"metric must be 'rel_l2' or 'rel_linf', got {metric!r}")
    t = table[(table["descriptor"] == descriptor) & (table["error"].fillna("") == "")]
    if t.empty:
        raise MeshError(f"the table has no successful rows for descriptor {descriptor!r}")
    kinds = sorted(t["kind"].unique())
    fig = Figure(figsize=(3.6 * len(kinds) + 0.4, 3.8), dpi=100, layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(kinds), sharey=True))
    from o3dheat.spectral import VARIANTS

    # the paper's kernel black, the others in matplotlib's cycle, in the order of kernel.VARIANTS
    colors = {v: "black" if i == 0 else f"C{i - 1}" for i, v in enumerate(VARIANTS)}
    means = t.groupby(["kind", "kernel", "scale"])[metric].mean()
    bars = bool((t["scale"] == 0).all())
    positive = means[means > 0]
    for ax, kind in zip(axes, kinds, strict=True):
        mean = means.loc[kind].reset_index()
        if bars:
            kernels = list(mean["kernel"])
            ax.bar(kernels, mean[metric], color=[colors.get(k, "gray") for k in kernels])
            ax.tick_params(axis="x", labelrotation=30, labelsize=8)
        else:
            for kern, g in mean.groupby("kernel"):
                ax.plot(g["scale"], g[metric], "o-", color=colors.get(kern, "gray"), label=kern, ms=3)
            ax.set_xlabel("scale i (each kernel's own t_i)")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True, nbins=10))
        ax.set_title(f"{kind}", fontsize=10)
    if bars:
        axes[0].set_ylim(0, float(means.max()) * 1.1 if len(means) else 1.0)  # linear: bars start at 0
    elif not len(positive):  # every discrepancy is 0 (or none is finite): a linear axis from 0
        axes[0].set_ylim(0, 1)
    elif len(positive) < len(means.dropna()):
        # some discrepancies are exactly 0 (e.g. the same number of critical points): a log axis
        # would drop them off the chart; symlog shows them at 0, linear up to the smallest non-zero
        # value's decade, logarithmic above
        lt = 10.0 ** np.floor(np.log10(positive.min()))
        axes[0].set_yscale("symlog", linthresh=lt, linscale=0.4)
        axes[0].set_ylim(0, positive.max() * 1.5)
    else:
        axes[0].set_yscale("log")
        if len(positive):
            axes[0].set_ylim(positive.min() / 1.5, positive.max() * 1.5)  # one range for all panels
    if not bars:  # one legend for every panel, below them: a legend inside would hide points
        handles = {h.get_label(): h for ax in axes for h in ax.get_lines()}
        fig.legend(handles=list(handles.values()), loc="outside lower center", ncols=len(handles), fontsize=8,
                   frameon=False)
    axes[0].set_ylabel(f"{metric} of {descriptor}")
    fig.suptitle(title or f"{descriptor}: discrepancy to the reference sampling", fontsize=11)
    return fig


# ------------------------------------------------------------------ critical points across scales
#: A track's move between two scales longer than this fraction of the mesh's diagonal is not drawn
#: (an extremum that flows far, a saddle matched far away): a straight line would cut across the surface.
JUMP = 0.05
#: The colour of a track of each kind (:data:`o3dheat.topology.tracking.KINDS`): the critical points' colours.
_KIND_COLORS = {"minimum": CRITICAL_COLORS["minima"], "saddle": CRITICAL_COLORS["saddles"],
                "maximum": CRITICAL_COLORS["maxima"]}
_PLURAL = {"minimum": "minima", "saddle": "saddles", "maximum": "maxima"}


def _check_tracks(tr):
    from o3dheat.topology import Tracks

    if not isinstance(tr, Tracks):
        raise MeshError(f"expected Tracks (from o3dheat.track_critical_points), got {type(tr).__name__}")
    return tr


def _by_lifetime(tr):
    """Track indices, the longest-lived first: lifetime (living at the last scale: longest), then
    the number of scales lived at, then the earlier start, then the index."""
    first, last = tr.first, tr.last
    return np.lexsort((np.arange(len(tr)), first, -(last - first), -tr.lifetime))


def _washed(cmap):
    """The colormap mixed halfway with white: the surface under the tracks, which keep the pure
    critical-point colours (a saturated colormap's red and blue ends would hide them)."""
    from matplotlib import colormaps
    from matplotlib.colors import ListedColormap

    base = colormaps[cmap](np.linspace(0.0, 1.0, 256))[:, :3]
    return ListedColormap(0.45 + 0.55 * base, name=f"{cmap}_washed")


def tracks(mesh, tracks, f=None, longest=None, view=(20.0, -60.0), cmap="Greys", title=None, size=6.0,
           up="z", label="f", renderer="auto"):
    """The critical points' tracks across scales on the surface (:func:`o3dheat.track_critical_points`).

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
        With vertex positions (as :func:`o3dheat.track_critical_points` makes them).
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
    import textwrap
    from types import SimpleNamespace

    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from scipy.spatial import cKDTree

    tr = _check_tracks(tracks)
    V, F = as_arrays(mesh)
    if tr.positions_of is None or len(tr.positions_of) != len(V):
        raise MeshError(f"the tracks are not of this mesh ({len(V)} vertices): pass the mesh given to "
                        "o3dheat.track_critical_points")
    _check_style(cmap, size)
    if longest is not None:
        longest = checks.count(longest, "longest")
    if f is None:
        g = np.zeros(len(V))
    else:
        G = np.asarray(checks.values(f), dtype=np.float64)
        g = _field_values(G[:, 0] if G.ndim == 2 else G, len(V))
    V = _upright(V, up)
    P = tr.positions[..., _UP[up]] if len(tr) else np.zeros((0, len(tr.times), 3))
    order = _by_lifetime(tr)
    chosen = order if longest is None else order[:longest]
    V, F, g = _welded(V, F, g)
    F = _oriented(V, F)
    frame = _View(V, view)
    r = _renderer(renderer)
    parts = _parts(len(V), F)
    if f is None:
        lo, hi, colormap = -0.6, 1.4, "Greys"  # g = 0: a light grey
    else:
        flat = _flat_parts(g, parts)[np.maximum(parts, 0)] & (parts >= 0)
        lo, hi = _range(g, flat)
        colormap = _washed(cmap)
    # the paths: consecutive living positions that differ; the ends: a vertex each (exact positions)
    kinds = np.asarray(tr.kind)[chosen]
    segs, cols = [], []
    from matplotlib.colors import to_rgb

    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]]])
    edge = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean()) if len(E) else 0.0
    jump = max(JUMP * frame.diagonal, 2.5 * edge)  # a move along an edge or two lies on the surface
    jumps = 0
    for i, kind in zip(chosen, kinds, strict=True):
        Q = P[i, tr.first[i]:tr.last[i] + 1]
        length = np.linalg.norm(Q[1:] - Q[:-1], axis=1)
        jumps += int((length > jump).sum())
        step = (length > 0) & (length <= jump)
        if step.any():
            segs.append(np.stack([Q[:-1][step], Q[1:][step]], 1))
            cols.append(np.tile(to_rgb(_KIND_COLORS[kind]), (int(step.sum()), 1)))
    segments = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
    colors = np.concatenate(cols) if cols else np.zeros((0, 3))
    ends = P[chosen, tr.last[chosen]] if len(chosen) else np.zeros((0, 3))
    end_vertex = cKDTree(V).query(ends)[1] if len(ends) else np.zeros(0, np.int64)
    counts = {k: int((kinds == k).sum()) for k in _KIND_COLORS}
    cp = SimpleNamespace(**{_PLURAL[k]: end_vertex[kinds == k] for k in _KIND_COLORS},
                         counts=(counts["minimum"], counts["saddle"], counts["maximum"]))
    panel = _Panel(V, F, g, lo, hi, colormap, None, cp, None, None, parts)
    aspect = float(np.clip(np.ptp(frame.u) / np.ptp(frame.v), 0.25, 4.0))
    w = size * min(1.0, aspect) if aspect < 1 else size
    h = w / aspect
    fig = Figure(figsize=(w + (1.1 if f is not None else 0.2), h + 0.9 + (0.35 if title else 0.0)), dpi=100,
                 layout="constrained")
    fig.get_layout_engine().set(w_pad=0.04, h_pad=0.04)
    normals = vertex_normals(V, F)
    if r is not None:
        ax = fig.add_subplot(1, 1, 1)
        shrink = r.size * np.ptp(frame.u) / (2 * frame.half) / (w * 100)
        ax.imshow(panel.render(r, frame, normals, line_width=1.6 * shrink, pixel=np.ptp(frame.u) / (w * 100),
                               paths=(segments, colors)), interpolation="antialiased")
        ax.set_axis_off()
    else:
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        ax = fig.add_subplot(1, 1, 1, projection="3d")
        panel.draw_matplotlib(ax, view, frame)
        if len(segments):
            _, near = cKDTree(V).query(segments.mean(axis=1))
            facing = normals[near] @ frame.d >= 0
            ax.add_collection3d(Line3DCollection(segments[facing], colors=colors[facing], linewidths=1.6,
                                                 zorder=2))
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
        text = getattr(ax, "text2D", ax.text)
        text(0.5, 0.0, "\n".join(textwrap.wrap("; ".join(notes), max(20, int(w / 0.055)))), transform=ax.transAxes,
             ha="center", va="top", fontsize=7, color="0.35")
    if f is not None:
        _colorbar(fig, ax, panel, label + " (first scale)", "right", panel.f)
    handles = [Line2D([], [], color=_KIND_COLORS[k], lw=2.0, marker="o", ms=5, markeredgecolor="white",
                      label=f"{_PLURAL[k]} ({counts[k]:,} track{'s' if counts[k] != 1 else ''})")
               for k in _KIND_COLORS]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False,
               title=f"tracks over {len(tr.times)} scales, ● where each ends (or at the last scale)",
               title_fontsize=8)
    return fig


def _time_positions(times):
    """``(x, zero)``: where each time is drawn on a log axis; ``t = 0`` (only the first can be)
    one grid step (the ratio of the first two positive times) left of the smallest positive
    time, or a decade without a second positive time; ``zero``: whether there is one."""
    x = np.asarray(times, dtype=np.float64).copy()
    zero = bool(len(x) and x[0] <= 0)
    if zero:
        pos = x[x > 0]
        x[0] = pos[0] ** 2 / pos[1] if len(pos) > 1 else (pos[0] / 10 if len(pos) else 1.0)
    return x, zero


def lifetime_chart(tracks, ax=None, title=None):
    """How long each track lives: one horizontal bar per track from the scale it starts at to the
    scale it ends at, on a logarithmic time axis, the longest-lived at the top.

    Bars are coloured by kind (minima blue, saddles green, maxima red); a track alive at the last
    scale runs to the right edge, past the last scale (dotted line), and ends in a black "▶" that
    says it lives on. A track seen at one scale only (a zero-length bar) is marked by a short
    vertical tick. With many tracks (more than 80) the rows are on a log scale of their rank
    (1 at the top): the longest-lived stay readable one by one while the thousands of short
    ones (a noisy field's) show as a block at the bottom.

    **t = 0** (the field itself, as a grid starting at 0 has it) cannot sit on a log axis: it is
    drawn one grid step left of the smallest positive time (the ratio of the first two positive
    times), labelled "0", behind a dashed break line. Bars that start there start at "0".

    Parameters
    ----------
    tracks : Tracks
        From :func:`o3dheat.track_critical_points`.
    ax : matplotlib.axes.Axes, optional
        Draw into this axes (default: a new figure).
    title : str, optional
        Default: how many tracks over how many scales.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of the axes (its first axes is the chart).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
    >>> t = np.r_[0.0, np.geomspace(1e-3, 1.0, 11)]
    >>> tr = o3dheat.track_critical_points(m, o3dheat.heat_flow(m, f, t), t)
    >>> fig = plot.lifetime_chart(tr)
    >>> ax = fig.axes[0]
    >>> len(ax.patches) == len(tr), ax.get_xscale()
    (True, 'log')
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    tr = _check_tracks(tracks)
    p, T = len(tr), len(tr.times)
    x, zero = _time_positions(tr.times)
    step = x[-1] / x[-2] if T > 1 else 10.0
    right = x[-1] * step ** 1.5  # the right edge: past the last scale
    order = _by_lifetime(tr)
    first, last = tr.first[order], tr.last[order]
    kinds = np.asarray(tr.kind)[order]
    alive = last == T - 1
    start, end = x[first], np.where(alive, right, x[last])
    many = p > 80
    if ax is None:
        fig = Figure(figsize=(7.0, 5.2 if many else min(1.6 + 0.2 * max(p, 1), 7.0)), dpi=100, layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    rank = np.arange(1, p + 1)
    color = [_KIND_COLORS[k] for k in kinds]
    # rows at least 4 pixels high get a white edge: neighbours of one kind stay apart
    height_px = 72.0 * fig.get_figheight() * 0.8 * (np.log((rank + 0.5) / (rank - 0.5)) / np.log(2 * p + 1) if many
                                                     else np.full(p, 1.0 / max(p, 1)))
    apart = height_px >= 4
    for sel, lw in ((~apart, 0.0), (apart, 0.6)):
        if sel.any():
            ax.barh(rank[sel], (end - start)[sel], left=start[sel], height=1.0 if many else 0.7,
                    color=np.asarray(color, object)[sel].tolist(), edgecolor="white", linewidth=lw)
    point = first == last
    if point.any():  # zero-length bars: a tick at their one scale
        ax.scatter(start[point], rank[point], marker="|", s=30 if not many else 12, c=np.asarray(color, object)[point],
                   linewidths=1.0)
    if alive.any():
        ax.scatter(np.full(int(alive.sum()), right), rank[alive], marker=">", s=28 if not many else 14, c="black",
                   zorder=3, clip_on=False)
    ax.axvline(x[-1], color="0.5", lw=0.8, ls=":")
    ax.set_xscale("log")
    lo = x[0] / step ** 0.5
    ax.set_xlim(lo, right * step ** 0.4)
    if many:
        ax.set_yscale("log")
        ax.set_ylim(p + 0.5, 0.5)
        ax.set_ylabel("tracks by lifetime (rank, log scale)")
    else:
        ax.set_ylim(p + 0.5, 0.5)
        if p <= 30:
            ax.set_yticks(rank, [str(i) for i in order], fontsize=7)
            ax.set_ylabel("track (its index), longest-lived first")
        else:
            from matplotlib.ticker import MaxNLocator

            ax.yaxis.set_major_locator(MaxNLocator(integer=True))
            ax.set_ylabel("tracks by lifetime (rank)")
    pos = x[1:] if zero and T > 1 else x  # the positive times
    ticks, labels = ([x[0]], ["0"]) if zero else ([], [])
    decades = range(int(np.ceil(np.log10(pos[0]) - 1e-9)), int(np.floor(np.log10(pos[-1]) + 1e-9)) + 1)
    if len(decades) >= 2:
        ticks += [10.0 ** d for d in decades]
        labels += [f"$10^{{{d}}}$" for d in decades]
    else:  # less than a decade: the ends of the grid
        ticks += [pos[0], pos[-1]] if len(pos) > 1 else [pos[0]]
        labels += [f"{v:.2g}" for v in ticks[len(labels):]]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.set_xticklabels(labels, fontsize=8)
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())
    if zero and T > 1:
        ax.axvline(np.sqrt(x[0] * x[1]), color="0.4", lw=0.8, ls="--")
    ax.set_xlabel("t (log scale" + ("; t = 0 drawn one grid step left of the smallest positive time)" if zero else ")"),
                  fontsize=9)
    counts = {k: int((kinds == k).sum()) for k in _KIND_COLORS}
    handles = [Line2D([], [], color=_KIND_COLORS[k], lw=6, label=f"{_PLURAL[k]} ({counts[k]:,})") for k in _KIND_COLORS]
    handles.append(Line2D([], [], ls="", marker=">", color="black", label=f"lives on ({int(alive.sum()):,})"))
    ax.legend(handles=handles, fontsize=8, loc="lower right", framealpha=0.9)
    ax.set_title(title or f"lifetimes of {p:,} tracks of critical points over {T} scales", fontsize=10)
    ax.tick_params(axis="y", labelsize=8)
    return fig
