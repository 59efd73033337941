"""One scene of a scale space, built once and drawn two ways: :class:`Scene`, :class:`ScaleField`.

A scene holds what a picture of a scale space shows: the surface as drawn (welded, repaired,
possibly decimated), one or more fields over scales (each column a scale ``t``), their critical
points at every scale (computed in Python on the float64 values, before any quantization), the
critical points' tracks, the number of level sets, the view and the vertical axis, and notes on
what was repaired or decimated. :mod:`o3dheat.visualization.plot` draws it as static PNGs and
:mod:`o3dheat.visualization.page` as one offline HTML page with a slider over ``t``.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable
from concurrent.futures import wait
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks, parallel
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, check_mesh, decimate, height, prepare, transfer_map, up_axis
from o3dheat.geometry.sampling import decimate_bytes
from o3dheat.memory import available_memory, peak_memory
from o3dheat.spectral import HeatFlow, HeatKernel, eigensolve
from o3dheat.topology import Surface, critical_points, track_critical_points

from . import _layout, _panels

if TYPE_CHECKING:
    from o3dheat.topology import CriticalPoints, Tracks

__all__ = ["Scene", "ScaleField", "Recipe", "build"]

log = logging.getLogger("o3dheat")
#: Vertex attributes that are never fields of a scene.
GEOMETRY = ("positions", "normals", "colors", "texture_uvs")
METHODS = ("exact", "spectral")
#: With the exact heat flow, a mesh of more than twice this many faces gets the default grids' λ_2
#: and λ_k from a copy decimated to this many faces: its own k-eigenpair solve would cost far more
#: than the flow (and does not fit in memory at 10M vertices). Measured on the bunny: λ_2 within
#: 0.12% and λ_100 within 0.35% of the mesh's own (docs/details/heatflow.md); the labels say so.
GRID_FACES = 100_000


@dataclasses.dataclass(frozen=True, eq=False)
class ScaleField:
    """One field over scales: column ``j`` of :attr:`values` is the field at time ``times[j]``.

    Attributes
    ----------
    name : str
        The field's name (a vertex attribute's name, e.g. ``"f_exact"``).
    values : (n, T) float64 ndarray
        Finite values, one row per vertex of the scene's surface.
    times : (T,) float64 ndarray
        The scales, paper convention (``exp(−λ t / 2)``); NaN where a column has no known time
        (an attribute read from a file): the page then shows the column's index.
    critical : tuple of CriticalPoints
        One per column: :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>`
        of that column on the scene's surface (``counts`` is what the page's ``counts()`` returns).
    eps_inf : (T,) float64 ndarray or None
        ``‖Φ_t f − f‖∞ / ‖f‖∞`` per column where the unsmoothed field is known, else None.
    label : str
        How the scales were made, in words (e.g. ``"exact heat flow, log grid"``).
    markers : tuple of CriticalPoints or None
        The critical points drawn, one per column (None: all of :attr:`critical`). :func:`build`
        leaves out those of rounding errors on a part where the column is constant (as the static
        figures do: :func:`o3dheat.visualization.plot.drawn_critical_points`); the page says how many.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> from o3dheat.visualization.scene import ScaleField
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> x = m.vertex.positions.numpy()[:, 0]
    >>> sf = ScaleField("x", np.c_[x, x / 2], np.array([0.0, 1.0]), (o3dheat.critical_points(m, x),) * 2)
    >>> sf.values.shape, sf.critical[1].counts
    ((600, 2), (1, 2, 1))
    """

    name: str
    values: np.ndarray
    times: np.ndarray
    critical: tuple[CriticalPoints, ...]
    eps_inf: np.ndarray | None = None
    label: str = ""
    markers: tuple[CriticalPoints, ...] | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class Scene:
    """What a picture of a scale space shows (see the module docstring).

    Attributes
    ----------
    V : (n, 3) float64 ndarray
        The drawn surface's vertices, in the mesh's own coordinates.
    F : (m, 3) int64 ndarray
        Its faces, wound consistently per part (outward on closed parts).
    fields : tuple of ScaleField
        At least one; the first is shown first.
    tracks : dict of str to Tracks
        The critical points' tracks of some fields (by :attr:`ScaleField.name`), on ``V``.
    up : {"x", "y", "z"}
        The axis drawn vertical.
    view : (float, float)
        (elevation, azimuth) in degrees of the initial view, ``up`` vertical.
    levels : int
        Number of level sets drawn (evenly spaced over the colour range); 0: none.
    cmap : str
        A matplotlib colormap's name.
    notes : tuple of str
        What was done to the mesh before drawing it (repairs, decimation), in words.
    name : str
        The mesh's name, for titles.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> from o3dheat.visualization.scene import Scene, ScaleField
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    >>> scene = Scene(V, F, (ScaleField("z", V[:, 2:], np.zeros(1), (o3dheat.critical_points(m, V[:, 2]),)),))
    >>> len(scene.fields), scene.up
    (1, 'z')
    """

    V: np.ndarray
    F: np.ndarray
    fields: tuple[ScaleField, ...]
    tracks: dict[str, Tracks] = dataclasses.field(default_factory=dict)
    up: str = "z"
    view: tuple[float, float] = (20.0, -60.0)
    levels: int = 10
    cmap: str = "coolwarm"
    notes: tuple[str, ...] = ()
    name: str = "mesh"


@dataclasses.dataclass(frozen=True)
class Recipe:
    """How a scene is made from a mesh (:func:`build`); every field has a default.

    Attributes
    ----------
    method : {"exact", "spectral"}
        ``Φ_t f`` by the full heat kernel (:func:`o3dheat.heat_flow <o3dheat.spectral.heatflow.heat_flow>`) or
        truncated to ``k`` eigenpairs (:class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`).
    k : int
        Eigenpairs of the spectral method, and of the spectrum that defines the default scale grids.
    up : {"auto", "x", "y", "z"}
        The vertical axis (:func:`o3dheat.geometry.up.up_axis`); with "auto" the rule uses ``source``.
    source : str or Path, optional
        The file the mesh was read from (for the up rule and the title).
    max_faces : int or None
        A larger mesh is shown on a decimated copy with the fields transferred (None: all faces).
    column : int, optional
        Of an (n, c) field, the column to smooth, 0-based, negative from the end (default: the
        columns are the scales).
    noise, seed : float, int
        The default field: the height along ``up`` plus ``noise`` (relative to its range) Gaussian
        noise of this seed.
    tracks : bool
        Follow the critical points across the scales (fields with increasing times only).
    levels : int
        Level sets drawn; cmap: a matplotlib colormap.

    Examples
    --------
    >>> from o3dheat.visualization.scene import Recipe
    >>> Recipe(method="spectral", k=50, up="y").max_faces
    400000
    """

    method: str = "exact"
    k: int = 100
    up: str = "auto"
    source: object = None
    max_faces: int | None = 400_000
    column: int | None = None
    noise: float = 0.1
    seed: int = 0
    tracks: bool = True
    levels: int = 10
    cmap: str = "coolwarm"

    def __post_init__(self):
        if self.method not in METHODS:
            raise MeshError(f"method must be one of {', '.join(METHODS)}, got {self.method!r}")
        checks.count(self.k, "k")
        if self.max_faces is not None:
            checks.count(self.max_faces, "max_faces", minimum=100)
        if self.column is not None and (isinstance(self.column, bool) or not isinstance(self.column, (int, np.integer))):
            raise MeshError(f"column must be an integer (0-based, -1 the last), got {self.column!r}")
        checks.flag(self.tracks, "tracks")
        checks.count(self.levels, "levels", minimum=0, maximum=1000)
        _layout.check_style(self.cmap)
        if isinstance(self.noise, bool) or not isinstance(self.noise, (int, float)) or not 0 <= self.noise < 1e6:
            raise MeshError(f"noise must be a number >= 0, got {self.noise!r}")
        checks.count(self.seed, "seed", minimum=0)
        up_axis(self.up)


def build(mesh, field=None, t=None, recipe: Recipe | None = None, echo: Callable[[str], None] | None = None) -> Scene:
    """The :class:`Scene` of a field's scale space on a mesh (what :func:`o3dheat.view` shows).

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        The surface; an ``o3d.t`` mesh may carry the field as a vertex attribute.
    field : str, (n,) or (n, T) array_like, optional
        A vertex attribute's name or values. (n,): smoothed at the times ``t``; (n, T): its
        columns are the scales, shown as they are (or, with ``recipe.column``, that column
        smoothed). Default: every (n, T) float attribute of the mesh (T > 1) as given (in name order), or where
        there is none the height along ``up`` plus noise, smoothed.
    t : float or (T,) array_like, optional
        The times (paper convention); for (n, T) fields, the time of each column. Default for a
        smoothed field: two grids, 20 log-spaced scales over the whole multi-scale range and the
        paper's 10 (:meth:`HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>` with
        ``recipe.k`` eigenpairs), two fields of the scene.
    recipe : Recipe, optional
        How (method, up, decimation, tracks, ...); default ``Recipe()``.
    echo : callable, optional
        Called with a line of progress per stage.

    Returns
    -------
    Scene

    Examples
    --------
    >>> import open3d as o3d
    >>> from o3dheat.visualization.scene import Recipe, build
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> s = build(m, m.vertex.positions.numpy()[:, 0], [0.0, 0.1, 1.0], Recipe(tracks=False))
    >>> s.fields[0].values.shape, [cp.counts for cp in s.fields[0].critical][:1], s.up
    ((600, 3), [(1, 2, 1)], 'z')
    """
    say = echo or (lambda line: None)
    recipe = Recipe() if recipe is None else recipe
    V0, F0 = as_arrays(mesh)
    up, why_up = up_axis(recipe.up, recipe.source)
    given = _given_fields(mesh, field, len(V0), recipe)
    notes = [f"drawn with {why_up}"]
    V, F, given = _cleaned(V0, F0, given, notes)
    # the operators first (GIL-bound numpy), then the surface as drawn in a thread beside the flow's
    # factorization and solves (which release the GIL and leave part of a core idle)
    smoother = _Smoother(V, F, recipe, say) if any(vals is None or vals.ndim == 1 for _, vals in given) else None
    need = smoother.peak_bytes(sum(vals is None or vals.ndim == 1 for _, vals in given)) if smoother else 0
    shown = _Shown(V, F, recipe.max_faces, say, need)
    if smoother is not None:
        smoother.drawn = shown.copy  # a decimated copy, for the grids' eigenvalues of a large mesh
    fields = _smoothed(smoother, given, t, up, say)
    V, F, S, parts, fields = shown.drawn(fields, notes)
    t0 = time.perf_counter()
    out = tuple(_with_critical_points(S, parts, *field) for field in fields)
    say(f"critical points at {sum(f.values.shape[1] for f in out)} scales: {time.perf_counter() - t0:.1f} s")
    tracks = {}
    if recipe.tracks:
        for f in out:
            if f.values.shape[1] > 1 and np.all(np.isfinite(f.times)) and np.all(np.diff(f.times) > 0):
                t0 = time.perf_counter()
                tracks[f.name] = track_critical_points(S, f.values, f.times, critical=f.critical)
                say(f"tracks of {f.name}: {len(tracks[f.name]):,} in {time.perf_counter() - t0:.1f} s")
    return Scene(V, F, out, tracks, up=up, levels=recipe.levels, cmap=recipe.cmap, notes=tuple(notes),
                 name=_name(recipe.source))


class _Shown:
    """The surface as drawn, made in a background thread while the fields are computed (it needs the
    geometry only): the mesh itself or, above ``max_faces`` faces, a decimated copy with the map that
    moves fields onto it (:func:`~o3dheat.geometry.interpolation.transfer_map`); its faces wound
    consistently (:func:`._layout.oriented`), its :class:`~o3dheat.topology.surface.Surface` with
    the edge tables built, and its parts."""

    def __init__(self, V, F, max_faces, say, need=0):
        self.n, self.m = len(V), len(F)
        decimating = max_faces is not None and len(F) > max_faces
        # beside the fields' computation (``need`` bytes) when there is room for both twice over,
        # else first: at 10M vertices each takes 8-10 GB
        aside = not decimating or _room_for_both(decimate_bytes(len(F), vertex_map=False), need)
        if decimating:
            say(f"decimating {len(F):,} faces to {max_faces:,} for the picture, "
                + ("while the fields are computed" if aside else "before the fields are computed (memory: not both at once)")
                + " (max_faces, --max-faces; None or 'none' keeps all)")
        if aside:  # a thread of its own: the flow's parallel loops keep the pool's threads
            self.future = parallel.aside(self._made, V, F, max_faces if decimating else None, name="o3dheat-surface")
        else:
            self.future = parallel.aside(self._made, V, F, max_faces)
            wait([self.future])  # done now; its error, if any, raised by drawn()

    @staticmethod
    def _made(V, F, max_faces):
        move = None
        if max_faces is not None:
            Vd, Fd = decimate((V, F), target_faces=max_faces, vertex_map=False).arrays
            V, F, move = Vd, Fd, transfer_map((V, F), Vd)
        F = _layout.oriented(V, F)
        S = Surface.from_faces(len(V), F, V)
        S.E  # noqa: B018 - the edge tables, built here (the tracks' radius reads them)
        return V, F, S, _panels.vertex_parts(len(V), F), move

    def copy(self):
        """``(V, F)`` of the decimated copy drawn, or None when the mesh is drawn as it is."""
        V, F, _, _, move = self.future.result()
        return None if move is None else (V, F)

    def drawn(self, fields, notes):
        """``(V, F, S, parts, fields)`` as drawn: the fields moved onto the decimated copy (said in
        ``notes``)."""
        V, F, S, parts, move = self.future.result()
        if move is not None:
            notes.append(f"shown on a decimated copy: {self.m:,} → {len(F):,} faces ({self.n:,} → "
                         f"{len(V):,} vertices), the fields computed on the full mesh and transferred")
            fields = [(name, move(vals), times, eps, label) for name, vals, times, eps, label in fields]
        return V, F, S, parts, fields


def _with_critical_points(S, parts, name, vals, times, eps, label):
    """The :class:`ScaleField`: the critical points of every column, and those drawn (less the
    rounding errors' on parts where the column is constant)."""
    def column(j):
        cp = critical_points(S, vals[:, j])
        flat = _panels.flat_parts(vals[:, j], parts)
        return cp, _panels.without_flat(cp, parts, flat)[0] if flat.any() else cp

    critical, markers = zip(*parallel.run(column, [(j,) for j in range(vals.shape[1])]), strict=True)
    return ScaleField(name, vals, times, tuple(critical), eps, label, tuple(markers))


def _name(source):
    from pathlib import Path

    return Path(source).name if source is not None else "mesh"


def _attributes(mesh):
    """``{name: values}`` of an ``o3d.t`` mesh's vertex attributes (none for other meshes)."""
    vertex = getattr(mesh, "vertex", None)
    if vertex is None or not hasattr(mesh, "triangle"):
        return {}
    return {key: vertex[key].numpy() for key in vertex if key not in GEOMETRY}


def _given_fields(mesh, field, n, recipe):
    """``[(name, values)]``: the fields asked for, checked (one line for a NaN, an unknown attribute)."""
    attrs = _attributes(mesh)
    if field is None and recipe.column is not None:
        raise MeshError(f"column={recipe.column} picks a column of a field: give the field (an attribute's name)")
    if field is None:
        many = {k: v for k, v in attrs.items() if v.ndim == 2 and v.shape[1] > 1 and np.issubdtype(v.dtype, np.floating)}
        if many and recipe.column is None:
            return [(k, checks.field(many[k], n, f"attribute {k!r}")) for k in sorted(many)]  # in name order
        return [("height", None)]
    if isinstance(field, str):
        if field not in attrs:
            have = ", ".join(attrs) or "none"
            raise MeshError(f"the mesh has no vertex attribute {field!r} (its attributes: {have})")
        name, values = field, attrs[field]
    else:
        name, values = "f", field
    values = checks.field(values, n, f"field {name!r}" if isinstance(field, str) else "the field")
    if recipe.column is not None:
        c = recipe.column
        if values.ndim != 2 or not -values.shape[1] <= c < values.shape[1]:
            raise MeshError(f"column {c} asked of {name!r}, which has shape {values.shape}")
        c = c % values.shape[1]
        values, name = values[:, c], f"{name}[{c}]"
    return [(name, values)]


def _cleaned(V, F, given, notes):
    """``(V, F, given)`` on the mesh as o3dheat sees it: non-manifold parts split (said), coincident
    vertices welded (said), unreferenced vertices dropped; the default field made on it."""
    try:
        Surface.from_faces(len(V), F, V)  # a tenth of check_mesh's time, and what needs a 2-manifold
        manifold = True
    except MeshError as e:  # other faults are for the later stages to name
        manifold = "manifold" not in str(e)
    if not manifold:
        report = check_mesh((V, F))
        why = (f"{report.non_manifold_edges} non-manifold edges and {report.non_manifold_vertices} non-manifold "
               "vertices split (o3dheat.repair)")
        # one repair for every field: the vertex each copy comes from, then each field indexed by it
        V, F, source = _layout.repaired(V, F, np.arange(len(V)), why, "the scene is made")
        given = [(name, None if vals is None else vals[source]) for name, vals in given]
        notes.append(why)
    p = prepare((V, F))
    if len(p.V) < len(V):
        notes.append(f"{len(V) - len(p.V):,} vertices welded or unreferenced dropped ({len(V):,} → {len(p.V):,}): "
                     "vertex indices are those of the cleaned mesh")
    return p.V, p.F, [(name, None if vals is None else p.restrict(vals)) for name, vals in given]


def _smoothed(smoother, given, t, up, say):
    """``[(name, values (n, T), times, eps_inf, label)]``: each field over its scales (``smoother``:
    None when every field is given over its scales). The fields to smooth are smoothed together,
    on every grid at once: one heat flow (its solves shared by the columns, its factors by the
    grids) instead of one per field and grid."""
    out, todo = [], []
    recipe = smoother.recipe if smoother is not None else None
    for name, vals in given:
        if vals is not None and vals.ndim == 2:
            T = vals.shape[1]
            times = np.full(T, np.nan) if t is None else checks.times(t)
            if len(times) != T:
                raise MeshError(f"{len(times)} times given for {name!r}, which has {T} columns")
            out.append((name, vals, times, None, "as given"))
            continue
        default = vals is None
        if default:  # the noisy height along up
            h = height(smoother.V, up)
            vals = h + recipe.noise * np.ptp(h) * np.random.default_rng(recipe.seed).standard_normal(len(h))
            name = "f"  # as in the demo: the noisy height
        todo.append((len(out), name, vals, default))
        out.append(None)  # its place, in the order given
    if not todo:
        return out
    grids = [("", checks.times(t), "times given")] if t is not None else [
        ("", smoother.grid(20, "log"), "20 log-spaced scales, the whole multi-scale range" + smoother.of),
        ("_paper", smoother.grid(10, "paper"), f"the paper's 10 scales (i/10)/λ_{recipe.k}" + smoother.of)]
    t0 = time.perf_counter()
    # the grids' times sorted, each once: the flow then writes its result in place (no reordered copy)
    union, where = np.unique(np.concatenate([tg for _, tg, _ in grids]), return_inverse=True)
    G = smoother(np.column_stack([vals for _, _, vals, _ in todo]), union)
    smoother.release()  # the factors' memory, before the fields are copied out
    say(f"{', '.join(name for _, name, _, _ in todo)}: {G.shape[2]} scales by the {smoother.what} in "
        f"{time.perf_counter() - t0:.1f} s")
    smoothed = []
    for i, (_, name, vals, default) in enumerate(todo):
        start, fields = 0, []
        for suffix, times, what in grids:
            Gi = G[:, i, where[start:start + len(times)]]
            start += len(times)
            eps = np.abs(Gi - vals[:, None]).max(axis=0) / max(float(np.abs(vals).max()), 1e-300)
            about = f"height along {up} + {recipe.noise:g} noise (seed {recipe.seed}); " if default else ""
            fields.append((name + suffix, Gi, times, eps, f"{about}{smoother.what}, {what}"))
        smoothed.append(fields)
    del G
    for (at, *_), fields in zip(todo, smoothed, strict=True):
        out[at] = fields
    return [f for item in out for f in (item if isinstance(item, list) else [item])]


def _room_for_both(first, second):
    """Whether two computations of ``first`` and ``second`` bytes fit side by side twice over."""
    free = available_memory()
    return free is None or free > 2 * (first + second)


class _Smoother:
    """``Φ_t f`` by the recipe's method, and the scale grids of its spectrum (computed once): with
    the exact flow on more than twice :data:`GRID_FACES` faces, the grids' spectrum is that of a
    decimated copy (``drawn``: the page's own decimated copy when there is one, decimated further)."""

    def __init__(self, V, F, recipe, say):
        self.V, self.F, self.recipe, self.say = V, F, recipe, say
        self.kernel = self.grids = None
        self.drawn = lambda: None
        self.flow = HeatFlow((V, F)) if recipe.method == "exact" else None
        self.what = "exact heat flow" if recipe.method == "exact" else f"heat kernel of {recipe.k} eigenpairs"
        self.of = ""  # how the grids' eigenvalues were had, when not from the mesh's own spectrum

    def spectral(self):
        if self.kernel is None:
            t0 = time.perf_counter()
            k = min(self.recipe.k, len(self.V) - 2)
            self.kernel = HeatKernel(eigensolve((self.V, self.F), k=k))
            self.say(f"eigensolve, {k} eigenpairs: {time.perf_counter() - t0:.1f} s")
        return self.kernel

    def release(self):
        """The flow's factors let go (:meth:`o3dheat.HeatFlow.release`)."""
        if self.flow is not None:
            self.flow.release()

    def peak_bytes(self, c):
        """Estimated peak bytes of smoothing ``c`` fields (on about 30 scales over four decades)."""
        if self.flow is not None:
            return self.flow.peak_bytes(c, np.geomspace(1e-4, 1.0, 30))
        return peak_memory(len(self.V), min(self.recipe.k, len(self.V) - 2)) + 8 * len(self.V) * c * 30

    def grid(self, count, kind):
        if self.flow is None or len(self.F) <= 2 * GRID_FACES:
            return self.spectral().scales(count, grid=kind)
        if self.grids is None:
            t0 = time.perf_counter()
            copy = self.drawn() or (self.V, self.F)
            V, F = decimate(copy, target_faces=GRID_FACES, vertex_map=False).arrays
            k = min(self.recipe.k, len(V) - 2)
            self.grids = HeatKernel(eigensolve((V, F), k=k))
            self.of = f" (λ_2, λ_{k} of a copy decimated to {len(F):,} faces)"
            self.say(f"the scales: eigensolve of {k} eigenpairs on a copy decimated to {len(F):,} faces "
                     f"(λ_2, λ_{k} within about 0.4% of the mesh's own; its own solve would cost far more): "
                     f"{time.perf_counter() - t0:.1f} s")
        return self.grids.scales(count, grid=kind)

    def __call__(self, F, times):
        """``(n, c, T)``: the columns of ``F`` at the times."""
        if self.flow is not None:
            return self.flow.apply(F, times).reshape(len(F), F.shape[1], -1)
        return self.spectral().smooth(F, times).reshape(len(F), F.shape[1], -1)
