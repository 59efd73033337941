"""One scene as one offline interactive HTML page: :func:`page_html`.

The page is a single self-contained file (no request of any kind leaves it: three.js r170 is
inlined, the data are embedded) that works opened from disk (``file://``) and inside an
``<iframe srcdoc=...>`` (Jupyter). It shows the surface of a :class:`~o3dheat.visualization.scene.Scene`
coloured by a field at one scale, with a slider and a play button over the scales, the time ``t``,
``ε∞`` and the numbers of minima, saddles and maxima (``CriticalPoints.counts``, computed in Python,
not in the page), a colorbar (range fixed over all scales, or per scale), the critical points as
markers (maxima red, minima blue, saddles green; 0.75% of the diagonal, smaller when thousands would
cover the surface), the tracks as thin tubes in the colour of their kind, filtered by a lifetime
threshold (``Tracks.lifetime``; tracks alive at the last scale are always kept), level sets
(``scene.levels`` values evenly spaced inside the colour range, by marching triangles on the shown
scale), a chooser of the field, a hover/click readout of a vertex's index and value, the mesh's
name and size, the fields' labels and the scene's notes. Open surfaces are drawn double-sided,
closed ones (no boundary edge: outward faces assumed) front faces only.
Mouse: drag to orbit (the ``up`` axis stays vertical), right-drag or shift-drag to pan, the wheel
to zoom; keys (on the picture): arrows orbit, ``+``/``-`` zoom, ``r`` resets the view.

Scripting API
-------------
The page defines ``window.o3dheat`` (for tests and notebooks)::

    o3dheat.ready         true once the first frame with the data has been drawn (and shown)
    o3dheat.error         null, or the message shown when the page cannot draw (no WebGL, ...)
    o3dheat.scales        the current field's times (ScaleField.times; NaN is null)
    o3dheat.scale         the index of the scale shown
    o3dheat.field         the current field's name;  o3dheat.fields: all the names
    o3dheat.setScale(i)   shows scale i (negative: from the end) and redraws before returning,
                          synchronously (returns the index shown; no Promise)
    o3dheat.setField(n)   shows the field named n (same scale index, clamped), synchronously
    o3dheat.counts()      {minima, saddles, maxima} of the current scale, as computed in Python
    o3dheat.setRange(r)   "global" (min/max over all scales) or "scale" (this scale's min/max)
    o3dheat.setLevels(b), o3dheat.setMarkers(b), o3dheat.setTracks(b)   show or hide
    o3dheat.setLifetime(x)  shows the tracks living at least x (snapped up to a track's lifetime;
                          -Infinity: all, Infinity: those alive at the last scale); returns it
    o3dheat.resetView()   the initial view
    o3dheat.frames        the number of frames drawn so far
    o3dheat.deferred      whether scale changes recolour a stored picture of the surface (software WebGL,
                          >= 100k faces: a full-screen pass instead of redrawing every triangle)
    o3dheat.setDeferred(b)  a debug switch of that path; o3dheat.timing.path: "deferred" or "plain"
    o3dheat.timing        {data, firstFrame}: ms since navigation; {update, submit}: ms of the last
                          setScale (the page's own work; handing the frame to WebGL)

The setters throw (an ``Error``) before ``ready``, and a ``RangeError`` on a bad argument. A frame is
drawn synchronously; to wait until it is on screen, wait for the next animation frame.

How the data are stored: the positions (float32, centred on the bounding box and turned so that
``scene.up`` is the third axis, as :mod:`~o3dheat.visualization.plot` does), the faces (uint16 up to
65,535 vertices, else uint32), each
field's values quantized per scale to 16 bits over that scale's ``(lo, hi)`` (``lo + q (hi − lo) /
65535``, within ``(hi − lo) / 65535`` of the float64 value; stored as two byte planes per scale, the
high bytes then the low ones, joined again by the page), the critical vertices per scale and kind
(uint32), and the tracks' vertices (int32, −1 where a track does not live), kinds (uint8) and
lifetimes (float64, ``Tracks.lifetime``) are packed in one binary blob (each array aligned to 8
bytes), gzip-compressed (one gzip member whose deflate stream is made in pieces on several threads,
as pigz does) and base64-encoded; the browser inflates it with ``DecompressionStream``.
The layout, the ranges, times, counts and texts are in a JSON block beside it. Size: three.js is
0.7 MB; values take at most 2.7 bytes of page per vertex and scale (incompressible noise), about
1.8 for smooth fields, the surface 6–10 per vertex and 4–6 per face (a sphere of 200k vertices,
400k faces and 20 scales: 10.7 MB with smooth fields, 13.9 MB with uniform noise).
"""

from __future__ import annotations

import base64
import functools
import html
import json
import math
import re
import struct
import zlib
from importlib import resources

import numpy as np

from o3dheat import parallel
from o3dheat.errors import MeshError

from ._render import UP
from ._tracks import longest_move
from .scene import Scene

__all__ = ["page_html"]

#: kinds of critical point, in the order of ``CriticalPoints.counts``
_KINDS = ("minima", "saddles", "maxima")
#: codes of the track kinds in the page (Tracks.kind strings)
_TRACK_KINDS = {"minimum": 0, "saddle": 1, "maximum": 2}


def page_html(scene: Scene) -> str:
    """The whole interactive page of ``scene`` as HTML text (one self-contained file).

    Parameters
    ----------
    scene : Scene
        The surface, its fields over scales, their critical points and tracks, the view and notes.

    Returns
    -------
    str
        An HTML document with everything inlined (three.js, the viewer, the data): write it to a
        ``.html`` file and open it in a browser, or show it in an ``<iframe srcdoc=...>``. Its
        scripting API (``window.o3dheat``) is described in the module docstring.

    Raises
    ------
    MeshError
        When the scene is inconsistent (shapes, non-finite values, indices out of range, an
        unknown colormap or ``up`` axis, tracks of a field the scene does not have).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> from o3dheat.visualization.scene import Scene, ScaleField
    >>> from o3dheat.visualization.page import page_html
    >>> m = o3d.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> V, F = np.asarray(m.vertices), np.asarray(m.triangles)
    >>> f = np.c_[V[:, 2], 0.5 * V[:, 2]]
    >>> cp = tuple(o3dheat.critical_points((V, F), f[:, j]) for j in range(2))
    >>> scene = Scene(V, F, (ScaleField("height", f, np.array([0.0, 1.0]), cp),), name="sphere")
    >>> text = page_html(scene)
    >>> text.startswith("<!DOCTYPE html>"), "<canvas" in text, "http://" in text.split("<script")[0]
    (True, True, False)
    """
    V, F, center = _surface(scene)
    n = len(V)
    # the surface's measures first: the packer deflates on the other threads from its first array on
    surface = {"radius": float(np.linalg.norm(V - center, axis=1).max()), "diagonal": float(np.linalg.norm(np.ptp(V, axis=0))),
               "closed": _closed(F, n), "area": _area(V, F), "jump": longest_move(V, F)}
    pack = _Packer()
    pack.add("positions", (V - center)[:, UP[scene.up]].astype(np.float32))
    # uint16 indices below 65535 only: WebGL 2 restarts the primitive at index 65535 of a uint16 buffer
    pack.add("faces", F.astype(np.uint16 if n <= 65535 else np.uint32))
    names = [f.name for f in scene.fields]
    fields = [_field(pack, i, field, n) for i, field in enumerate(scene.fields)]
    for key, tracks in scene.tracks.items():
        if key not in names:
            raise MeshError(f"scene.tracks has tracks of {key!r}, which is not one of the scene's fields {names}")
        i = names.index(key)
        fields[i]["tracks"] = _tracks(pack, i, tracks, scene.fields[i], n)
    meta = {
        "name": str(scene.name), "notes": [str(s) for s in scene.notes], "n": n, "m": len(F),
        "up": scene.up, "view": _view(scene.view), "levels": _levels(scene.levels), "cmap": str(scene.cmap),
        "lut": _lut(scene.cmap), **surface,
        "fields": fields,
        "layout": pack.layout,
    }
    parts = {
        "title": html.escape(str(scene.name)),
        "meta": json.dumps(meta, allow_nan=False, separators=(",", ":")).replace("<", "\\u003c")
        .replace(">", "\\u003e").replace("&", "\\u0026"),
        "data": base64.b64encode(pack.gzip()).decode("ascii"),
        "three": _three(),
        "script": _asset("page.js"),
    }
    return re.sub(r"\{\{(\w+)\}\}", lambda m: parts[m.group(1)], _asset("page.html"))


class _Deflater:
    """One gzip member made piece by piece, pigz's way: each piece of ``piece`` bytes (default
    :data:`_PIECE`) fed is deflated (level 1) on :mod:`o3dheat.parallel`'s pool while the caller
    goes on (zlib releases the GIL), as a raw deflate run ended by a sync flush (an empty stored
    block, byte-aligned); :meth:`finish` adds the final empty block, so the concatenation is one
    valid deflate stream (a piece refers to no earlier piece), and the CRC-32 and size."""

    HEADER = b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x04\xff"  # magic, deflate, no flags, mtime 0, fastest, OS unknown

    def __init__(self, piece=None):
        self.piece, self.jobs, self.crc, self.size = piece or _PIECE, [], 0, 0

    def feed(self, data, level=1):
        """Deflate ``data`` at ``level`` (0: stored, for bytes that do not compress)."""
        view = memoryview(data)
        self.crc, self.size = zlib.crc32(view, self.crc), self.size + len(view)
        self.jobs += [parallel.background(_deflated, view[a:a + self.piece], level, False)
                      for a in range(0, len(view), self.piece)]
        return self

    def finish(self):
        body = b"".join(job.result() for job in self.jobs)
        return self.HEADER + body + _deflated(b"", 1, True) + struct.pack("<II", self.crc, self.size & 0xFFFFFFFF)


def _deflated(data, level, final):
    """A raw deflate run of ``data``, ended by the final block or by a sync flush."""
    z = zlib.compressobj(level, zlib.DEFLATED, -15)
    return z.compress(data) + z.flush(zlib.Z_FINISH if final else zlib.Z_SYNC_FLUSH)


# ------------------------------------------------------------------ checks and pieces of the page
def _surface(scene):
    """``(V, F, center)``: the scene's checked vertices (float64), faces (int64) and the centre of
    their bounding box."""
    if not isinstance(scene, Scene):
        raise MeshError(f"page_html needs an o3dheat.visualization.scene.Scene, got {type(scene).__name__}")
    V = np.asarray(scene.V, dtype=np.float64)
    F = np.asarray(scene.F)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise MeshError(f"scene.V must be an (n, 3) array of vertices, got shape {V.shape}")
    if not np.isfinite(V).all():
        raise MeshError("scene.V has NaN or infinite coordinates: repair the mesh before drawing it")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or F.dtype.kind not in "iu":
        raise MeshError(f"scene.F must be an (m, 3) integer array of faces, got shape {F.shape} ({F.dtype})")
    if F.min() < 0 or F.max() >= len(V):
        raise MeshError(f"scene.F has vertex indices outside [0, {len(V) - 1}]")
    if scene.up not in UP:
        raise MeshError(f"scene.up must be 'x', 'y' or 'z', got {scene.up!r}")
    if not scene.fields:
        raise MeshError("the scene has no fields: give at least one ScaleField")
    names = [f.name for f in scene.fields]
    if len(set(names)) != len(names):
        raise MeshError(f"the scene's fields need distinct names, got {names}")
    return V, F.astype(np.int64), (V.min(0) + V.max(0)) / 2


def _closed(F, n):
    """True when every edge has exactly two faces (no boundary): the page then draws front faces only."""
    a, b = F.reshape(-1), F[:, [1, 2, 0]].reshape(-1)
    keys = np.sort(np.minimum(a, b) * np.int64(n) + np.maximum(a, b))
    # every key exactly twice: pairs (0, 1), (2, 3) ... equal, and no pair equal to the next one
    return bool(len(keys) % 2 == 0 and np.all(keys[0::2] == keys[1::2]) and np.all(keys[1:-1:2] != keys[2::2]))


def _area(V, F):
    """The surface's area (the page sizes the markers by it)."""
    return float(np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1).sum() / 2)


def _field(pack, i, field, n):
    """The page's description of field ``i`` (its values and critical points packed into ``pack``)."""
    values = np.asarray(field.values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2 or values.shape[0] != n or values.shape[1] == 0:
        raise MeshError(f"field {field.name!r}: values must be ({n}, T), one row per vertex, got {values.shape}")
    if not np.isfinite(values).all():
        raise MeshError(f"field {field.name!r} has NaN or infinite values: the page draws finite values only")
    T = values.shape[1]
    times = np.asarray(field.times, dtype=np.float64).reshape(-1)
    if len(times) != T:
        raise MeshError(f"field {field.name!r}: {len(times)} times for {T} columns of values")
    if len(field.critical) != T:
        raise MeshError(f"field {field.name!r}: {len(field.critical)} CriticalPoints for {T} columns of values")
    lo, hi = values.min(axis=0), values.max(axis=0)
    planes = _quantized(values, lo, hi)  # (T, 2, n): the low bytes stored, deflate gains nothing on them
    pack.add(f"values{i}", planes.reshape(2 * T, n), levels=[1, 0] * T)
    markers = field.critical if field.markers is None else field.markers
    if len(markers) != T:
        raise MeshError(f"field {field.name!r}: {len(markers)} sets of markers for {T} columns of values")
    crit, offsets, counts = [], [0], []
    hidden = [int(sum(a.counts) - sum(b.counts)) for a, b in zip(field.critical, markers, strict=True)]
    for j, cp in enumerate(markers):
        for kind in _KINDS:
            idx = np.asarray(getattr(cp, kind), dtype=np.int64).reshape(-1)
            if len(idx) and (idx.min() < 0 or idx.max() >= n):
                raise MeshError(f"field {field.name!r}, scale {j}: {kind} outside the scene's {n} vertices")
            crit.append(idx)
            offsets.append(offsets[-1] + len(idx))
    counts = [[int(c) for c in cp.counts] for cp in field.critical]
    pack.add(f"critical{i}", np.concatenate(crit).astype(np.uint32))
    eps = None
    if field.eps_inf is not None:
        eps = np.asarray(field.eps_inf, dtype=np.float64).reshape(-1)
        if len(eps) != T:
            raise MeshError(f"field {field.name!r}: {len(eps)} eps_inf values for {T} columns of values")
        eps = _floats(eps)
    return {"name": str(field.name), "label": str(field.label), "T": T, "times": _floats(times), "eps_inf": eps,
            "lo": lo.tolist(), "hi": hi.tolist(), "min": float(lo.min()), "max": float(hi.max()),
            "counts": counts, "hidden": hidden, "values": f"values{i}", "critical": f"critical{i}", "offsets": offsets,
            "tracks": None}


def _quantized(values, lo, hi):
    """(T, 2, n) uint8: column ``j`` of ``values`` as ``q = round((v − lo_j) / (hi_j − lo_j) · 65535)``
    (0 where the column is constant), stored as two byte planes: ``[j, 0]`` the high bytes
    ``q >> 8``, ``[j, 1]`` the low bytes. The high bytes of a smooth field vary slowly from vertex to
    vertex, which deflate's matching finds when they are not interleaved with the noisy low bytes:
    19-30% smaller than interleaved uint16, and faster to deflate. The low bytes do not deflate at
    all (the page stores them: level 0)."""
    n, T = values.shape
    out = np.empty((T, 2, n), np.uint8)
    for j in range(T):  # one column at a time: no (n, T) float temporary
        span = hi[j] - lo[j]
        scale = 65535.0 / span if span > 0 else 0.0
        q = np.clip(np.rint((values[:, j] - lo[j]) * scale), 0, 65535).astype(np.uint16)
        out[j, 0] = q >> 8
        out[j, 1] = q & 0xFF
    return out


def _tracks(pack, i, tracks, field, n):
    """The page's description of the tracks of field ``i`` (arrays packed into ``pack``)."""
    vertex = np.asarray(tracks.vertex, dtype=np.int64)
    T = len(field.times)
    if vertex.ndim != 2 or vertex.shape[1] != T:
        raise MeshError(f"tracks of {field.name!r}: vertex must be (p, {T}), one column per scale, "
                        f"got {vertex.shape}")
    if vertex.size and (vertex.min() < -1 or vertex.max() >= n):
        raise MeshError(f"tracks of {field.name!r}: vertices outside the scene's {n} vertices")
    try:
        kind = np.array([_TRACK_KINDS[k] for k in tracks.kind], dtype=np.uint8)
    except KeyError as e:
        raise MeshError(f"tracks of {field.name!r}: unknown kind {e.args[0]!r}") from None
    pack.add(f"track_vertex{i}", vertex.astype(np.int32))
    pack.add(f"track_kind{i}", kind)
    pack.add(f"track_lifetime{i}", np.asarray(tracks.lifetime, dtype=np.float64).reshape(-1))
    return {"p": len(vertex), "vertex": f"track_vertex{i}", "kind": f"track_kind{i}",
            "lifetime": f"track_lifetime{i}"}


def _floats(x):
    """A list of floats with NaN as None (JSON null)."""
    return [float(v) if math.isfinite(v) else None for v in np.asarray(x, dtype=np.float64).tolist()]


def _view(view):
    try:
        elev, azim = (float(v) for v in np.asarray(view, dtype=np.float64).reshape(2))
    except (TypeError, ValueError):
        raise MeshError(f"scene.view must be (elevation, azimuth) in degrees, got {view!r}") from None
    if not (math.isfinite(elev) and math.isfinite(azim)):
        raise MeshError(f"scene.view must be finite (elevation, azimuth) in degrees, got {view!r}")
    return [elev, azim]


def _levels(levels):
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)) or not 0 <= levels <= 1000:
        raise MeshError(f"scene.levels must be an integer from 0 to 1000, got {levels!r}")
    return int(levels)


def _lut(cmap):
    """The colormap ``cmap`` sampled at 256 points: a flat list of 768 RGB bytes."""
    import matplotlib

    try:
        cm = matplotlib.colormaps[cmap]
    except (KeyError, ValueError, TypeError):
        raise MeshError(f"scene.cmap {cmap!r} is not a matplotlib colormap (e.g. 'coolwarm', 'viridis')") from None
    rgb = cm(np.linspace(0.0, 1.0, 256))[:, :3]
    return np.rint(rgb * 255).astype(np.uint8).ravel().tolist()


#: the deflate pieces' size (bytes): many more pieces than threads, each long enough to deflate well
_PIECE = 1 << 18


class _Packer:
    """Arrays laid out one after the other in one byte string, each at a multiple of 8 bytes, and
    deflated as they come (:class:`_Deflater`: on other threads while the page's next pieces are
    made); :attr:`layout` maps a name to ``[byte offset, length, type]`` (a JavaScript typed-array
    name); :meth:`gzip` is the whole as one gzip member."""

    TYPES = {"float32": "Float32Array", "float64": "Float64Array", "uint32": "Uint32Array",
             "int32": "Int32Array", "uint16": "Uint16Array", "uint8": "Uint8Array"}

    def __init__(self):
        self.layout, self._size, self._deflater = {}, 0, _Deflater()

    def add(self, name, a, levels=None):
        """Append the array ``a``; ``levels``: per row of its first axis, the deflate level of that
        row (0: stored, for bytes that do not compress); default 1 for every row."""
        a = np.ascontiguousarray(a)
        a = a.astype(a.dtype.newbyteorder("<"), copy=False)
        self.layout[name] = [self._size, int(a.size), self.TYPES[a.dtype.name]]
        rows = [(a.tobytes(), 1)] if levels is None else [(r.tobytes(), lv) for r, lv in zip(a, levels, strict=True)]
        for data, level in rows:
            self._deflater.feed(data, level)
            self._size += len(data)
        pad = b"\0" * (-self._size % 8)
        self._deflater.feed(pad)
        self._size += len(pad)

    def gzip(self):
        return self._deflater.finish()


@functools.cache
def _asset(name):
    """The text of ``_page/<name>`` (package data)."""
    return resources.files("o3dheat.visualization").joinpath("_page", *name.split("/")).read_text("utf-8")


@functools.lru_cache(maxsize=1)
def _three():
    """three.js as the body of a function returning its exports (for a classic ``<script>``):
    the vendored ES module with its one final ``export{...}`` turned into ``return {...}``."""
    src = _asset("three/three.module.min.js")
    found = list(re.finditer(r"export\s*\{([^}]*)\}\s*;?\s*$", src))
    if len(found) != 1 or re.search(r"(^|[;\s])import[\s{*(]", src) or "</script" in src.lower():
        raise MeshError("the vendored three.js is not a self-contained module build with one final export "
                        "(see o3dheat/visualization/_page/three/README.md)")
    items = []
    for item in found[0].group(1).split(","):
        local, _, exported = (s.strip() for s in item.partition(" as "))
        items.append(f"{exported or local}:{local}")
    return src[: found[0].start()] + "\nreturn {" + ",".join(items) + "};"
