"""The static figures' renderer (one per process) and a view's geometry: :func:`renderer`, :class:`View`.

:func:`renderer` gives the renderer to draw with (or None for matplotlib), :func:`renderer_available`
says whether it works here (it always does: it needs nothing of the machine); :class:`View` frames a
mesh in an orthographic view.

Notes
-----
Surfaces are drawn by o3dheat's own z-buffer rasterizer (:mod:`o3dheat.visualization._raster`):
the figures bake their shading into vertex colours (:func:`shade`) and look through an orthographic
camera, so hidden-surface removal and colour interpolation are all there is to do, in one
deterministic pass on the CPU. It replaced Open3D's offscreen renderer (Filament over software
Vulkan): three times faster figures, level sets as wide as asked (Filament drew them one pixel
wide: faint dotted lines once scaled down), no Vulkan packages. The figures that came out blank
were not the renderer's doing but :meth:`View.crop`'s (see there). ``renderer="open3d"`` is an old spelling of ``"raster"`` (deprecated).
The meshes handed to it are ``(V, F, rgb)`` triples (:func:`tmesh`, :func:`tubes`), in the view's
coordinates.
"""

from __future__ import annotations

import os
import warnings

import numpy as np

from o3dheat.errors import MeshError

from . import _raster

RENDER_SIZE = 1200  # pixels of the (square) render; panels are crops of it
UP = {"z": [0, 1, 2], "y": [2, 0, 1], "x": [1, 2, 0]}  # cyclic: keeps the orientation
RENDERERS = ("auto", "raster", "matplotlib", "open3d")


# ------------------------------------------------------------------ the renderer
def renderer_available() -> tuple[bool, str]:
    """Whether fields are drawn as real 3D renders here (hidden surfaces removed), and if not, why.

    Returns
    -------
    ok : bool
        Always True: the renderer is o3dheat's own rasterizer, which needs no display, GPU or
        driver (the function stays for scripts that asked when Open3D's renderer drew the figures).
    reason : str
        Empty.

    Examples
    --------
    >>> import o3dheat.visualization.plot as plot
    >>> plot.renderer_available()
    (True, '')
    """
    return True, ""


class Raster:
    """Draws ``(V, F, rgb)`` meshes and line segments seen along ``-d`` in an orthographic view
    into a square image ``size`` pixels wide (white background): see :mod:`._raster`."""

    def __init__(self, size):
        self.size = size

    def image(self, meshes, lines, line_width, frame):
        """(size, size, 3) uint8: ``meshes`` (``(V, F, rgb)``, V relative to ``frame.target``) and
        ``lines`` (``(segments (m, 2, 3), rgb (m, 3))`` or None), ``line_width`` pixels wide."""
        n = self.size
        img = np.ones((n, n, 3), np.float32)
        depth = np.full((n, n), -np.inf)
        scale = n / (2 * frame.half)

        def pixels(V):
            V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
            return np.c_[(V @ frame.right + frame.half) * scale, (frame.half - V @ frame.up) * scale, V @ frame.d]

        for V, F, rgb in meshes:
            if len(F):
                _raster.draw(pixels(V), F, rgb, img, depth)
        if lines is not None and len(lines[0]):
            S = pixels(lines[0]).reshape(-1, 2, 3)
            P, F = _raster.segment_quads(S[:, 0], S[:, 1], float(line_width))
            _raster.draw(P, F, np.repeat(np.asarray(lines[1], dtype=np.float64).reshape(-1, 3), 4, axis=0), img, depth)
        return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def renderer(choice: str) -> Raster | None:
    """The renderer to use: a :class:`Raster`, or None for matplotlib's 3D axes. "auto" follows
    the environment variable ``O3DHEAT_RENDERER`` (default: the rasterizer)."""
    if choice not in RENDERERS:
        raise MeshError(f"renderer must be one of {', '.join(RENDERERS[:3])}, got {choice!r}")
    if choice == "auto":
        choice = os.environ.get("O3DHEAT_RENDERER", "auto").strip().lower() or "auto"
        if choice not in RENDERERS:
            raise MeshError(f"O3DHEAT_RENDERER must be one of {', '.join(RENDERERS[:3])}, got {choice!r}")
    if choice == "open3d":
        warnings.warn("renderer='open3d' is deprecated: the figures are drawn by o3dheat's own rasterizer "
                      "(renderer='raster'), which replaced Open3D's offscreen renderer", DeprecationWarning,
                      stacklevel=4)
    return None if choice == "matplotlib" else Raster(RENDER_SIZE)


# ------------------------------------------------------------------ geometry of a view
def upright(V, up):
    if up not in UP:
        raise MeshError(f"up must be 'x', 'y' or 'z', got {up!r}")
    return V[:, UP[up]]


def camera(view):
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


class View:
    """An orthographic view framing every vertex (all parts of a multi-part mesh), with a margin."""

    def __init__(self, V, view, margin=0.04):
        self.d, self.right, self.up = camera(view)
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
        """Pixel rows and columns of the square render that hold the framed geometry.

        The longer side is the whole render: ``size * ptp / (2 half)`` is ``size`` up to rounding,
        which can make it ``size + 2e-13``; its ceiling, ``size + 1``, once gave the slice
        ``(-1, size)``, one column of white margin, and a picture refused as blank (the
        "intermittently blank" figures: always the same meshes, whatever the load). Hence the
        tolerance and the clamp.

        Examples
        --------
        >>> import numpy as np
        >>> from o3dheat.visualization._render import View
        >>> frame = View(np.eye(3), (20, -60))
        >>> frame.u = (-3.640200020722534, 3.5601544210293667)  # the frame of a figure once blank
        >>> frame.half = np.ptp(frame.u) / 2
        >>> float(1200 * np.ptp(frame.u) / (2 * frame.half)), frame.crop(1200)[1]
        (1200.0000000000002, slice(0, 1200, None))
        """
        def pixels(extent):
            return min(size, max(1, int(np.ceil(size * extent / (2 * self.half) - 1e-6))))

        w, h = pixels(np.ptp(self.u)), pixels(np.ptp(self.v))
        c0, r0 = (size - w) // 2, (size - h) // 2
        return slice(r0, r0 + h), slice(c0, c0 + w)


def shade(normals, view):
    """Lambert shading by a key light above and left of the viewer (normals turned toward the
    viewer, so the orientation of the faces does not matter)."""
    light = view.d + 0.55 * view.up - 0.35 * view.right
    light /= np.linalg.norm(light)
    n = normals * np.where(normals @ view.d < 0, -1.0, 1.0)[:, None]
    return 0.38 + 0.62 * np.clip(n @ light, 0.0, 1.0)


_SPHERE = None


def sphere():
    """``(V, F)`` of a unit sphere (an icosahedron subdivided once, 42 vertices): a marker."""
    global _SPHERE
    if _SPHERE is None:
        t = (1 + 5 ** 0.5) / 2
        V = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                      [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
        F = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                      [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                      [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
        mid = {}
        points = list(V)

        def middle(i, j):
            key = (min(i, j), max(i, j))
            if key not in mid:
                mid[key] = len(points)
                points.append((V[i] + V[j]) / 2)
            return mid[key]

        faces = []
        for a, b, c in F:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            faces += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        P = np.array(points)
        _SPHERE = P / np.linalg.norm(P, axis=1, keepdims=True), np.array(faces, dtype=np.int64)
    return _SPHERE


def tmesh(V, F, rgb):
    """A mesh for :meth:`Raster.image`: ``(V, F, rgb)`` with colours clipped to [0, 1]."""
    return (np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), np.clip(rgb, 0, 1))


def tubes(P, radius, rgb, view, sides=6):
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
    colors = np.repeat(rgb, 2 * sides, axis=0) * shade(normals, view)[:, None]
    return tmesh(Vt.reshape(-1, 3), T, colors)
