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
  welded as for the FEM (:func:`o3dheat.geometry.mesh.prepare`) when the mesh comes with coordinates
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
every value), which keeps the same identity with the sublevel 1-dimensional pairs.

**How it scales.** The loops over vertices, edges and faces are compiled (numba, ``nogil``) and
cached beside this module, so only the first call of an installation compiles them (a few
seconds). :class:`Surface` holds the mesh's tables, vertex adjacency included, built once in O(m)
(a counting sort of the half-edges, a union-find over the corners for the fans). A field then
costs one pass over the adjacency and one over the faces (classification; no sort of the
vertices), a sort of the critical vertices only, and two union-finds: a vertex that is not
critical joins the component of one lower (upper) neighbour, and only the saddles, taken in
order, merge components. O(n + c log c) for c critical vertices. About 0.1 µs per vertex for
persistence of a noisy field at 1M vertices, 0.2 µs to build the Surface; memory: see
:func:`critical_points`, :func:`persistence` and :class:`Surface`. At most 2**31 − 2 vertices
(vertex ids are int32 inside).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from o3dheat import checks
from o3dheat._jit import any_compiled, compiled
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, note_repair
from o3dheat.geometry._tables import degenerate, unique_rows, weld_map

__all__ = ["CriticalPoints", "PersistenceDiagram", "critical_points", "persistence", "REGULAR", "MINIMUM", "SADDLE", "MAXIMUM",
           "simplify_critical_points", "level_sets", "Surface", "warm_up", "compiled_in_this_process"]

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
        Unique edges, ``E[:, 0] < E[:, 1]``, in lexicographic order.
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
        When an edge has more than two faces or a vertex more than one fan of faces, or for more
        than 2**31 − 2 vertices or 715,827,882 faces.

    Notes
    -----
    Built in O(m) by compiled loops (see the module docstring): about 0.2 s from the faces at 1M
    vertices (checking the coordinates for duplicates comes on top when a mesh is given). It holds
    about 190 bytes per vertex of a closed mesh (faces, edges, the edges of each face, vertex
    adjacency, ...); its construction peaks at about 220 bytes per vertex from the faces, 300
    from ``(V, F)`` (copies of the input and the welding check), beyond the input.

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
        given = (V, F)  # what repairs are noted against (once per mesh, with prepare's: note_repair)
        if weld:
            rep = weld_map(V, F)
            welded = int(np.sum(rep != np.arange(len(V))))
            if welded:
                note_repair(given, "weld", "welded %d duplicate vertices (exactly coincident coordinates): the "
                            "faces use the first copy of each vertex", welded)
                self.representative, F = rep, rep[F]
        self._build(len(V), F, given)

    @classmethod
    def of(cls, mesh):
        """``mesh`` itself when it is a Surface, otherwise ``Surface(mesh)``.

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.topology import Surface
        >>> s = Surface.of(o3d.t.geometry.TriangleMesh.create_torus())
        >>> Surface.of(s) is s, s.components
        (True, 1)
        """
        return mesh if isinstance(mesh, cls) else cls(mesh)

    @classmethod
    def from_faces(cls, n, F, V=None):
        """A Surface from a vertex count and faces (no coordinates needed; no welding).

        Examples
        --------
        Two triangles sharing an edge, and a vertex no face uses:

        >>> from o3dheat.topology import Surface
        >>> s = Surface.from_faces(5, [[0, 1, 2], [0, 2, 3]])
        >>> s.euler_characteristic, s.used.tolist(), int(s.boundary_edge.sum())
        (1, [True, True, True, True, False], 4)
        """
        self = cls.__new__(cls)
        self.V = V
        self.representative = None
        F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
        if len(F) == 0:
            raise MeshError("the mesh has no faces")
        if F.min() < 0 or F.max() >= n:
            raise MeshError(f"face indices out of range [0, {n - 1}]")
        self._build(int(n), F, (F,))
        return self

    def _build(self, n, F, given):
        if n >= 2**31 - 1:
            raise MeshError(f"{n} vertices: topology handles at most 2**31 - 2 vertices")
        bad = degenerate(F)
        if bad.any():
            note_repair(given, "degenerate", "dropping %d degenerate faces (a vertex index repeated)", int(bad.sum()))
            F = F[~bad]
        if len(F) == 0:
            raise MeshError("no face is left once the degenerate ones are dropped")
        if 3 * len(F) >= 2**31:
            raise MeshError(f"{len(F)} faces: topology handles at most {(2**31 - 1) // 3} faces")
        F = np.ascontiguousarray(F, dtype=np.int64)
        edges = _kernel("_k_edges")(F, n)
        if np.any(edges[1] > 2):  # duplicate faces are one cause: drop them, then look again
            _, first = unique_rows(np.sort(F, axis=1), return_index=True)
            if len(first) < len(F):
                note_repair(given, "duplicate", "dropping %d duplicate faces", len(F) - len(first))
                F = np.ascontiguousarray(F[np.sort(first)])
                edges = _kernel("_k_edges")(F, n)
        E, counts, face_edges, he, first, ptr, adj = edges
        if np.any(counts > 2):
            raise MeshError(f"{int(np.sum(counts > 2))} edges have more than two faces (non-manifold): "
                            "topology needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) "
                            "(or `o3dheat repair IN OUT`), which splits such edges")
        m = len(F)
        self.n = n
        self.F = F
        self.E = E
        self.boundary_edge = counts == 1
        self.face_edges = face_edges.reshape(m, 3)
        self.degree = np.diff(ptr)
        self.used = self.degree > 0
        self.boundary = np.zeros(n, bool)
        self.boundary[E[self.boundary_edge].reshape(-1)] = True
        self.euler_characteristic = int(self.used.sum() - len(E) + m)
        self._ptr, self._adj = ptr, adj  # the neighbours of vertex v: adj[ptr[v]:ptr[v + 1]]
        self._all_used = bool(self.used.all())
        bad = _kernel("_k_fans")(F, E, counts, he, first, n)
        if bad:
            raise MeshError(f"{bad} vertices are non-manifold (their faces form several fans): topology "
                            "needs a 2-manifold: repair the mesh first with o3dheat.repair(mesh) (or "
                            "`o3dheat repair IN OUT`), which gives each fan its own vertex")

    @property
    def adjacency(self):
        """``(ptr, adj)``: the neighbours of vertex ``v`` are ``adj[ptr[v]:ptr[v + 1]]`` (CSR).

        Examples
        --------
        >>> import open3d as o3d
        >>> from o3dheat.topology import Surface
        >>> ptr, adj = Surface(o3d.t.geometry.TriangleMesh.create_torus()).adjacency
        >>> int(ptr[1] - ptr[0])
        6
        """
        return self._ptr, self._adj

    @property
    def components(self):
        """Number of connected components (of the referenced vertices)."""
        g = sp.coo_matrix((np.ones(len(self.E)), (self.E[:, 0], self.E[:, 1])), shape=(self.n, self.n))
        _, lab = connected_components(g, directed=False)
        return int(len(np.unique(lab[self.used])))

    def field(self, f, name="f"):
        """``f`` as a checked (n,) float64 array (MeshError on a wrong shape or non-finite values).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> from o3dheat.topology import Surface
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> s = Surface(m)
        >>> s.field(m.vertex.positions[:, 0]).dtype           # an Open3D tensor is read too
        dtype('float64')
        >>> s.field([1.0, 2.0])
        Traceback (most recent call last):
        ...
        o3dheat.errors.MeshError: f must have shape (600,) or (600, c) (one value per vertex), got (2,)
        """
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


# -------------------------------------------------------------------------------- compiled loops
# The loops below are plain Python functions compiled on first use (:func:`o3dheat._jit.compiled`:
# numba, imported only then, cached once per installation). Vertex ids are int32 inside, indices
# of faces and edges int64.


def _kernel(name):
    """The compiled version of the module function ``name``."""
    return compiled(globals()[name])


def warm_up():
    """Load this module's compiled loops now (or compile them: the first call of an installation,
    or after a change of the source), by finding the critical points and persistence of a small
    field, so that the first real call does not pay it: about 0.3 s per process from the cache.
    Each Dask worker of o3dheat's studies and batches calls it at start
    (:func:`o3dheat.pipelines.cluster.register_warm_up`), like pymeshlab's first call.

    Examples
    --------
    >>> import o3dheat.topology as T
    >>> T.warm_up()
    """
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_sphere(1.0, 6)
    V, F = np.asarray(m.vertices), np.asarray(m.triangles, dtype=np.int64)
    S = Surface.from_faces(len(V), F, V)
    f = V[:, 2] + 0.1 * V[:, 0]
    critical_points(S, f)
    persistence(S, f)


def compiled_in_this_process():
    """Whether this process compiled any of the topology's loops (a first call of an installation,
    or after a change of the source: a few seconds once) rather than loading them from the cache.

    Examples
    --------
    >>> import o3dheat.topology as T
    >>> isinstance(T.compiled_in_this_process(), bool)
    True
    """
    return any_compiled(__name__)


def _k_edges(F, n):
    """Unique edges of the faces in ``(lo, hi)`` order, by a counting sort of the half-edges on
    their lower vertex (then by the higher one inside each bucket, small: a vertex's edges).

    Returns ``E`` (e, 2) int64, faces per edge ``count`` (e,) int32, ``face_edges`` (3m,) int64
    (edge of half-edge ``3 t + s``, from ``F[t, s]`` to ``F[t, s + 1]``), ``he`` (3m,) int32 the
    half-edges in edge order and ``first`` (e,) int32 the position in ``he`` of each edge's first
    one, and the vertex adjacency: ``ptr`` (n + 1,) int64, ``adj`` (2e,) int32.
    """
    m = F.shape[0]

    def sift(hi, he, i0, root, end):  # restore the max-heap hi[i0:i0 + end] below root
        while 2 * root + 1 < end:
            c = 2 * root + 1
            if c + 1 < end and hi[i0 + c + 1] > hi[i0 + c]:
                c += 1
            if hi[i0 + root] >= hi[i0 + c]:
                return
            hi[i0 + root], hi[i0 + c] = hi[i0 + c], hi[i0 + root]
            he[i0 + root], he[i0 + c] = he[i0 + c], he[i0 + root]
            root = c

    start = np.zeros(n + 1, np.int64)
    for t in range(m):
        for s in range(3):
            a, b = F[t, s], F[t, (s + 1) % 3]
            start[min(a, b) + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:n].copy()
    hi = np.empty(3 * m, np.int32)
    he = np.empty(3 * m, np.int32)
    for t in range(m):
        for s in range(3):
            a, b = F[t, s], F[t, (s + 1) % 3]
            lo = min(a, b)
            p = fill[lo]
            fill[lo] = p + 1
            hi[p] = max(a, b)
            he[p] = 3 * t + s
    ne = 0
    for v in range(n):
        i0, i1 = start[v], start[v + 1]
        if i1 - i0 <= 16:  # insertion sort: the usual bucket has about six half-edges
            for i in range(i0 + 1, i1):
                x, y = hi[i], he[i]
                j = i - 1
                while j >= i0 and hi[j] > x:
                    hi[j + 1] = hi[j]
                    he[j + 1] = he[j]
                    j -= 1
                hi[j + 1] = x
                he[j + 1] = y
        else:  # a vertex of high degree: heapsort, O(d log d) (the order of equal hi is free)
            for root in range((i1 - i0) // 2 - 1, -1, -1):
                sift(hi, he, i0, root, i1 - i0)
            for end in range(i1 - i0 - 1, 0, -1):
                hi[i0], hi[i0 + end] = hi[i0 + end], hi[i0]
                he[i0], he[i0 + end] = he[i0 + end], he[i0]
                sift(hi, he, i0, 0, end)
        for i in range(i0, i1):
            if i == i0 or hi[i] != hi[i - 1]:
                ne += 1
    E = np.empty((ne, 2), np.int64)
    count = np.zeros(ne, np.int32)
    first = np.empty(ne, np.int32)
    face_edges = np.empty(3 * m, np.int64)
    deg = np.zeros(n + 1, np.int64)
    k = -1
    for v in range(n):
        for i in range(start[v], start[v + 1]):
            if i == start[v] or hi[i] != hi[i - 1]:
                k += 1
                E[k, 0] = v
                E[k, 1] = hi[i]
                first[k] = i
                deg[v + 1] += 1
                deg[hi[i] + 1] += 1
            count[k] += 1
            face_edges[he[i]] = k
    for v in range(n):
        deg[v + 1] += deg[v]
    ptr = deg
    fill = ptr[:n].copy()
    adj = np.empty(2 * ne, np.int32)
    for k in range(ne):
        a, b = E[k, 0], E[k, 1]
        adj[fill[a]] = b
        fill[a] += 1
        adj[fill[b]] = a
        fill[b] += 1
    return E, count, face_edges, he, first, ptr, adj


def _k_fans(F, E, count, he, first, n):
    """Number of vertices whose faces form more than one fan (0 for a manifold).

    Union–find over the corners (corner ``3 t + s`` is vertex ``F[t, s]`` in face t): across each
    edge with two faces, the corners at each of its ends are joined. A vertex is manifold when its
    corners form one class.
    """
    m = F.shape[0]
    uf = np.arange(3 * m, dtype=np.int32)
    for k in range(E.shape[0]):
        if count[k] != 2:
            continue
        t1, t2 = he[first[k]] // 3, he[first[k] + 1] // 3
        for e in range(2):
            x = E[k, e]
            c1 = 3 * t1 + (0 if F[t1, 0] == x else (1 if F[t1, 1] == x else 2))
            c2 = 3 * t2 + (0 if F[t2, 0] == x else (1 if F[t2, 1] == x else 2))
            while uf[c1] != c1:  # find with path halving
                uf[c1] = uf[uf[c1]]
                c1 = uf[c1]
            while uf[c2] != c2:
                uf[c2] = uf[uf[c2]]
                c2 = uf[c2]
            if c1 != c2:
                uf[max(c1, c2)] = min(c1, c2)
    fans = np.zeros(n, np.int32)
    for c in range(3 * m):
        if uf[c] == c:
            fans[F[c // 3, c % 3]] += 1
    bad = 0
    for v in range(n):
        if fans[v] > 1:
            bad += 1
    return bad


def _k_classify(f, ptr, adj, F, boundary, pointers):
    """Banchoff's classification in the order (f, index).

    Returns ``kind`` (n,) int8 (0 regular or unreferenced, 1 minimum, 2 saddle, 3 maximum),
    ``mult`` (n,) int32 (saddle multiplicity, else 0), ``crit`` the critical vertices (ascending)
    and, when ``pointers``, ``low`` and ``high`` (n,) int32: a lower and an upper neighbour (the
    last listed; -1: none). Written without branches on the values (selects instead), which noisy
    fields would mispredict.
    """
    n = f.shape[0]
    nlow = np.zeros(n, np.int32)
    low = np.full(n if pointers else 0, -1, np.int32)
    high = np.full(n if pointers else 0, -1, np.int32)
    for v in range(n):
        fv = f[v]
        c = 0
        lo, hi = -1, -1
        for k in range(ptr[v], ptr[v + 1]):
            u = adj[k]
            fu = f[u]
            below = (fu < fv) | ((fu == fv) & (u < v))
            c += below
            lo = u if below else lo
            hi = hi if below else u
        nlow[v] = c
        if pointers:
            low[v] = lo
            high[v] = hi
    le = np.zeros(n, np.int32)  # edges of the lower link: the faces whose highest vertex is v
    for t in range(F.shape[0]):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        fa, fb, fc = f[a], f[b], f[c]
        top = a + np.int64((fb > fa) | ((fb == fa) & (b > a))) * (b - a)
        ftop = max(fa, fb)
        le[top + np.int64((fc > ftop) | ((fc == ftop) & (c > top))) * (c - top)] += 1
    kind = np.zeros(n, np.int8)
    mult = np.zeros(n, np.int32)
    nc = 0
    for v in range(n):
        deg = ptr[v + 1] - ptr[v]
        if deg == 0:
            continue
        if nlow[v] == 0:
            kind[v] = 1
        elif nlow[v] == deg and not boundary[v]:
            kind[v] = 3
        elif nlow[v] - le[v] >= 2:  # the lower link has nlow - le arcs
            kind[v] = 2
            mult[v] = nlow[v] - le[v] - 1
        nc += kind[v] != 0
    crit = np.empty(nc, np.int64)
    nc = 0
    for v in range(n):
        if kind[v] != 0:
            crit[nc] = v
            nc += 1
    return kind, mult, crit, low, high


def _k_arcs(f, ptr, adj, boundary, kind, low, high, crit):
    """The saddles' links in the lower and upper forests, as sortable keys.

    ``crit`` lists the critical vertices in increasing (f, index): position ``i`` in it is the
    vertex's *id*, so that of two ids the smaller is the older in the sublevel sweep. A vertex that
    is not critical joins the component of ``low`` (a lower neighbour; its lower link is one arc,
    so all its lower neighbours are connected already), and likewise of ``high`` for superlevel
    sets, where every boundary vertex joins an apex ``n`` above every value (id ``len(crit)``, the
    boundary coned to one point). These links form two forests whose roots are the minima and
    saddles (lower) and the maxima, saddles and apex (upper).

    For each saddle, in vertex order (its neighbours are near it in memory), the roots of its lower
    and upper neighbours are found (with path compression) and listed once each as keys
    ``(saddle id << shift) | root id``: sorted, they give each saddle's roots in sweep order.
    """
    n = f.shape[0]
    nc = crit.shape[0]
    apex = n
    shift = 1
    while (1 << shift) <= nc:
        shift += 1

    def find(uf, u):  # id of the root of u, with path compression
        r = u
        while uf[r] >= 0:
            r = uf[r]
        while u != r:
            w = uf[u]
            uf[u] = r
            u = w
        return -uf[r] - 1

    def push(keys, start, end, key):  # key appended unless keys[start:end] has it: the new end
        for j in range(start, end):
            if keys[j] == key:
                return end
        keys[end] = key
        return end + 1

    uf0 = np.empty(n, np.int32)  # >= 0: the parent vertex; < 0: a root, its id -(uf + 1)
    uf1 = np.empty(n + 1, np.int32)
    cap0, cap1 = 0, 0
    for v in range(n):
        uf0[v] = low[v]
        uf1[v] = apex if boundary[v] else high[v]
        if kind[v] == 2:
            cap0 += ptr[v + 1] - ptr[v]
            cap1 += ptr[v + 1] - ptr[v] + 1
    uf1[apex] = -(nc + 1)
    for i in range(nc):
        v = crit[i]
        if kind[v] != 3:
            uf0[v] = -(i + 1)
        if kind[v] != 1:
            uf1[v] = -(i + 1)
    keys0 = np.empty(cap0, np.int64)
    keys1 = np.empty(cap1, np.int64)
    k0, k1 = 0, 0
    for s in range(n):
        if kind[s] != 2:
            continue
        hi_s = np.int64(-uf0[s] - 1) << shift
        j0, j1 = k0, k1
        fs = f[s]
        for k in range(ptr[s], ptr[s + 1]):
            u = adj[k]
            fu = f[u]
            if (fu < fs) | ((fu == fs) & (u < s)):
                k0 = push(keys0, j0, k0, hi_s | find(uf0, u))
            else:
                k1 = push(keys1, j1, k1, hi_s | find(uf1, u))
        if boundary[s]:
            k1 = push(keys1, j1, k1, hi_s | nc)
    return keys0[:k0], keys1[:k1], shift


def _k_sweeps(keys0, keys1, shift, kind, left):
    """Elder-rule union–find over the critical ids (see :func:`_k_arcs`), from sorted keys.

    Dimension 0 takes the saddles in increasing order; each unions the components of its lower
    roots: the oldest (smallest id) survives, each other is paired with the saddle. Dimension 1
    takes them in decreasing order with the upper roots; the oldest is the largest id (the apex
    oldest of all). Returns the (creator, destroyer) ids of both and the unpaired minima and
    maxima (``kind``: the kind of each id); ``left`` (the multiplicity of each id) drops by one
    for each pair a saddle makes.
    """
    nc = kind.shape[0]
    mask = (np.int64(1) << shift) - 1

    def find(uf, u):
        r = u
        while uf[r] != r:
            r = uf[r]
        while uf[u] != r:
            w = uf[u]
            uf[u] = r
            u = w
        return r

    out = []
    for reverse in (False, True):
        keys = keys1 if reverse else keys0
        nk = keys.shape[0]
        uf = np.arange(nc + 1, dtype=np.int32)
        cre = np.empty(nk, np.int32)
        des = np.empty(nk, np.int32)
        p = 0
        i = 0
        while i < nk:
            ki = keys[nk - 1 - i] if reverse else keys[i]
            s = ki >> shift
            elder = -1
            while True:
                r = find(uf, ki & mask)
                if elder < 0:
                    elder = r
                elif r != elder:
                    young = elder if (r > elder) == reverse else r
                    elder = r + elder - young
                    uf[young] = elder
                    cre[p] = young
                    des[p] = s
                    p += 1
                    left[s] -= 1
                i += 1
                if i == nk:
                    break
                ki = keys[nk - 1 - i] if reverse else keys[i]
                if ki >> shift != s:
                    break
            uf[s] = elder
        extremum = 3 if reverse else 1
        nroot = 0
        for j in range(nc):
            nroot += (uf[j] == j) & (kind[j] == extremum)
        roots = np.empty(nroot, np.int32)
        nroot = 0
        for j in range(nc):
            if uf[j] == j and kind[j] == extremum:
                roots[nroot] = j
                nroot += 1
        out.append((cre[:p], des[:p], roots))
    return out[0][0], out[0][1], out[0][2], out[1][0], out[1][1], out[1][2]


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

    Examples
    --------
    The height across an upright torus: one minimum, two saddles, one maximum.

    >>> import open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> cp = o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0])
    >>> cp
    CriticalPoints(minima=1, saddles=2, maxima=1, euler_characteristic=0)
    >>> cp.counts, cp.euler_characteristic, cp.kind.shape, int((cp.kind == 2).sum())
    ((1, 2, 1), 0, (600,), 2)
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

    def __len__(self):
        """Number of critical vertices (a saddle of multiplicity 2 is one vertex; ``sum(counts)``
        counts it twice, as the Morse relation ``M − s + m = χ`` does).

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> len(o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0]))
        4
        """
        return len(self.minima) + len(self.saddles) + len(self.maxima)

    def same_as(self, other):
        """True when both have the same minima, saddles (with multiplicities) and maxima.

        Examples
        --------
        >>> import open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_torus()
        >>> x = m.vertex.positions.numpy()[:, 0]
        >>> o3dheat.critical_points(m, x).same_as(o3dheat.critical_points(m, 2 * x + 1))
        True
        """
        return (np.array_equal(self.minima, other.minima) and np.array_equal(self.maxima, other.maxima)
                and np.array_equal(self.saddles, other.saddles)
                and np.array_equal(self.saddle_multiplicity, other.saddle_multiplicity))

    def __repr__(self):
        m, s, M = self.counts
        return f"CriticalPoints(minima={m}, saddles={s}, maxima={M}, euler_characteristic={m - s + M})"


def _classify(S, f, pointers=False):
    """(kind, mult, crit, low, high) of :func:`_k_classify` on the surface."""
    return _kernel("_k_classify")(np.ascontiguousarray(f), S._ptr, S._adj, S.F, S.boundary, pointers)


def _order(key, second):
    """Indices sorting ``key`` ascending, ties by ``second`` (unique where ``key`` ties)."""
    o = np.argsort(key)  # not stable, but fast (SIMD)
    k = key[o]
    if len(k) > 1 and np.any(k[1:] == k[:-1]):
        o = np.lexsort((second, key))
    return o


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
    whose neighbours are all lower is regular (see the module docstring).

    Cost: O(m), one pass over the vertex adjacency and one over the faces (compiled; no sort).
    Build the :class:`Surface` once to analyse many fields: from ``(V, F)`` each call builds it
    again (0.3–0.7 s at 1M vertices, against 0.02–0.04 s for the field itself). Memory beyond the
    Surface and the field: about 25 bytes per vertex at the peak (measured at 0.1M, 1M and 10M
    vertices by ``scripts/bench_topology.py``).

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
    _warn_constant(f, S)
    kind, mult, crit, _, _ = _classify(S, f)
    kc = kind[crit]
    saddles = crit[kc == SADDLE]
    return CriticalPoints(crit[kc == MINIMUM], saddles, mult[saddles].astype(np.int64),
                          crit[kc == MAXIMUM], S.n, S.representative)


def _warn_constant(f, S):
    vals = f if S._all_used else f[S.used]
    if len(vals) and vals.min() == vals.max():
        log.warning("the field is constant: its critical points only reflect the vertex order")


# ---------------------------------------------------------------------------------- persistence
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

    Notes
    -----
    Every critical vertex appears exactly as often (creators, destroyers and essentials together)
    as its multiplicity in :func:`critical_points`. Pairs are sorted by dimension, then by
    decreasing persistence.

    Examples
    --------
    A height with a second, shallow minimum: one (minimum, saddle) pair, and the global minimum
    and maximum never paired.

    >>> import numpy as np, open3d as o3d, o3dheat
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> d = o3dheat.persistence(m, V[:, 2] + 0.5 * np.cos(3 * V[:, 0]))
    >>> d
    PersistenceDiagram(pairs=1 (dim 0: 1, dim 1: 0), essential=2)
    >>> d.persistence.round(3).tolist(), d.essential_dimension.tolist()
    ([0.469], [0, 2])
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
        """(q, 2) ``(birth, death)`` of the pairs of one dimension (0 or 1).

        Examples
        --------
        >>> import numpy as np, open3d as o3d, o3dheat
        >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
        >>> V = m.vertex.positions.numpy().astype(float)
        >>> d = o3dheat.persistence(m, V[:, 2] + 0.5 * np.cos(3 * V[:, 0]))
        >>> d.intervals(0).round(3).tolist(), d.intervals(1).shape
        ([[-0.969, -0.5]], (0, 2))
        """
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

    Cost: O(n + c log c) for c critical vertices (compiled loops; see the module docstring), about
    0.02 s for a smooth field and 0.1 s for a noisy one (c ≈ 0.6 n) at 1M vertices with a
    prebuilt :class:`Surface`. Memory beyond the Surface and the field, at the peak: about 30
    bytes per vertex for a smooth field, 100 for a noisy one (measured at 0.1M, 1M and 10M
    vertices by ``scripts/bench_topology.py``), the returned diagram included (about 50 bytes per
    pair).

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
    _warn_constant(f, S)
    kind, mult, crit, low, high = _classify(S, f, pointers=True)
    crit = crit[_order(f[crit], crit)]  # increasing (f, index): a critical vertex's id is its place
    keys0, keys1, shift = _kernel("_k_arcs")(f, S._ptr, S._adj, S.boundary, kind, low, high, crit)
    keys0.sort()
    keys1.sort()
    kc = kind[crit]
    left = mult[crit]  # the multiplicity not used by a pair, once the sweeps are done
    c0, d0, m0, c1, d1, m1 = _kernel("_k_sweeps")(keys0, keys1, shift, kc, left)
    if left.min(initial=0) < 0:  # pragma: no cover - a bug, not an input problem
        raise AssertionError("persistence used a saddle more often than its multiplicity")
    ess = np.flatnonzero(left)
    o = np.argsort(crit[ess])
    ess_sad = np.repeat(crit[ess[o]], left[ess[o]])
    ess_min, ess_max = np.sort(crit[m0]), np.sort(crit[m1])
    c0, d0, c1, d1 = crit[c0], crit[d0], crit[c1], crit[d1]
    blocks = []
    for c, d in ((c0, d0), (c1, d1)):  # per dimension: decreasing persistence, then creator
        birth, death = f[c], f[d]
        pers = np.abs(death - birth)
        o = _order(-pers, c)
        blocks.append((np.stack([c[o], d[o]], 1), birth[o], death[o], pers[o]))
    pairs, birth, death, pers = (np.concatenate(x) for x in zip(*blocks, strict=True))
    dim = np.repeat(np.array([0, 1], np.int8), [len(c0), len(c1)])
    essential = np.concatenate([ess_min, ess_sad, ess_max]).astype(np.int64)
    edim = np.repeat(np.array([0, 1, 2], np.int8), [len(ess_min), len(ess_sad), len(ess_max)])
    return PersistenceDiagram(pairs, birth, death, pers, dim, essential, edim)


def simplify_critical_points(mesh, f, delta=None, keep_fraction=None, diagram=None):
    """The δ-simplification of the critical points (§3.3, ref. [33]).

    Keeps the essential critical points and both ends of every persistence pair with
    ``persistence >= delta`` (or of the ``ceil(keep_fraction · p)`` most persistent of the p
    pairs; ties broken by the diagram's order).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh, (V, F) tuple or Surface
        The surface (a :class:`Surface` when already built, saving its construction).
    f : (n,) array_like
        The field, one value per vertex.
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
        The surface.
    f : (n,) array_like
        The field, one value per vertex.
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

