"""Critical points followed across scales: :func:`track_critical_points`, returning :class:`Tracks`.

The paper's scale spaces (§3): as t grows, critical points of the smoothed field disappear in
pairs, an extremum with a saddle. Tracking follows each one from scale to scale and records when
it ends and why.

Notes
-----
Between scales ``i`` and ``i + 1``, extrema follow the gradient flow of ``F[:, i + 1]`` (steepest
ascent for maxima, descent for minima, ties by vertex index as everywhere in
:mod:`o3dheat.topology`; of several reaching the same one the most persistent at scale ``i``
continues); saddles paired (persistence, scale ``i``) with an extremum that ends end with it, the
others are matched to the saddles of scale ``i + 1`` by a minimum-cost assignment of distances
within ``radius``. Events: ``"cancel"``, ``"creation"``, ``"split"`` / ``"merge"`` (a saddle's
multiplicity changes), ``"death"`` / ``"birth"``. Every critical vertex at every scale lies on
exactly one living track, so ``M − s + m = χ`` holds at every scale (saddles with their
multiplicity). On a closed surface an extremum whose persistence exceeds ``2‖F_i − F_{i+1}‖∞``
continues, its value moving by at most ``‖F_i − F_{i+1}‖∞`` (tested in
``tests/topology/test_tracking.py``). The rule in full, the events, what is guaranteed and what is
not, the limits and the cost: ``docs/details/topology.md`` (Tracking).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from o3dheat import checks, parallel
from o3dheat.errors import MeshError
from o3dheat.typing import FieldLike, MeshLike, TimesLike

from . import _loops
from .critical import CriticalPoints, critical_points
from .diagrams import persistence
from .surface import Surface

__all__ = ["Tracks", "track_critical_points", "KINDS"]

#: the track kinds
KINDS = ("minimum", "saddle", "maximum")


@dataclass
class Tracks:
    """Critical points followed across scales (see the module docstring for the rule).

    Computed from the attributes below, as attributes too (properties): :attr:`first`, :attr:`last`,
    :attr:`lifetime`, :attr:`positions` and :attr:`euler_characteristic`, a ``(T,)`` array of
    ``M − s + m`` per scale (it was a method: ``tr.euler_characteristic(scale)`` still works, with a
    DeprecationWarning; write ``tr.euler_characteristic[scale]``).

    Attributes
    ----------
    kind : (p,) object ndarray
        "minimum", "saddle" or "maximum" per track.
    vertex : (p, T) int64 ndarray
        The track's vertex at each scale, -1 where it does not live.
    persistence : (p, T) float64 ndarray
        Its persistence at each scale (``inf`` for an essential critical point, NaN where it does
        not live): the largest persistence of the pairs of :func:`o3dheat.persistence <o3dheat.topology.diagrams.persistence>` it belongs
        to. Computed on first access (one diagram per scale; the tracking itself computes only the
        diagrams of the scales where an extremum ends) and kept; until then the tracks hold the
        checked copy of the fields (8 n T bytes).
    multiplicity : (p, T) int64 ndarray
        Saddle multiplicity (1 for extrema, 0 where it does not live).
    times : (T,) float64 ndarray
    events : list of dict
        ``{"kind", "scale", "tracks"}``: between scale ``scale`` and ``scale + 1``.
    positions_of : (n, 3) float64 ndarray or None
        The mesh's vertex positions (for :attr:`positions`).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> x = m.vertex.positions.numpy()[:, 0]
    >>> tr = o3dheat.track_critical_points(m, np.c_[x, 2 * x, 3 * x], [0.0, 0.1, 0.2])
    >>> len(tr), tr.kind.tolist(), tr.last.tolist()
    (4, ['minimum', 'maximum', 'saddle', 'saddle'], [2, 2, 2, 2])
    >>> tr.euler_characteristic          # χ of the torus at every scale
    array([0, 0, 0])
    """

    kind: np.ndarray
    vertex: np.ndarray
    multiplicity: np.ndarray
    times: np.ndarray
    events: list = field(default_factory=list)
    positions_of: np.ndarray | None = None
    _source: tuple | None = field(default=None, repr=False)  # (Surface, F, {scale: (vertices, persistence)})
    _persistence: np.ndarray | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def persistence(self) -> np.ndarray:
        """(p, T) float64: see :class:`Tracks` (computed on first access, then kept).

        Examples
        --------
        See :class:`Tracks`.
        """
        if self._persistence is None:
            S, F, known = self._source
            pers = np.full(self.vertex.shape, np.nan)
            for j in range(self.vertex.shape[1]):
                alive = np.flatnonzero(self.vertex[:, j] >= 0)
                if len(alive):
                    cv, cp = known[j] if j in known else _vertex_persistence(persistence(S, F[:, j]))
                    pers[alive, j] = _lookup(cv, cp, self.vertex[alive, j])
            self._persistence, self._source = pers, None  # the fields are not needed any more
        return self._persistence

    def __getstate__(self):  # pickles carry the persistence, not the fields
        _ = self.persistence
        return dict(self.__dict__)

    @property
    def first(self) -> np.ndarray:
        """(p,) int64: the first scale index each track lives at.

        Examples
        --------
        See :class:`Tracks`.
        """
        return np.argmax(self.vertex >= 0, axis=1)

    @property
    def last(self) -> np.ndarray:
        """(p,) int64: the last scale index each track lives at.

        Examples
        --------
        See :class:`Tracks`.
        """
        T = self.vertex.shape[1]
        return T - 1 - np.argmax(self.vertex[:, ::-1] >= 0, axis=1)

    @property
    def lifetime(self) -> np.ndarray:
        """(p,) float64: ``times[last] − times[first]`` (``inf`` for tracks alive at the last scale).

        Examples
        --------
        See :class:`Tracks`.
        """
        out = self.times[self.last] - self.times[self.first]
        return np.where(self.last == len(self.times) - 1, np.inf, out)

    @property
    def positions(self) -> np.ndarray:
        """(p, T, 3) float64: the track's position at each scale (NaN where it does not live).

        Examples
        --------
        See :class:`Tracks`.
        """
        if self.positions_of is None:
            raise MeshError("these tracks were made without vertex positions")
        out = np.full(self.vertex.shape + (3,), np.nan)
        alive = self.vertex >= 0
        out[alive] = self.positions_of[self.vertex[alive]]
        return out

    def features(self, scale: int = -1) -> np.ndarray:
        """The critical vertices of the first field whose tracks live to ``scale`` (an index into
        :attr:`times`, default the last): the lifetime criterion of feature-driven approximation
        (beside δ-persistence), A for :func:`o3dheat.feature_driven <o3dheat.topology.approximation.feature_driven>`.

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
        >>> V = m.vertex.positions.numpy().astype(float)
        >>> f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
        >>> t = np.geomspace(1e-3, 1.0, 12)
        >>> tr = o3dheat.track_critical_points(m, o3dheat.heat_flow(m, f, t), t)
        >>> len(tr.features(0)), len(tr.features())     # the bump's maximum and a saddle do not last
        (4, 2)
        """
        T = len(self.times)
        if isinstance(scale, bool) or not isinstance(scale, (int, np.integer)) or not -T <= scale < T:
            raise MeshError(f"scale must be an index of the {T} scales (0 to {T - 1}, or negative from the end), "
                            f"got {scale!r}")
        scale = range(T)[scale]
        keep = (self.first == 0) & (self.last >= scale)
        return np.unique(self.vertex[keep, 0])

    def subset(self, keep: ArrayLike) -> Tracks:
        """The tracks ``keep`` (a (p,) bool mask), the events among them renumbered (a persistence
        not yet computed is computed from the subset's vertices; one computed already is sliced).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> x = m.vertex.positions.numpy()[:, 0]
        >>> tr = o3dheat.track_critical_points(m, np.c_[x, 2 * x], [0.0, 0.1])
        >>> tr.subset(tr.kind != "saddle").kind.tolist()
        ['minimum', 'maximum']
        """
        keep = np.asarray(keep, bool)
        if keep.all():
            return self
        new = np.cumsum(keep) - 1
        events = [dict(e, tracks=[int(new[i]) for i in e["tracks"]]) for e in self.events
                  if keep[list(e["tracks"])].all()]
        pers = None if self._persistence is None else self._persistence[keep]
        return replace(self, kind=self.kind[keep], vertex=self.vertex[keep],
                       multiplicity=self.multiplicity[keep], events=events, _persistence=pers)

    @property
    def euler_characteristic(self) -> np.ndarray:
        """(T,) int64: ``M − s + m`` of the living tracks at each scale (saddles with their
        multiplicity), χ of the surface at every scale (see the module docstring).

        It was a method: ``tr.euler_characteristic(scale)`` still returns the int at ``scale``, with a
        DeprecationWarning (the array is callable for that); write ``tr.euler_characteristic[scale]``.

        Examples
        --------
        See :class:`Tracks`.
        """
        sign = np.where(self.kind == "saddle", -1, 1).astype(np.int64)
        alive = self.vertex >= 0
        chi = np.sum(np.where(alive, sign[:, None] * self.multiplicity, 0), axis=0, dtype=np.int64)
        return chi.view(_PerScale)

    def __repr__(self):
        counts = {k: int(np.sum(self.kind == k)) for k in KINDS}
        return (f"Tracks({len(self)} tracks: {counts['minimum']} minima, {counts['saddle']} saddles, "
                f"{counts['maximum']} maxima; {len(self.times)} scales; {len(self.events)} events)")


class _PerScale(np.ndarray):
    """:attr:`Tracks.euler_characteristic`: a plain ``(T,)`` array that can also be called the way of
    the former method, ``tr.euler_characteristic(scale)`` (a DeprecationWarning; the int at ``scale``).
    What is computed from it (``chi == 0``, ``chi + 1``) is a plain ndarray."""

    def __call__(self, scale: int) -> int:
        warnings.warn("Tracks.euler_characteristic is an attribute now, a (T,) array of M - s + m per scale "
                      "(like first, last and lifetime): write tr.euler_characteristic[scale] instead of "
                      "tr.euler_characteristic(scale)", DeprecationWarning, stacklevel=2)
        return int(np.asarray(self)[scale])

    def __array_wrap__(self, array, context=None, return_scalar=False):
        array = np.asarray(array)
        return array[()] if return_scalar else array

    def __repr__(self) -> str:
        return repr(np.asarray(self))


def track_critical_points(mesh: MeshLike | Surface, F: FieldLike, t: TimesLike,
                          radius: float | None = None, *, critical: Sequence[CriticalPoints] | None = None) -> Tracks:
    """Follow the critical points of fields at increasing times across the scales.

    Parameters
    ----------
    mesh : mesh-like or :class:`o3dheat.topology.Surface <o3dheat.topology.surface.Surface>`
        A 2-manifold triangle mesh (see :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>`).
    F : (n, T) array_like
        One field per scale, e.g. ``heat_flow(mesh, f, t)`` or ``HeatKernel(s).smooth(f, t)``.
    t : (T,) array_like
        Strictly increasing times (any unit: only their order and differences are used).
    radius : float, optional
        Largest distance (mesh units) a saddle moves between two scales; default 10 mean edge
        lengths. A :class:`~o3dheat.topology.surface.Surface` made from faces alone (no positions)
        matches a saddle only where it stays on its vertex: one that moves is a death and a birth
        (extrema, which follow the flow, are tracked as with positions).
    critical : sequence of CriticalPoints, optional
        ``critical_points(mesh, F[:, j])`` for every column ``j``, when the caller has them already
        (a scene draws them too); checked for number and mesh size only. Default: computed here,
        the columns shared among threads (:mod:`o3dheat.parallel`).

    Returns
    -------
    Tracks

    Raises
    ------
    MeshError
        ``F`` not of shape (n, T) for T times, NaN, times not increasing, a bad mesh.

    Notes
    -----
    Cost: per scale one :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>` (O(m), compiled; none with ``critical``), a walk up (down) the
    steepest edges from each maximum (minimum) of the scale before, compiled, over the vertices it
    passes only, and bookkeeping in numpy over the critical points; :func:`o3dheat.persistence <o3dheat.topology.diagrams.persistence>`
    only at the scales where an extremum ends (its partner and the "most persistent" rule need
    it). The saddles' matching is a dense assignment, quadratic in the saddles of a scale. Measured
    (``scripts/bench_topology.py``): 100 scales of a smooth field on 200k vertices take 1.6 to 1.9
    times the 100 critical-point sets alone. Memory: the checked copy of ``F`` (8 n T bytes, kept
    by the tracks until :attr:`Tracks.persistence` is first read), O(n) per scale, and 24 bytes per
    track and scale for the result: linear in n T.

    Examples
    --------
    A tilted height and a bump: the bump's maximum and a saddle cancel between scales 6 and 7.

    >>> import numpy as np, open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
    >>> t = np.geomspace(1e-3, 1.0, 12)
    >>> tr = o3dheat.track_critical_points(m, o3dheat.heat_flow(m, f, t), t)
    >>> [(e["kind"], e["scale"], tr.kind[e["tracks"]].tolist()) for e in tr.events]
    [('cancel', 6, ['maximum', 'saddle'])]
    """
    S = Surface.of(mesh)
    times, Fa, V, radius = _checked(S, F, t, radius)
    T = len(times)
    critical = _critical(S, Fa, critical)
    diagrams = _Diagrams(S, Fa)
    cur = _Scale(critical[0])
    ids = {k: np.arange(len(cur.v[k])) + o for k, o in zip(("minimum", "maximum", "saddle"),
                                                          np.cumsum([0, len(cur.v["minimum"]), len(cur.v["maximum"])]),
                                                          strict=True)}
    p = sum(len(x) for x in ids.values())
    kinds = [k for k in ("minimum", "maximum", "saddle") for _ in range(len(ids[k]))]
    alive = [_living(ids, cur)]
    events = []
    for i in range(T - 1):
        nxt = _Scale(critical[i + 1])
        new_of, ended = _follow_extrema(S, cur, nxt, Fa[:, i], Fa[:, i + 1], diagrams, i)
        partner = diagrams(i)[2] if ended else {}
        new_of["saddle"], gone = _follow_saddles(V, cur, nxt, ended, partner, radius)
        ended += gone
        new_ids, born, p = _number(new_of, ids, nxt, p, kinds)
        events += _events(i, ended, born, ids, new_ids, cur, nxt, new_of["saddle"], partner, V, radius)
        alive.append(_living(new_ids, nxt))
        cur, ids = nxt, new_ids
    vertex = np.full((p, T), -1, np.int64)
    mult = np.zeros((p, T), np.int64)
    for j, (tid, v, m) in enumerate(alive):
        vertex[tid, j], mult[tid, j] = v, m
    kind = np.array(kinds, dtype=object)
    return Tracks(kind, vertex, mult, times, events, V, (S, Fa, diagrams.known()))


def _checked(S, F, t, radius):
    """The checked arguments of :func:`track_critical_points`: (times, fields, positions or None,
    radius)."""
    times = checks.times(t)
    times = np.atleast_1d(times)
    if np.any(np.diff(times) <= 0):
        raise MeshError("t must be strictly increasing")
    Fa = checks.field(F, S.n, "F", ndim=(2,))
    if Fa.shape[1] != len(times):
        raise MeshError(f"F has {Fa.shape[1]} columns for {len(times)} times: one field per time")
    V = None if S.V is None else np.asarray(S.V, dtype=np.float64)
    if radius is None:
        radius = 10 * (np.linalg.norm(V[S.E[:, 0]] - V[S.E[:, 1]], axis=1).mean() if V is not None else 1.0)
    elif (isinstance(radius, bool) or not isinstance(radius, (int, float, np.integer, np.floating))
          or not (np.isfinite(radius) and radius > 0)):
        raise MeshError(f"radius must be a positive number, got {radius!r}")
    return times, Fa, V, radius


def _critical(S, Fa, critical):
    """The critical points of every column: ``critical`` checked (one per column, of this mesh's
    size), or computed, the columns shared among threads."""
    T = Fa.shape[1]
    if critical is None:
        return parallel.run(lambda j: critical_points(S, Fa[:, j]), [(j,) for j in range(T)])
    critical = list(critical) if not isinstance(critical, (str, bytes)) and hasattr(critical, "__len__") else None
    if critical is None or len(critical) != T:
        raise MeshError(f"critical must be a sequence of {T} CriticalPoints, one per column of F")
    for j, cp in enumerate(critical):
        if not isinstance(cp, CriticalPoints) or cp.n != S.n:
            what = f"of a mesh of {cp.n} vertices" if isinstance(cp, CriticalPoints) else f"a {type(cp).__name__}"
            raise MeshError(f"critical[{j}] is {what}: give critical_points(mesh, F[:, {j}]) for this mesh of "
                            f"{S.n} vertices")
    return critical


class _Diagrams:
    """The persistence of the scales, computed where needed: ``diagrams(i)`` is (the critical
    vertices of scale i sorted, their persistence, {creator: destroyer})."""

    def __init__(self, S, F):
        self.S, self.F, self.done = S, F, {}

    def __call__(self, i):
        if i not in self.done:
            dg = persistence(self.S, self.F[:, i])
            self.done[i] = _vertex_persistence(dg) + (dict(zip(dg.pairs[:, 0].tolist(), dg.pairs[:, 1].tolist(),
                                                                strict=True)),)
        return self.done[i]

    def known(self):
        """{scale: (vertices, persistence)} of the scales computed."""
        return {j: d[:2] for j, d in self.done.items()}


def _living(ids, sc):
    """(track ids, vertices, multiplicities) of the critical points of a scale, in :data:`KINDS` order."""
    return (np.concatenate([ids[k] for k in KINDS]), np.concatenate([sc.v[k] for k in KINDS]),
            np.concatenate([sc.m[k] for k in KINDS]))


def _follow_extrema(S, cur, nxt, f_now, f_next, diagrams, i):
    """Maxima and minima of scale i (``cur``) followed along the flow to scale i + 1 (``nxt``):
    ({kind: (positions in cur of the continuing tracks, their positions in nxt)}, the ended
    ``(kind, position in cur)`` in the order the rule lists them)."""
    new_of, ended = {}, []
    for kind, up in (("maximum", True), ("minimum", False)):
        heads = cur.v[kind]
        w = _climb(S, f_next, heads, up)
        pos = _positions(nxt.v[kind], w)  # -1: the walk stopped on a regular vertex
        ended += [(kind, int(a)) for a in np.flatnonzero(pos < 0)]
        reach = np.flatnonzero(pos >= 0)
        _, first, inv, cnt = np.unique(pos[reach], return_index=True, return_inverse=True, return_counts=True)
        win = reach[first]  # a group of one: its only head continues
        for g in np.argsort(first, kind="stable"):  # groups in the order of their first head
            if cnt[g] == 1:
                continue
            vs = reach[inv == g]
            cv, cpers, _ = diagrams(i)
            sign = 1.0 if up else -1.0
            key = [(float(q), sign * f_now[heads[a]], -int(heads[a]))
                   for a, q in zip(vs, _lookup(cv, cpers, heads[vs]), strict=True)]
            best = int(vs[max(range(len(vs)), key=key.__getitem__)])
            win[g] = best
            ended += [(kind, int(a)) for a in vs if a != best]
        new_of[kind] = (win, pos[win])
    return new_of, ended


def _follow_saddles(V, cur, nxt, ended, partner, radius):
    """The saddles of ``cur`` not paired with an ended extremum matched to those of ``nxt``:
    ((positions in cur, positions in nxt), the ended ``("saddle", position in cur)``)."""
    ending = {partner[int(cur.v[k][a])] for k, a in ended if int(cur.v[k][a]) in partner}
    sv = cur.v["saddle"]
    keep = np.flatnonzero(~np.isin(sv, np.fromiter(ending, np.int64, len(ending))))
    a, b = _match(V, keep, sv, nxt.v["saddle"], radius)
    gone = np.ones(len(sv), bool)
    gone[a] = False
    return (a, b), [("saddle", int(x)) for x in np.flatnonzero(gone)]


def _number(new_of, ids, nxt, p, kinds):
    """The track ids of the critical points of ``nxt``: a continuing one keeps its track's, a new
    one gets the next free id (``p`` on, its kind appended to ``kinds``). Returns ({kind: ids},
    the born ``(kind, position in nxt)``, the next free id)."""
    new_ids, born = {}, []
    for kind in ("minimum", "maximum", "saddle"):
        a, b = new_of[kind]
        tid = np.full(len(nxt.v[kind]), -1, np.int64)
        tid[b] = ids[kind][a]
        fresh = np.flatnonzero(tid < 0)
        tid[fresh] = p + np.arange(len(fresh))
        p += len(fresh)
        kinds += [kind] * len(fresh)
        born += [(kind, int(x)) for x in fresh]
        new_ids[kind] = tid
    return new_ids, born, p


class _Scale:
    """The critical points of one scale by kind (vertex order of :func:`o3dheat.critical_points <o3dheat.topology.critical.critical_points>`)
    and their multiplicities."""

    def __init__(self, cp):
        self.v = {"minimum": cp.minima, "maximum": cp.maxima, "saddle": cp.saddles}
        self.m = {"minimum": np.ones(len(cp.minima), np.int64), "maximum": np.ones(len(cp.maxima), np.int64),
                  "saddle": cp.saddle_multiplicity}


def _vertex_persistence(dg):
    """(vertices, persistence): the vertices of the pairs of a diagram, sorted, each with the
    largest persistence of its pairs."""
    keys = dg.pairs.T.reshape(-1)
    q = np.concatenate([dg.persistence, dg.persistence])
    o = np.argsort(keys, kind="stable")
    keys, q = keys[o], q[o]
    if not len(keys):
        return keys, q
    start = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    return keys[start], np.maximum.reduceat(q, start)


def _lookup(cv, cp, v):
    """The persistence of vertices ``v`` from :func:`_vertex_persistence` (``inf`` when unpaired)."""
    j = np.minimum(np.searchsorted(cv, v), max(len(cv) - 1, 0))
    hit = (cv[j] == v) if len(cv) else np.zeros(len(v), bool)
    return np.where(hit, cp[j] if len(cv) else 0.0, np.inf)


def _positions(sorted_vertices, w):
    """The position of each ``w`` in ``sorted_vertices`` (ascending), -1 where it is absent."""
    j = np.minimum(np.searchsorted(sorted_vertices, w), max(len(sorted_vertices) - 1, 0))
    if not len(sorted_vertices):
        return np.full(len(w), -1, np.int64)
    return np.where(sorted_vertices[j] == w, j, -1)


def _climb(S, f, starts, up):
    """The vertex where steepest ascent (``up``) or descent from each of ``starts`` stops (the
    compiled loop ``climb`` of ``o3dheat.topology._loops``)."""
    ptr, adj = S.adjacency
    starts = np.ascontiguousarray(starts, dtype=np.int64)
    if not len(starts):
        return starts
    return _loops.kernel("climb")(np.ascontiguousarray(f), ptr, adj, starts, up)


def _match(V, keep, old, new, radius):
    """Minimum-cost matching of the saddles ``old[keep]`` to ``new`` by distance, within ``radius``:
    (positions in ``old``, positions in ``new``), in the order of ``keep``."""
    none = np.zeros(0, np.int64)
    if not len(keep) or not len(new):
        return none, none
    if V is None:  # no positions: a saddle continues only on its own vertex
        order = np.argsort(new)
        at = np.minimum(np.searchsorted(new, old[keep], sorter=order), len(new) - 1)
        same = new[order[at]] == old[keep]
        return keep[same], order[at[same]].astype(np.int64)
    # imported here: scipy.optimize costs 0.2 s to import, which `import o3dheat` does not pay
    from scipy.optimize import linear_sum_assignment

    A, B = V[old[keep]], V[new]
    D = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2)
    big = 1e6 * (radius + D.max())
    rows, cols = linear_sum_assignment(np.where(D <= radius, D, big))
    ok = D[rows, cols] <= radius
    return keep[rows[ok]], cols[ok].astype(np.int64)


def _events(i, ended, born, ids, new_ids, cur, nxt, saddle_map, partner, V, radius):
    """The events between scales i and i + 1 (see the module docstring). ``ended`` and ``born``
    list ``(kind, position)`` in ``cur`` and ``nxt``; ``saddle_map`` the continuing saddles."""
    out = []
    sad_end = [a for k, a in ended if k == "saddle"]
    sad_vertex = cur.v["saddle"]
    for k, a in ended:
        if k == "saddle":
            continue
        tid = int(ids[k][a])
        s = partner.get(int(cur.v[k][a]))
        hit = [j for j, x in enumerate(sad_end) if s is not None and sad_vertex[x] == s][:1]
        if hit or sad_end:
            x = sad_end.pop(hit[0] if hit else 0)
            out.append({"kind": "cancel", "scale": i, "tracks": [tid, int(ids["saddle"][x])]})
        else:
            out.append({"kind": "death", "scale": i, "tracks": [tid]})
    sad_born = [b for k, b in born if k == "saddle"]
    for k, b in born:
        if k == "saddle":
            continue
        tid = int(new_ids[k][b])
        if sad_born:
            out.append({"kind": "creation", "scale": i, "tracks": [tid, int(new_ids["saddle"][sad_born.pop(0)])]})
        else:
            out.append({"kind": "birth", "scale": i, "tracks": [tid]})
    a, b = saddle_map  # continuing saddles, in the order of the matching
    before, after = cur.m["saddle"][a], nxt.m["saddle"][b]
    for kind, lst in (("split", sad_born), ("merge", sad_end)):
        changed = np.flatnonzero(after < before if kind == "split" else after > before)
        for x in lst:
            tid = int(new_ids["saddle"][x] if kind == "split" else ids["saddle"][x])
            near = None
            if V is not None:
                here = V[(nxt if kind == "split" else cur).v["saddle"][x]]
                near = next((int(ids["saddle"][a[c]]) for c in changed
                             if np.linalg.norm(V[nxt.v["saddle"][b[c]]] - here) <= radius), None)
            if near is None:
                out.append({"kind": "birth" if kind == "split" else "death", "scale": i, "tracks": [tid]})
            else:
                out.append({"kind": kind, "scale": i, "tracks": [tid, near]})
    return out
