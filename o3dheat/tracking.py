"""Critical points across scales: which critical point of Φ_t f at one scale is which at the next
(entry point: :func:`track_critical_points`, returning :class:`Tracks`).

The paper's scale spaces (§3): as t grows, critical points of the smoothed field disappear in
pairs, an extremum with a saddle. Tracking follows each one from scale to scale and records when
it ends and why.

**Matching rule** (between consecutive scales ``i`` and ``i + 1``):

* *Extrema follow the gradient flow.* A maximum ``v`` of ``F[:, i]`` goes to the maximum of
  ``F[:, i + 1]`` reached by steepest ascent from ``v`` (each vertex to its highest neighbour in
  the order of values, ties by vertex index as everywhere in :mod:`o3dheat.topology`); minima by
  steepest descent. When several reach the same one, the most persistent at scale ``i`` continues
  (then the higher, for maxima; the lower, for minima) and the others end. An ascent that ends on
  a vertex that is not a maximum (a boundary vertex above its neighbours is regular) ends the
  track.
* *Saddles* have no flow to follow: those paired (persistence, scale ``i``) with an extremum that
  ends are taken to end with it; the others are matched to the saddles of scale ``i + 1`` by a
  minimum-cost assignment of Euclidean distances, pairs farther apart than ``radius`` left
  unmatched.
* *Events* between ``i`` and ``i + 1``: ``"cancel"`` (an extremum track and a saddle track end
  together, the saddle its persistence partner when possible), ``"creation"`` (tracks that begin
  together: an extremum and a saddle, rare and numerical for the heat flow), ``"split"`` /
  ``"merge"`` (a saddle of multiplicity ``k`` becomes ``k`` saddles or the reverse: a track begins
  or ends next to a continuing saddle whose multiplicity changed), and ``"death"`` / ``"birth"``
  for what nothing else explains.

Every critical vertex at every scale lies on exactly one living track, so the living tracks of a
scale are its critical points and ``M − s + m = χ`` holds at every scale (saddles with their
multiplicity). Limits: a fast-moving saddle (coarse scales, ``radius`` too small) is recorded as a
death and a birth rather than a move; a matching is only as good as the grid of scales is fine.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import checks
from .errors import MeshError
from .topology import Surface, critical_points, persistence

__all__ = ["Tracks", "track_critical_points", "KINDS"]

#: track kinds, in the order of their codes in :attr:`Tracks.kind_code`
KINDS = ("minimum", "saddle", "maximum")


@dataclass
class Tracks:
    """Critical points followed across scales (see the module docstring for the rule).

    Attributes
    ----------
    kind : (p,) object ndarray
        "minimum", "saddle" or "maximum" per track.
    vertex : (p, T) int64 ndarray
        The track's vertex at each scale, -1 where it does not live.
    persistence : (p, T) float64 ndarray
        Its persistence at each scale (``inf`` for an essential critical point, NaN where it does
        not live).
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
    """

    kind: np.ndarray
    vertex: np.ndarray
    persistence: np.ndarray
    multiplicity: np.ndarray
    times: np.ndarray
    events: list = field(default_factory=list)
    positions_of: np.ndarray | None = None

    def __len__(self):
        return len(self.kind)

    @property
    def first(self):
        """(p,) int64: the first scale index each track lives at.

        Examples
        --------
        See :class:`Tracks`.
        """
        return np.argmax(self.vertex >= 0, axis=1)

    @property
    def last(self):
        """(p,) int64: the last scale index each track lives at.

        Examples
        --------
        See :class:`Tracks`.
        """
        T = self.vertex.shape[1]
        return T - 1 - np.argmax(self.vertex[:, ::-1] >= 0, axis=1)

    @property
    def lifetime(self):
        """(p,) float64: ``times[last] − times[first]`` (``inf`` for tracks alive at the last scale).

        Examples
        --------
        See :class:`Tracks`.
        """
        out = self.times[self.last] - self.times[self.first]
        return np.where(self.last == len(self.times) - 1, np.inf, out)

    @property
    def positions(self):
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

    def features(self, scale=-1):
        """The critical vertices of the first field whose tracks live to ``scale`` (an index into
        :attr:`times`, default the last): the lifetime criterion of feature-driven approximation
        (beside δ-persistence), A for :func:`o3dheat.feature_driven`.

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
        scale = range(len(self.times))[scale]
        keep = (self.first == 0) & (self.last >= scale)
        return np.unique(self.vertex[keep, 0])

    def euler_characteristic(self, scale):
        """``M − s + m`` of the living tracks at ``scale`` (saddles with their multiplicity).

        Examples
        --------
        See :class:`Tracks`.
        """
        alive = self.vertex[:, scale] >= 0
        sign = np.where(self.kind == "saddle", -1, 1)
        return int(np.sum((sign * self.multiplicity[:, scale])[alive]))

    def __repr__(self):
        counts = {k: int(np.sum(self.kind == k)) for k in KINDS}
        return (f"Tracks({len(self)} tracks: {counts['minimum']} minima, {counts['saddle']} saddles, "
                f"{counts['maximum']} maxima; {len(self.times)} scales; {len(self.events)} events)")


def track_critical_points(mesh, F, t, radius=None):
    """Follow the critical points of fields at increasing times across the scales.

    Parameters
    ----------
    mesh : mesh-like or :class:`o3dheat.topology.Surface`
        A 2-manifold triangle mesh (see :func:`o3dheat.critical_points`).
    F : (n, T) array_like
        One field per scale, e.g. ``heat_flow(mesh, f, t)`` or ``HeatKernel(s).smooth(f, t)``.
    t : (T,) array_like
        Strictly increasing times (any unit: only their order and differences are used).
    radius : float, optional
        Largest distance (mesh units) a saddle moves between two scales; default 10 mean edge
        lengths.

    Returns
    -------
    Tracks

    Raises
    ------
    MeshError
        ``F`` not of shape (n, T) for T times, NaN, times not increasing, a bad mesh.

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
    elif not (np.isfinite(radius) and radius > 0):
        raise MeshError(f"radius must be a positive number, got {radius!r}")
    T = len(times)
    scales, pairs = zip(*[_scale(S, Fa[:, i]) for i in range(T)], strict=True)
    rows = []  # per track: [kind, {scale: (vertex, persistence, multiplicity)}]
    live = {}  # (kind, vertex) at the current scale -> track id
    events = []
    for (kind, v), (p, mult) in scales[0].items():
        live[(kind, v)] = len(rows)
        rows.append([kind, {0: (v, p, mult)}])
    for i in range(T - 1):
        cur, nxt = scales[i], scales[i + 1]
        f_next = Fa[:, i + 1]
        mapping = {}
        ended = []
        for kind, up in (("maximum", True), ("minimum", False)):
            heads = [v for (k, v) in cur if k == kind]
            if not heads:
                continue
            ends = _flow_ends(S, f_next, np.array(heads), up)
            claims = {}
            for v, w in zip(heads, ends, strict=True):
                if (kind, int(w)) in nxt:
                    claims.setdefault(int(w), []).append(v)
                else:
                    ended.append((kind, v))
            f_now = Fa[:, i]
            for w, vs in claims.items():
                sign = 1.0 if up else -1.0
                best = max(vs, key=lambda v: (cur[(kind, v)][0], sign * f_now[v], -v))
                mapping[(kind, best)] = (kind, w)
                ended += [(kind, v) for v in vs if v != best]
        # saddles: those paired with an ending extremum end; the rest are matched by distance
        partner = pairs[i]
        ending_saddles = {partner[e[1]] for e in ended if e[1] in partner}
        old = [v for (k, v) in cur if k == "saddle" and v not in ending_saddles]
        new = [v for (k, v) in nxt if k == "saddle"]
        matched_old, matched_new = _match(V, old, new, radius)
        for a, b in zip(matched_old, matched_new, strict=True):
            mapping[("saddle", a)] = ("saddle", b)
        ended += [("saddle", v) for (k, v) in cur if k == "saddle" and ("saddle", v) not in mapping]
        new_live = {}
        for key, nkey in mapping.items():
            tid = live[key]
            p, mult = nxt[nkey]
            rows[tid][1][i + 1] = (nkey[1], p, mult)
            new_live[nkey] = tid
        born = [key for key in nxt if key not in new_live]
        for key in born:
            p, mult = nxt[key]
            new_live[key] = len(rows)
            rows.append([key[0], {i + 1: (key[1], p, mult)}])
        events += _events(i, ended, born, live, new_live, cur, nxt, partner, V, radius)
        live = new_live
    p = len(rows)
    vertex = np.full((p, T), -1, np.int64)
    pers = np.full((p, T), np.nan)
    mult = np.zeros((p, T), np.int64)
    for tid, (_, life) in enumerate(rows):
        for j, (v, pe, m) in life.items():
            vertex[tid, j], pers[tid, j], mult[tid, j] = v, pe, m
    kind = np.array([r[0] for r in rows], dtype=object)
    return Tracks(kind, vertex, pers, mult, times, events, V)


def _scale(S, f):
    """``{(kind, vertex): (persistence, multiplicity)}`` of one field, and ``{extremum: saddle}``
    (persistence partners)."""
    cp = critical_points(S, f)
    dg = persistence(S, f)
    pers = {}
    for (a, b), q in zip(dg.pairs.tolist(), dg.persistence.tolist(), strict=True):
        pers[a] = max(pers.get(a, 0.0), q)
        pers[b] = max(pers.get(b, 0.0), q)
    out = {}
    for kind, vs in (("minimum", cp.minima), ("maximum", cp.maxima)):
        for v in vs.tolist():
            out[(kind, v)] = (pers.get(v, np.inf), 1)
    for v, m in zip(cp.saddles.tolist(), cp.saddle_multiplicity.tolist(), strict=True):
        out[("saddle", v)] = (pers.get(v, np.inf), int(m))
    return out, {int(a): int(b) for a, b in dg.pairs.tolist()}


def _flow_ends(S, f, starts, up):
    """Where steepest ascent (``up``) or descent from each start vertex stops, in the order of
    ``(f, vertex index)`` (pointer doubling over every vertex's steepest neighbour)."""
    ptr, adj = S.adjacency
    n = len(f)
    order = np.lexsort((np.arange(n), f))  # ascending (f, index)
    rank = np.empty(n, np.int64)
    rank[order] = np.arange(n)
    r = rank if up else -rank
    nb = r[adj]
    deg = np.diff(ptr)
    best = np.full(n, np.iinfo(np.int64).min)
    has = deg > 0
    best[has] = np.maximum.reduceat(nb, ptr[:-1][has])
    step = np.arange(n)
    better = has & (best > r)
    target = best[better] if up else -best[better]
    step[better] = order[target]
    ends = step[starts]
    for _ in range(64):  # doubling: at most log2(n) rounds
        nxt = step[ends]
        if np.array_equal(nxt, ends):
            break
        ends = nxt
        step = step[step]
    return ends


def _match(V, old, new, radius):
    """Minimum-cost matching of saddles by distance, within ``radius``."""
    if not old or not new or V is None:
        return [], []
    from scipy.optimize import linear_sum_assignment

    A, B = V[np.array(old)], V[np.array(new)]
    D = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2)
    big = 1e6 * (radius + D.max())
    rows, cols = linear_sum_assignment(np.where(D <= radius, D, big))
    keep = D[rows, cols] <= radius
    return [old[i] for i in rows[keep]], [new[j] for j in cols[keep]]


def _events(i, ended, born, live, new_live, cur, nxt, partner, V, radius):
    """The events between scales i and i + 1 (see the module docstring)."""
    out = []
    ext_end = [e for e in ended if e[0] != "saddle"]
    sad_end = [e for e in ended if e[0] == "saddle"]
    for e in ext_end:
        s = partner.get(e[1])
        pick = ("saddle", s) if s is not None and ("saddle", s) in sad_end else (sad_end[0] if sad_end else None)
        if pick is None:
            out.append({"kind": "death", "scale": i, "tracks": [live[e]]})
        else:
            sad_end.remove(pick)
            out.append({"kind": "cancel", "scale": i, "tracks": [live[e], live[pick]]})
    ext_born = [b for b in born if b[0] != "saddle"]
    sad_born = [b for b in born if b[0] == "saddle"]
    for b in ext_born:
        if sad_born:
            out.append({"kind": "creation", "scale": i, "tracks": [new_live[b], new_live[sad_born.pop(0)]]})
        else:
            out.append({"kind": "birth", "scale": i, "tracks": [new_live[b]]})
    grew = {key for key, tid in new_live.items() if key[0] == "saddle" and key in nxt}
    for kind, lst in (("split", sad_born), ("merge", sad_end)):
        for s in lst:
            near = _near_multiplicity_change(s, kind, live, new_live, cur, nxt, V, radius, grew)
            tid = new_live[s] if kind == "split" else live[s]
            if near is None:
                out.append({"kind": "birth" if kind == "split" else "death", "scale": i, "tracks": [tid]})
            else:
                out.append({"kind": kind, "scale": i, "tracks": [tid, near]})
    return out


def _near_multiplicity_change(s, kind, live, new_live, cur, nxt, V, radius, grew):
    """A continuing saddle track within ``radius`` of ``s`` whose multiplicity went down (split)
    or up (merge), or None."""
    if V is None:
        return None
    inverse = {tid: key for key, tid in live.items()}
    for nkey, tid in new_live.items():
        if nkey[0] != "saddle" or tid not in inverse or inverse[tid][0] != "saddle":
            continue
        before, after = cur[inverse[tid]][1], nxt[nkey][1]
        changed = after < before if kind == "split" else after > before
        if changed and np.linalg.norm(V[nkey[1]] - V[s[1]]) <= radius:
            return tid
    return None
