"""Open3D's offscreen renderer (one per process) and a view's geometry: :func:`renderer`, :class:`View`.

:func:`renderer` gives the renderer to draw with (or None for matplotlib), :func:`renderer_available`
says whether it starts here; :class:`View` frames a mesh in an orthographic view.

Notes
-----
Surfaces are rendered by Filament through software Vulkan (Mesa's lavapipe: no display and no GPU
needed), which needs the system packages ``libvulkan1`` and ``mesa-vulkan-drivers`` (Debian
names; ``scripts/setup.sh`` installs them). Whether it starts is tried once per process in a child
process (:func:`probe`): where Vulkan has no driver Filament aborts the whole process. Where it
cannot start, "auto" warns once (``RuntimeWarning``) and the drawings use matplotlib's 3D axes.
One renderer is kept per process (Open3D cannot destroy one safely); draw from one thread at a
time. The meshes handed to it are tensor meshes of baked colours (:func:`tmesh`, :func:`tubes`,
:func:`sphere`), shaded by :func:`shade`.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import warnings

import numpy as np

from o3dheat.errors import MeshError

RENDER_SIZE = 1200  # pixels of the (square) offscreen render; panels are crops of it
UP = {"z": [0, 1, 2], "y": [2, 0, 1], "x": [1, 2, 0]}  # cyclic: keeps the orientation
RENDERERS = ("auto", "open3d", "matplotlib")
MISSING = ("Open3D's offscreen renderer cannot start here: it needs Vulkan, which a machine without "
           "a GPU gets from Mesa's software driver (lavapipe). Install the system packages libvulkan1 "
           "and mesa-vulkan-drivers (Debian/Ubuntu: sudo apt-get install libvulkan1 mesa-vulkan-drivers; "
           "scripts/setup.sh does it)")


# ------------------------------------------------------------------ the renderer (one per process)
lock = threading.RLock()
state = {"probe": None, "renderer": None, "warned": False}

PROBE = """
import numpy as np, open3d as o3d
R = o3d.visualization.rendering
r = R.OffscreenRenderer(16, 16)
mat = R.MaterialRecord()
mat.shader = "defaultUnlit"
r.scene.add_geometry("s", o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4), mat)
r.setup_camera(60.0, [0, 0, 0], [0, 0, 4], [0, 1, 0])
print("O3DHEAT_RENDER_OK", np.asarray(r.render_to_image()).shape)
"""


def probe():
    """Can Open3D's offscreen renderer start? Tried once per process in a child process: where
    Vulkan has no driver, Filament aborts the whole process instead of raising."""
    if state["probe"] is None:
        import subprocess

        try:
            r = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=180)
            ok = r.returncode == 0 and "O3DHEAT_RENDER_OK" in r.stdout
            lines = [s for s in (r.stderr + r.stdout).splitlines() if s.strip() and "O3DHEAT" not in s]
            why = "" if ok else (f" (exit status {r.returncode}: {lines[-1].strip()})" if lines
                                 else f" (exit status {r.returncode})")
        except (OSError, subprocess.SubprocessError) as e:
            ok, why = False, f" ({e})"
        state["probe"] = (ok, "" if ok else MISSING + why)
    return state["probe"]


def renderer_available() -> tuple[bool, str]:
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
    with lock:
        return probe()


@contextlib.contextmanager
def quiet_output():
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


class Renderer:
    """Open3D's OffscreenRenderer set up for exact colours: unlit materials (the shading is baked
    into the vertex colours), no post-processing (Filament's tone mapping, ambient occlusion and
    anti-aliasing change the colours and cost seconds a frame in software), white background."""

    def __init__(self, size):
        import open3d as o3d

        R = o3d.visualization.rendering
        self.size = size
        with quiet_output(), o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
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
        with lock:
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


def renderer(choice: str) -> Renderer | None:
    """The renderer to use: a :class:`Renderer`, or None for matplotlib (warning once when "auto"
    had to fall back)."""
    if choice not in RENDERERS:
        raise MeshError(f"renderer must be one of {', '.join(RENDERERS)}, got {choice!r}")
    if choice == "auto":
        choice = os.environ.get("O3DHEAT_RENDERER", "auto").strip().lower() or "auto"
        if choice not in RENDERERS:
            raise MeshError(f"O3DHEAT_RENDERER must be one of {', '.join(RENDERERS)}, got {choice!r}")
        fallback = choice == "auto"
    else:
        fallback = False
    if choice == "matplotlib":
        return None
    with lock:
        if state["renderer"] is None:
            ok, reason = probe()
            if not ok:
                if not fallback:
                    raise MeshError(reason + "; or pass renderer='matplotlib'")
                if not state["warned"]:
                    warnings.warn(reason + ". Drawing with matplotlib instead (no hidden-surface removal); "
                                  "set O3DHEAT_RENDERER=matplotlib to choose that without this warning.",
                                  RuntimeWarning, stacklevel=4)  # the caller of field, fields, tracks
                    state["warned"] = True
                return None
            state["renderer"] = Renderer(RENDER_SIZE)
        return state["renderer"]


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
        """Pixel rows and columns of the square render that hold the framed geometry."""
        w = int(np.ceil(size * np.ptp(self.u) / (2 * self.half)))
        h = int(np.ceil(size * np.ptp(self.v) / (2 * self.half)))
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
    global _SPHERE
    if _SPHERE is None:
        import open3d as o3d

        s = o3d.geometry.TriangleMesh.create_sphere(1.0, 8)
        _SPHERE = np.asarray(s.vertices), np.asarray(s.triangles)
    return _SPHERE


def tmesh(V, F, rgb):
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh()  # tensor meshes: Open3D's legacy path is erratically slow here
    m.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(V, dtype=np.float32))
    m.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(F, dtype=np.int32))
    m.vertex.colors = o3d.core.Tensor(np.ascontiguousarray(np.clip(rgb, 0, 1), dtype=np.float32))
    return m


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
