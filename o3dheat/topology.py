"""Topology of piecewise-linear scalar fields on triangle meshes (§3.1, §3.3 of the paper).

A per-vertex field ``f`` is extended linearly over the triangles. Everything here is
combinatorial: it depends on the order of the values, not on the geometry.

Conventions (each one is tested):

* **Simulation of simplicity.** Vertices are ordered by ``(f, vertex index)``: of two equal
  values, the vertex with the smaller index counts as lower. Every field then behaves as a
  generic (Morse) one, so the Morse count ``M − Σ multiplicity + m`` equals the Euler
  characteristic of the mesh for every input, plateaus and constant fields included. A constant
  field is accepted (with a logged warning): its critical points are those of the vertex order.
* **Banchoff's classification by the lower link.** The lower link of a vertex is the part of its
  link (the cycle of neighbours, a path on the boundary) spanned by lower vertices. Empty: a
  minimum. The whole cycle of an interior vertex: a maximum. ``k >= 2`` arcs: a saddle of
  multiplicity ``k − 1`` (``k = 3``: a monkey saddle). Otherwise (one arc): regular.
* **Boundary vertices** follow the same rule with a path as link. So a boundary vertex is a
  minimum when all its neighbours are higher, a saddle when its lower neighbours form ``k >= 2``
  runs along the path, and regular otherwise, *including when all its neighbours are lower*: a
  boundary maximum does not change the topology of the sublevel sets, and the index
  ``1 − χ(lower link)`` is 0 there. This is the rule that makes ``M − s + m = χ`` hold on
  surfaces with boundary (a disk: χ = 1).
* **The mesh** must be a 2-manifold, possibly with boundary and several components: every edge
  in at most two faces and every vertex with one fan of faces (:class:`~o3dheat.MeshError`
  otherwise, with advice). Faces repeating a vertex and duplicate faces are dropped with a
  warning; vertices referenced by no face are not part of the surface and never critical.
* **Duplicate vertices** (referenced, exactly equal coordinates: STL files, triangle soups) are
  welded as for the FEM (:func:`o3dheat.mesh.prepare`) when the mesh comes with coordinates
  (not by :meth:`Surface.from_faces`): the faces use the first copy of each vertex, so results
  are those of the welded mesh. Vertex indices (critical points, pairs) name that first copy; a
  field is averaged over the copies of each vertex; per-vertex outputs
  (:attr:`CriticalPoints.kind`) give every copy the value of its welded vertex.

Persistence pairs the critical points of the lower-star filtration (Edelsbrunner, Letscher and
Zomorodian 2002). Dimension 0 pairs a minimum with the saddle that merges its sublevel component
into an older one (elder rule). Dimension 1 pairs a maximum with the saddle that merges its
superlevel component into an older one; on a closed surface these are exactly the 1-dimensional
pairs (saddle, maximum) of the sublevel filtration (Morse duality). On a surface with boundary
the superlevel sets are taken relative to the boundary (the boundary is coned to one point above
every value), which keeps the same identity with the sublevel 1-dimensional pairs. Both sweeps
are union–find over edges sorted by their higher vertex, O(m log m); vertices that cannot merge
components are contracted first by vectorised pointer jumping, so the Python loop only visits
saddles.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from . import checks
from .errors import MeshError
from .mesh import _degenerate, _unique_rows, _weld_map, as_arrays

__all__ = ["CriticalPoints", "PersistenceDiagram", "critical_points", "persistence",
           "simplify_critical_points", "level_sets", "Surface"]

log = logging.getLogger("o3dheat")

REGULAR, MINIMUM, SADDLE, MAXIMUM = 0, 1, 2, 3


# --------------------------------------------------------------------------------- the surface
class Surface:
    """The combinatorial surface of a mesh: faces, edges, boundary, checked to be a 2-manifold.

    Build it once and pass it instead of the mesh to analyse many fields on one mesh.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        The triangle mesh (a Surface is returned as is by :meth:`of`).
    weld : bool
        Weld referenced vertices with exactly equal coordinates first (the default, logged as a
        warning; see the module docstring).

    Attributes
    ----------
    n : int
        Number of vertices of the mesh (including unreferenced ones).
    F : (m, 3) int64 ndarray
        The faces used (degenerate and duplicate faces dropped).
    E : (e, 2) int64 ndarray
        Unique edges, ``E[:, 0] < E[:, 1]``.
    boundary_edge : (e,) bool ndarray
    face_edges : (m, 3) int64 ndarray
        Edge index of the edge ``(F[t, s], F[t, s + 1])`` of each face.
    used, boundary : (n,) bool ndarray
        Vertices referenced by a face; vertices on the boundary.
    degree : (n,) int64 ndarray
        Number of neighbours.
    euler_characteristic : int
        ``V − E + F`` of the referenced part.
    representative : (n,) int64 ndarray or None
        After welding, the vertex standing for each vertex (its first copy; itself when it is not
        a duplicate); None when nothing was welded.

    Raises
    ------
    MeshError
        When an edge has more than two faces or a vertex more than one fan of faces.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> s = o3dheat.topology.Surface(o3d.t.geometry.TriangleMesh.create_torus())
    >>> s.euler_characteristic, int(s.boundary.sum())
    (0, 0)
    """

    def __init__(self, mesh, weld=True):
        V, F = as_arrays(mesh)
        self.V = V
        self.representative = None
        if weld:
            rep = _weld_map(V, F)
            welded = int(np.sum(rep != np.arange(len(V))))
            if welded:
                log.warning("welded %d duplicate vertices (exactly coincident coordinates): the faces "
                            "use the first copy of each vertex", welded)
                self.representative, F = rep, rep[F]
        self._build(len(V), F)

    @classmethod
    def of(cls, mesh):
        """``mesh`` itself when it is a Surface, otherwise ``Surface(mesh)``."""
        return mesh if isinstance(mesh, cls) else cls(mesh)

    @classmethod
    def from_faces(cls, n, F, V=None):
        """A Surface from a vertex count and faces (no coordinates needed; no welding)."""
        self = cls.__new__(cls)
        self.V = V
        self.representative = None
        F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
        if len(F) == 0:
            raise MeshError("the mesh has no faces")
        if F.min() < 0 or F.max() >= n:
            raise MeshError(f"face indices out of range [0, {n - 1}]")
        self._build(int(n), F)
        return self

    def _build(self, n, F):
        bad = _degenerate(F)
        if bad.any():
            log.warning("dropping %d degenerate faces (a vertex index repeated)", int(bad.sum()))
            F = F[~bad]
        if len(F) == 0:
            raise MeshError("no face is left once the degenerate ones are dropped")
        edges = _edge_table(F, n)
        if np.any(edges[3] > 2):  # duplicate faces are one cause: drop them, then look again
            _, first = _unique_rows(np.sort(F, axis=1), return_index=True)
            if len(first) < len(F):
                log.warning("dropping %d duplicate faces", len(F) - len(first))
                F = F[np.sort(first)]
                edges = _edge_table(F, n)
        ek, order, new, counts, face_edges = edges
        if np.any(counts > 2):
            raise MeshError(f"{int(np.sum(counts > 2))} edges have more than two faces (non-manifold): "
                            "topology needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) "
                            "(or `o3dheat repair IN OUT`), which splits such edges")
        m = len(F)
        a = F.reshape(-1)
        self.n = n
        self.F = F
        self.E = np.stack([ek // n, ek % n], axis=1)
        self.boundary_edge = counts == 1
        self.face_edges = face_edges.reshape(m, 3)
        self.used = np.zeros(n, bool)
        self.used[a] = True
        self.degree = np.bincount(self.E.reshape(-1), minlength=n)
        bE = self.E[self.boundary_edge]
        self.boundary = np.zeros(n, bool)
        self.boundary[bE.reshape(-1)] = True
        self.euler_characteristic = int(self.used.sum() - len(self.E) + m)
        self._check_fans(a, order, new)

    def _check_fans(self, a, order, new):
        """Every vertex must have one fan: the corners around it connected across shared edges."""
        m3 = len(a)
        itype = np.int32 if m3 < 2**31 - 1 else np.int64
        c = np.arange(m3, dtype=itype).reshape(-1, 3)
        nxt = c[:, [1, 2, 0]].reshape(-1)  # the corner where half-edge h ends
        prev = c[:, [2, 0, 1]].reshape(-1)  # the half-edge that ends at corner h
        twin_pos = np.flatnonzero(~new[1:])  # sorted positions p, p + 1 hold the two half-edges
        h1, h2 = order[twin_pos], order[twin_pos + 1]
        # corner h (at vertex a[h]) is joined to the corner at the same vertex in the face across
        # half-edge h, and in the face across half-edge prev(h): one array per side
        across = c.reshape(-1).copy()
        across_end = nxt.copy()
        same = a[h1] == a[h2]  # the two faces orient the edge alike (inconsistent orientation)
        across[h1] = np.where(same, h2, nxt[h2])
        across_end[h1] = np.where(same, nxt[h2], h2)
        across[h2] = np.where(same, h1, nxt[h1])
        across_end[h2] = np.where(same, nxt[h1], h1)
        ind = np.empty(2 * m3, itype)
        ind[0::2] = across
        ind[1::2] = across_end[prev]
        g = sp.csr_matrix((np.ones(2 * m3, np.int8), ind, np.arange(0, 2 * m3 + 1, 2, dtype=itype)),
                          shape=(m3, m3))
        # the corner graph is symmetric: its strong components are its components, found
        # without the transpose an undirected search would build
        k, lab = connected_components(g, directed=True, connection="strong")
        if k == self.used.sum():
            return
        vert_of = np.empty(k, np.int64)
        vert_of[lab] = a
        bad = int(np.sum(np.bincount(vert_of, minlength=self.n) > 1))
        raise MeshError(f"{bad} vertices are non-manifold (their faces form several fans): topology "
                        "needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) (or "
                        "`o3dheat repair IN OUT`), which gives each fan its own vertex")

    @property
    def components(self):
        """Number of connected components (of the referenced vertices)."""
        g = sp.coo_matrix((np.ones(len(self.E)), (self.E[:, 0], self.E[:, 1])), shape=(self.n, self.n))
        _, lab = connected_components(g, directed=False)
        return int(len(np.unique(lab[self.used])))

    def field(self, f, name="f"):
        """``f`` as a checked (n,) float64 array (MeshError on a wrong shape or non-finite values)."""
        arr = checks.field(f, self.n, name)
        if arr.ndim == 2 and arr.shape[1] == 1:
            arr = arr[:, 0]
        if arr.ndim != 1:
            raise MeshError(f"{name} must have one value per vertex, shape ({self.n},), got {arr.shape}")
        rep = self.representative
        if rep is not None:  # welded: the mean over the copies of each vertex, on every copy, as
            # the first copy's value plus the mean deviation (exact when the copies agree)
            dev = np.bincount(rep, weights=arr - arr[rep], minlength=self.n)
            arr = arr[rep] + (dev / np.bincount(rep, minlength=self.n).clip(1))[rep]
        return arr


def _edge_table(F, n):
    """Unique edges of the faces by one sort of the half-edges.

    Half-edge ``h = 3 t + s`` goes from ``F[t, s]`` to ``F[t, s + 1]``. Returns the edge keys
    ``lo * n + hi``, the sorting permutation of the half-edges, the "first of its edge" flags in
    sorted order, the number of faces per edge and the edge index of every half-edge.
    """
    a = F.reshape(-1)
    b = F[:, [1, 2, 0]].reshape(-1)
    hkey = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(hkey)
    sk = hkey[order]
    new = np.empty(len(sk), bool)
    new[0] = True
    np.not_equal(sk[1:], sk[:-1], out=new[1:])
    face_edges = np.empty(len(sk), np.int64)
    face_edges[order] = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, len(sk)))
    return sk[starts], order, new, counts, face_edges


def _rank(f):
    """Position of each vertex in the order (f, index): the simulation of simplicity."""
    order = np.argsort(f, kind="stable")
    rank = np.empty(len(f), np.int64)
    rank[order] = np.arange(len(f))
    return rank, order


# ------------------------------------------------------------------------------- classification
@dataclass(frozen=True)
class CriticalPoints:
    """PL critical points of a field (see the module docstring for the rules).

    Attributes
    ----------
    minima, saddles, maxima : int64 ndarray
        Vertex indices, ascending.
    saddle_multiplicity : int64 ndarray
        Same length as ``saddles``: ``k − 1`` for a lower link of ``k`` arcs (monkey saddle: 2).
    n : int
        Number of vertices of the mesh.
    representative : (n,) int64 ndarray or None
        :attr:`Surface.representative` of the mesh (duplicate vertices welded), else None.
    """

    minima: np.ndarray
    saddles: np.ndarray
    saddle_multiplicity: np.ndarray
    maxima: np.ndarray
    n: int
    representative: np.ndarray | None = None

    @property
    def euler_characteristic(self):
        """``M − Σ multiplicity + m``: equals the Euler characteristic of the mesh."""
        return int(len(self.maxima) - self.saddle_multiplicity.sum() + len(self.minima))

    @property
    def counts(self):
        """``(minima, saddles counted with multiplicity, maxima)``."""
        return (len(self.minima), int(self.saddle_multiplicity.sum()), len(self.maxima))

    @property
    def kind(self):
        """(n,) int8 per vertex: 0 regular, 1 minimum, 2 saddle, 3 maximum (the copies of a welded
        duplicate vertex: the kind of their first copy)."""
        out = np.zeros(self.n, np.int8)
        out[self.minima] = MINIMUM
        out[self.saddles] = SADDLE
        out[self.maxima] = MAXIMUM
        return out if self.representative is None else out[self.representative]

    def same_as(self, other):
        """True when both have the same minima, saddles (with multiplicities) and maxima."""
        return (np.array_equal(self.minima, other.minima) and np.array_equal(self.maxima, other.maxima)
                and np.array_equal(self.saddles, other.saddles)
                and np.array_equal(self.saddle_multiplicity, other.saddle_multiplicity))

    def __repr__(self):
        m, s, M = self.counts
        return f"CriticalPoints(minima={m}, saddles={s}, maxima={M}, euler_characteristic={m - s + M})"


def _classify(S, rank):
    """Lower-link counts: (lower neighbours, lower-link edges, multiplicity, minima, maxima masks)."""
    E = S.E
    hi0 = rank[E[:, 0]] > rank[E[:, 1]]
    top = np.where(hi0, E[:, 0], E[:, 1])
    bottom = np.where(hi0, E[:, 1], E[:, 0])
    lv = np.bincount(top, minlength=S.n)  # vertices of the lower link
    rF = rank[S.F]
    ftop = S.F[np.arange(len(S.F)), np.argmax(rF, axis=1)]
    le = np.bincount(ftop, minlength=S.n)  # edges of the lower link: faces whose top is the vertex
    minima = S.used & (lv == 0)
    maxima = S.used & ~S.boundary & (lv == S.degree)
    arcs = lv - le  # χ of the lower link = its number of arcs when it is not the whole cycle
    mult = np.where(minima | maxima, 0, np.maximum(arcs - 1, 0))
    return top, bottom, mult, minima, maxima


def critical_points(mesh, f):
    """PL critical points of a per-vertex field (Banchoff's lower-link classification).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        A 2-manifold triangle mesh, possibly with boundary and several components.
    f : (n,) array_like
        One finite value per vertex.

    Returns
    -------
    CriticalPoints
        ``euler_characteristic`` (``M − Σ multiplicity + m``) equals χ of the mesh for every field.

    Raises
    ------
    MeshError
        Non-manifold mesh, wrong length, NaN or infinite values.

    Notes
    -----
    Equal values are ordered by vertex index (simulation of simplicity). On the boundary a vertex
    whose neighbours are all lower is regular (see the module docstring). O(m) after one sort.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.4, 40, 20)
    >>> mesh = mesh.rotate(o3d.core.Tensor(o3d.geometry.get_rotation_matrix_from_xyz((1.5708, 0, 0))),
    ...                    o3d.core.Tensor([0.0, 0.0, 0.0]))     # axis horizontal: stand it upright
    >>> cp = o3dheat.critical_points(mesh, mesh.vertex.positions.numpy()[:, 2] )  # height
    >>> cp.counts, cp.euler_characteristic
    ((1, 2, 1), 0)
    """
    S = Surface.of(mesh)
    f = S.field(f)
    rank, _ = _rank(f)
    _warn_constant(f, S)
    _, _, mult, minima, maxima = _classify(S, rank)
    saddles = np.flatnonzero(mult > 0)
    return CriticalPoints(np.flatnonzero(minima), saddles, mult[saddles].astype(np.int64),
                          np.flatnonzero(maxima), S.n, S.representative)


def _warn_constant(f, S):
    vals = f[S.used]
    if len(vals) and vals.min() == vals.max():
        log.warning("the field is constant: its critical points only reflect the vertex order")


# ---------------------------------------------------------------------------------- persistence
def _sweep(rank, top, bottom, merge):
    """Elder-rule union–find of the sublevel components of a vertex order.

    ``rank`` (N,) distinct; ``(top, bottom)`` the edges with ``rank[top] > rank[bottom]``;
    ``merge`` (N,) marks the only vertices whose lower neighbours can lie in several components
    (saddles). Returns (creators, destroyers, root) where ``root[v]`` is the oldest vertex of v's
    final component.
    """
    N = len(rank)
    vertex_of_rank = np.empty(N, np.int64)
    vertex_of_rank[rank] = np.arange(N)
    # every other vertex joins the component of its lowest lower neighbour: contract those links
    sel = ~merge[top]
    best = np.full(N, N, np.int64)
    np.minimum.at(best, top[sel], rank[bottom[sel]])
    parent = np.arange(N)
    has = best < N
    parent[has] = vertex_of_rank[best[has]]
    parent = _jump(parent)
    # saddles in increasing order: union-find over the roots of their lower neighbours
    sel = merge[top]
    ts, bs = top[sel], parent[bottom[sel]]
    o = np.argsort(rank[ts], kind="stable")
    ts, bs = ts[o], bs[o]
    starts = np.flatnonzero(np.r_[True, ts[1:] != ts[:-1]]) if len(ts) else np.zeros(0, np.int64)
    ends = np.r_[starts[1:], len(ts)].astype(np.int64)
    uf = list(range(N))
    rk = rank.tolist()
    bl = bs.tolist()
    creators, destroyers = [], []
    for s, i0, i1 in zip(ts[starts].tolist(), starts.tolist(), ends.tolist()):
        roots = set()
        for u in bl[i0:i1]:
            r = u
            while uf[r] != r:
                r = uf[r]
            while uf[u] != r:  # path compression
                uf[u], u = r, uf[u]
            roots.add(r)
        elder = min(roots, key=rk.__getitem__)
        for r in roots:
            if r != elder:
                creators.append(r)
                destroyers.append(s)
                uf[r] = elder
        uf[s] = elder
    root = _jump(np.asarray(uf, dtype=np.int64))[parent]
    return np.asarray(creators, np.int64), np.asarray(destroyers, np.int64), root


def _jump(parent):
    """Pointer jumping to the roots of a forest given by parent pointers (roots point to self)."""
    while True:
        nxt = parent[parent]
        if np.array_equal(nxt, parent):
            return parent
        parent = nxt


@dataclass(frozen=True)
class PersistenceDiagram:
    """Persistence pairs of a PL field on a surface (see the module docstring).

    Attributes
    ----------
    pairs : (p, 2) int64 ndarray
        ``(creator, destroyer)`` vertex indices: (minimum, saddle) in dimension 0 (sublevel sets),
        (maximum, saddle) in dimension 1 (superlevel sets).
    birth, death : (p,) float64 ndarray
        ``f[creator]``, ``f[destroyer]``.
    persistence : (p,) float64 ndarray
        ``|death − birth|`` (0 for pairs made by ties, which the simulation of simplicity keeps).
    dimension : (p,) int8 ndarray
    essential : int64 ndarray
        Critical vertices never paired: the global minimum of each component, its global maximum
        when it is closed, and ``2g + b − 1`` saddles of a component of genus g with b > 0
        boundary curves (``2g`` when closed). A saddle appears as often as its unpaired
        multiplicity.
    essential_dimension : int8 ndarray
        0 for minima, 1 for saddles, 2 for maxima.

    Every critical vertex appears exactly as often (creators, destroyers and essentials together)
    as its multiplicity in :func:`critical_points`. Pairs are sorted by dimension, then by
    decreasing persistence.
    """

    pairs: np.ndarray
    birth: np.ndarray
    death: np.ndarray
    persistence: np.ndarray
    dimension: np.ndarray
    essential: np.ndarray
    essential_dimension: np.ndarray

    def __len__(self):
        return len(self.pairs)

    def intervals(self, dimension):
        """(q, 2) ``(birth, death)`` of the pairs of one dimension (0 or 1)."""
        sel = self.dimension == dimension
        return np.stack([self.birth[sel], self.death[sel]], axis=1)

    def __repr__(self):
        p0 = int(np.sum(self.dimension == 0))
        return (f"PersistenceDiagram(pairs={len(self)} (dim 0: {p0}, dim 1: {len(self) - p0}), "
                f"essential={len(self.essential)})")


def persistence(mesh, f):
    """Persistence pairs of the critical points of a PL field, with the essential ones.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        A 2-manifold triangle mesh, possibly with boundary and several components.
    f : (n,) array_like
        One finite value per vertex.

    Returns
    -------
    PersistenceDiagram

    Notes
    -----
    Dimension 0 equals the 0-dimensional persistence of the lower-star filtration of f, dimension
    1 its 1-dimensional persistence with birth and death exchanged (the pair is read on superlevel
    sets); both are checked against gudhi in the tests. Stable: for ``f + e`` every pair moves by
    at most ``‖e‖∞`` in the bottleneck distance.

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0.]])
    >>> F = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    >>> d = o3dheat.persistence((V, F), [0.0, 2.0, 1.0, 0.5, 3.0, 1.5])   # two valleys, one pass
    >>> d.pairs.tolist(), d.persistence.tolist(), d.essential.tolist()
    ([[2, 1]], [1.0], [0])
    """
    S = Surface.of(mesh)
    f = S.field(f)
    rank, _ = _rank(f)
    _warn_constant(f, S)
    top, bottom, mult, _, _ = _classify(S, rank)
    merge = mult > 0
    n = S.n
    # dimension 0: sublevel components
    c0, d0, root0 = _sweep(rank, top, bottom, merge)
    # dimension 1: superlevel components relative to the boundary: reverse the order and cone the
    # boundary to a vertex (index n) above every value, which is the oldest of the reversed order
    apex = n
    bverts = np.flatnonzero(S.boundary)
    rrank = np.append(n - rank, 0)
    top1 = np.concatenate([bottom, bverts])
    bot1 = np.concatenate([top, np.full(len(bverts), apex)])
    c1, d1, root1 = _sweep(rrank, top1, bot1, np.append(merge, False))
    # essential: component roots (minus the apex), and the saddle multiplicity never used
    ess_min = np.unique(root0[:n][S.used])
    ess_max = np.unique(root1[:n][S.used])
    ess_max = ess_max[ess_max != apex]
    used_mult = np.bincount(np.concatenate([d0, d1]), minlength=n)
    left = mult - used_mult
    if np.any(left < 0):  # pragma: no cover - a bug, not an input problem
        raise AssertionError("persistence used a saddle more often than its multiplicity")
    ess_sad = np.repeat(np.arange(n), left)
    pairs = np.concatenate([np.stack([c0, d0], 1), np.stack([c1, d1], 1)]).reshape(-1, 2)
    dim = np.concatenate([np.zeros(len(c0), np.int8), np.ones(len(c1), np.int8)])
    birth, death = f[pairs[:, 0]], f[pairs[:, 1]]
    pers = np.abs(death - birth)
    o = np.lexsort((pairs[:, 1], pairs[:, 0], -pers, dim))
    essential = np.concatenate([ess_min, ess_sad, ess_max]).astype(np.int64)
    edim = np.concatenate([np.zeros(len(ess_min)), np.ones(len(ess_sad)), np.full(len(ess_max), 2)])
    return PersistenceDiagram(pairs[o], birth[o], death[o], pers[o], dim[o], essential,
                              edim.astype(np.int8))


def simplify_critical_points(mesh, f, delta=None, keep_fraction=None, diagram=None):
    """The δ-simplification of the critical points (§3.3, ref. [33]).

    Keeps the essential critical points and both ends of every persistence pair with
    ``persistence >= delta`` (or of the ``ceil(keep_fraction · p)`` most persistent of the p
    pairs; ties broken by the diagram's order).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
    f : (n,) array_like
    delta : float, optional
        Persistence threshold in the units of f (>= 0). With neither delta nor keep_fraction,
        every critical point is kept (delta = 0).
    keep_fraction : float in [0, 1], optional
        Alternative to delta.
    diagram : PersistenceDiagram, optional
        The diagram of (mesh, f) when already computed.

    Returns
    -------
    int64 ndarray
        Sorted vertex indices. Monotone: a larger delta keeps a subset.

    Examples
    --------
    >>> import numpy as np, o3dheat
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0.]])
    >>> F = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    >>> f = [0.0, 2.0, 1.0, 0.5, 3.0, 1.5]
    >>> o3dheat.simplify_critical_points((V, F), f).tolist()
    [0, 1, 2]
    >>> o3dheat.simplify_critical_points((V, F), f, delta=1.5).tolist()
    [0]
    """
    if delta is not None and keep_fraction is not None:
        raise MeshError("give delta or keep_fraction, not both")
    if delta is not None:
        delta = float(delta)
        if not (np.isfinite(delta) and delta >= 0):
            raise MeshError(f"delta must be a finite number >= 0, got {delta}")
    if keep_fraction is not None:
        keep_fraction = float(keep_fraction)
        if not (0.0 <= keep_fraction <= 1.0):
            raise MeshError(f"keep_fraction must lie in [0, 1], got {keep_fraction}")
    d = persistence(mesh, f) if diagram is None else diagram
    if not isinstance(d, PersistenceDiagram):
        raise MeshError(f"diagram must be a PersistenceDiagram, got {type(d).__name__}")
    if keep_fraction is not None:
        o = np.argsort(-d.persistence, kind="stable")
        sel = o[: int(np.ceil(keep_fraction * len(o)))]
    else:
        sel = np.flatnonzero(d.persistence >= (delta or 0.0))
    return np.unique(np.concatenate([d.essential, d.pairs[sel].reshape(-1)])).astype(np.int64)


# ----------------------------------------------------------------------------------- level sets
def level_sets(mesh, f, values=None, count=None, color=(0.0, 0.0, 0.0)):
    """Level sets of a PL field as line segments (marching triangles), for figures.

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
    f : (n,) array_like
    values : sequence of float, optional
        The iso-values.
    count : int, optional
        Instead of values: ``count`` values evenly spaced strictly inside ``[min f, max f]``.
        Default 10 when neither is given.
    color : 3 floats in [0, 1]
        Colour of every line.

    Returns
    -------
    o3d.geometry.LineSet
        One segment per triangle crossed by each value; points are shared between adjacent
        triangles. A vertex exactly at a value counts as above it, so a level set never
        doubles back along an edge.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> ls = o3dheat.level_sets(mesh, mesh.vertex.positions.numpy()[:, 2], values=[0.0])
    >>> len(ls.lines) > 0
    True
    """
    import open3d as o3d

    S = Surface.of(mesh)
    if S.V is None:
        raise MeshError("level_sets needs vertex coordinates: pass a mesh or (V, F)")
    f = S.field(f)
    vals = f[S.used]
    if values is None:
        count = checks.count(10 if count is None else count, "count", maximum=10_000)
        values = np.linspace(vals.min(), vals.max(), count + 2)[1:-1]
    elif count is not None:
        raise MeshError("give values or count, not both")
    values = np.atleast_1d(np.asarray(values, dtype=np.float64))
    if values.ndim != 1 or not np.all(np.isfinite(values)):
        raise MeshError("values must be a 1-D sequence of finite numbers")
    V, E, FE = S.V, S.E, S.face_edges
    pts, lines, npts = [], [], 0
    for c in values:
        above = f >= c
        cross = above[E[:, 0]] != above[E[:, 1]]
        ce = np.flatnonzero(cross)
        i, j = E[ce, 0], E[ce, 1]
        w = (c - f[i]) / (f[j] - f[i])
        pts.append(V[i] + w[:, None] * (V[j] - V[i]))
        pid = np.full(len(E), -1, np.int64)
        pid[ce] = npts + np.arange(len(ce))
        npts += len(ce)
        cf = cross[FE]
        tri = np.flatnonzero(cf.sum(axis=1) == 2)
        first = np.argmax(cf[tri], axis=1)
        last = 2 - np.argmax(cf[tri][:, ::-1], axis=1)
        lines.append(np.stack([pid[FE[tri, first]], pid[FE[tri, last]]], axis=1))
    P = np.concatenate(pts) if pts else np.zeros((0, 3))
    Lz = np.concatenate(lines) if lines else np.zeros((0, 2), np.int64)
    ls = o3d.geometry.LineSet(o3d.utility.Vector3dVector(P), o3d.utility.Vector2iVector(Lz.astype(np.int32)))
    if len(Lz):
        ls.colors = o3d.utility.Vector3dVector(np.tile(np.asarray(color, dtype=np.float64), (len(Lz), 1)))
    return ls

