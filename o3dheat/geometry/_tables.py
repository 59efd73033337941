"""Mesh tables, the geometry's internal API: :func:`edges`, :func:`weld_copies`, :func:`clean`,
:func:`first_copies`, :func:`vertex_normals`, ...

The tables behind :mod:`o3dheat.geometry` and its users (fem, topology, sampling, plot): unique
rows, edges, degenerate and zero-area faces, exact copies, welding, corners and fans, non-manifold
edges and vertices, vertex normals, and the cleaning every computation applies (:func:`clean`).
Plain names, no checks of the arguments (the public functions that call them check), imported by
the modules downstream of :mod:`o3dheat.geometry.mesh` instead of its private names.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ._loops import double_areas, first_rows


def unit_scale(V):
    """A power of two ``s`` with ``V / s`` of extent near 1, or 1 when the extent is within
    ``[2^-60, 2^60]``: squares of coordinates then neither overflow nor underflow, and dividing
    by ``s`` is exact (no rounding), so results at ordinary scales are unchanged bit for bit.

    Examples
    --------
    >>> import numpy as np, o3dheat.geometry.mesh as m
    >>> m.unit_scale(np.eye(3)), m.unit_scale(1e90 * np.eye(3)) == 2.0 ** 299
    (1.0, True)
    """
    V = np.asarray(V)
    extent = float(np.max(np.ptp(V, axis=0))) if len(V) else 0.0
    if not np.isfinite(extent) or extent == 0 or 2.0**-60 <= extent <= 2.0**60:
        return 1.0
    return float(2.0 ** np.round(np.log2(extent)))


def unique_rows(A, return_index=False, return_counts=False):
    """``np.unique(A, axis=0, ...)`` for rows of non-negative integers, 5-10x faster: each row is
    packed into one int64 key when that fits (the general path otherwise)."""
    A = np.asarray(A, dtype=np.int64)
    base = int(A.max()) + 1 if A.size else 1
    c = A.shape[1] if A.ndim == 2 else 1
    if A.ndim != 2 or A.min(initial=0) < 0 or c * np.log2(max(base, 2)) >= 62:
        return np.unique(A, axis=0, return_index=return_index, return_counts=return_counts)
    key = np.zeros(len(A), np.int64)
    for j in range(c):
        key = key * base + A[:, j]
    out = np.unique(key, return_index=True, return_counts=return_counts)
    rows = A[out[1]]
    res = (rows,) + ((out[1],) if return_index else ()) + ((out[2],) if return_counts else ())
    return res if len(res) > 1 else rows


def edges(F):
    """Unique undirected edges (e, 2) and, for each, the number of incident faces."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    E, counts = unique_rows(E, return_counts=True)
    return E, counts


def degenerate(F):
    """Faces that repeat a vertex index."""
    return (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])


def zero_area(V, F):
    s = unit_scale(V)  # relative test: at unit scale (exact, a power of two)
    V = V / s if s != 1.0 else V
    area = 0.5 * double_areas(V, F)
    scale = np.max(np.ptp(V, axis=0)) if len(V) else 1.0
    return area <= 1e-14 * max(scale, np.finfo(float).tiny) ** 2


def first_copies(P, bits=64):
    """(m,) int64: for each row of ``P`` (m, 3), the smallest index of a row with exactly the same
    float64 values (itself when unique; -0.0 equals 0.0, NaN equals nothing), in one pass over a
    hash table of the coordinates' bits (:func:`o3dheat.geometry._loops.first_rows`; ``bits``
    narrows the hash, for tests). An STL's 6M corners: about 0.5 s."""
    P = np.ascontiguousarray(P, dtype=np.float64) + 0.0  # -0.0 hashes as 0.0
    return first_rows(P.view(np.uint64), P, bits)


def first_faces(F):
    """(m,) bool: True at the first of each set of faces with the same three vertices (in any
    order), in one pass (:func:`o3dheat.geometry._loops.first_rows` on the sorted triples)."""
    S = np.sort(np.asarray(F, dtype=np.int64), axis=1)
    return first_rows(S.view(np.uint64), S) == np.arange(len(S))


def weld_map(V, F):
    """``rep`` (n,) int64: for each vertex referenced by ``F``, the smallest index of a referenced
    vertex with exactly the same coordinates it is welded into; ``rep[i] = i`` otherwise
    (unreferenced vertices are never welded). Vectorised (:func:`first_copies`). See
    :func:`weld_copies` for the copies kept apart."""
    return weld_copies(V, F)[0]


def weld_copies(V, F):
    """(``rep`` as :func:`weld_map`, ``apart``): ``apart`` counts the referenced vertices left
    as separate vertices although they coincide exactly with another referenced one -- the copies
    welding keeps apart to keep the surface a manifold, i.e. the vertices it *splits*: a soup
    (an STL) cannot tell a pinched vertex (one vertex, two fans) from two coincident vertices
    with a fan each (pymeshlab's cow.obj has such a pair, vertices 45 and 2904), and welding
    gives one vertex per fan, the 2-manifold; the count says how many such splits it made."""
    n = len(V)
    rep = np.arange(n, dtype=np.int64)
    if n == 0 or len(F) == 0:
        return rep, 0
    used = np.zeros(n, bool)
    used[F.reshape(-1)] = True
    idx = np.flatnonzero(used)
    rep[idx] = idx[first_copies(V[idx])]
    if np.all(rep == np.arange(n)):
        return rep, 0
    positions = len(np.unique(rep[idx]))
    # copies are welded only where that keeps the surface a manifold: a mesh split on purpose at a
    # non-manifold edge or vertex (o3dheat.repair) stays split. The corners of one input vertex
    # stay together; corners of coincident copies join across welded edges with exactly two faces.
    m = len(F)
    W = rep[F]  # pairs from the welded faces that stay (not degenerate, first of duplicates)
    ok = ~degenerate(W)  # (the faces prepare drops after welding: degenerate, duplicate, zero-area)
    _, first = unique_rows(np.sort(W, axis=1), return_index=True)
    ok &= np.isin(np.arange(m), first)
    ok[ok] &= ~zero_area(V, W[ok])
    faces = np.flatnonzero(ok)
    u, v = corner_pairs(W[faces], n)
    u, v = 3 * faces[u // 3] + u % 3, 3 * faces[v // 3] + v % 3
    order = np.argsort(F.reshape(-1), kind="stable")  # corners of the same input vertex
    same = F.reshape(-1)[order[1:]] == F.reshape(-1)[order[:-1]]
    u, v = np.r_[u, order[1:][same]], np.r_[v, order[:-1][same]]
    k, lab = corner_components(m, u, v)
    flat = F.reshape(-1)
    smallest = np.full(k, n, np.int64)
    np.minimum.at(smallest, lab, flat)
    rep[flat] = smallest[lab]
    return rep, int(len(np.unique(rep[idx])) - positions)


def corner_pairs(F, n):
    """Corners (``3 f + j``) joined across the edges that have exactly two faces: (u, v) arrays,
    each pair the two corners of one vertex in the two faces of such an edge."""
    a, b = F, F[:, [1, 2, 0]]
    key = np.minimum(a, b).reshape(-1) * np.int64(n) + np.maximum(a, b).reshape(-1)  # incidence 3 f + j
    order = np.argsort(key, kind="stable")
    ks = key[order]
    start = np.r_[True, ks[1:] != ks[:-1]]
    gid = np.cumsum(start) - 1
    pair = np.flatnonzero(start & (np.bincount(gid)[gid] == 2))
    e1, e2 = order[pair], order[pair + 1]
    ca1, cb1 = e1, 3 * (e1 // 3) + (e1 % 3 + 1) % 3  # corners at the edge's two ends, per face
    ca2, cb2 = e2, 3 * (e2 // 3) + (e2 % 3 + 1) % 3
    flat = F.reshape(-1)
    same = flat[ca1] == flat[ca2]
    return np.r_[ca1, cb1], np.r_[np.where(same, ca2, cb2), np.where(same, cb2, ca2)]


def corner_components(m, u, v):
    g = sp.coo_matrix((np.ones(len(u)), (u, v)), shape=(3 * m, 3 * m))
    return connected_components(g, directed=False)


def non_manifold_edge_faces(F, n):
    """(m,) bool: the faces that have an edge shared by three or more faces."""
    a, b = F, F[:, [1, 2, 0]]
    key = np.minimum(a, b) * np.int64(n) + np.maximum(a, b)  # (m, 3) edge keys
    uniq, inv, counts = np.unique(key.reshape(-1), return_inverse=True, return_counts=True)
    return (counts[inv.reshape(-1)] > 2).reshape(-1, 3).any(axis=1)


def non_manifold_vertex_mask(F, n):
    """(n,) bool: vertices whose incident faces form more than one edge-connected fan."""
    m = len(F)
    if m == 0:
        return np.zeros(n, bool)
    # corner c = (face, slot); two corners at the same vertex are adjacent when their faces share
    # the edge (vertex, other) -- join corners through the "half-edge key" (vertex, other vertex).
    vert = F.reshape(-1)
    nxt = F[:, [1, 2, 0]].reshape(-1)
    prv = F[:, [2, 0, 1]].reshape(-1)
    keys = np.concatenate([vert * n + nxt, vert * n + prv])
    corner = np.concatenate([np.arange(3 * m), np.arange(3 * m)])
    order = np.argsort(keys, kind="stable")
    ks, cs = keys[order], corner[order]
    same = ks[1:] == ks[:-1]
    a, b = cs[:-1][same], cs[1:][same]
    g = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(3 * m, 3 * m))
    _, lab = connected_components(g, directed=False)
    # a vertex is in more than one fan when its corners carry more than one label: compare each
    # corner's label with one label of its vertex (any corner's), O(m) with no sort
    one = np.empty(n, lab.dtype)
    one[vert] = lab
    mask = np.zeros(n, bool)
    mask[vert[one[vert] != lab]] = True
    return mask


def non_manifold_vertices(F, n):
    """Number of vertices whose incident faces form more than one edge-connected fan."""
    return int(np.sum(non_manifold_vertex_mask(F, n)))



def vertex_normals(V, F):
    """Area-weighted vertex normals (unit length where defined)."""
    V = V / unit_scale(V)  # exact; unit normals do not depend on the scale
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])  # 2 |t| times the face normal
    N = np.zeros_like(V)
    for i in range(3):
        np.add.at(N, F[:, i], n)
    length = np.linalg.norm(N, axis=1, keepdims=True)
    return np.divide(N, length, out=np.zeros_like(N), where=length > 0)


@dataclass
class Cleaned:
    """What :func:`clean` did to a mesh's faces: the one set of rules
    :func:`o3dheat.geometry.welding.prepare` (every computation) applies and
    :func:`o3dheat.geometry.mesh.check_mesh` reports."""

    F: np.ndarray  # the faces used, in the caller's vertex numbering (welded copies replaced)
    rep: np.ndarray | None  # weld map (n,) or None when nothing was welded
    welded: int = 0  # referenced copies welded into an earlier one
    split: int = 0  # referenced vertices coincident with another, kept apart (see weld)
    degenerate: int = 0
    duplicate: int = 0
    zero_area: int = 0
    used: np.ndarray | None = None  # (n,) bool: vertices of the faces used
    unreferenced: int = 0  # input vertices in no face used (welded copies not counted)


def clean(V, F, weld=True):
    """Weld, then drop degenerate, duplicate and zero-area faces, in this order (the rules of the
    Notes of :mod:`o3dheat.geometry.welding`), counting each. ``V`` must be finite, ``F`` in range."""
    n = len(V)
    rep, split = weld_copies(V, F) if weld else (None, 0)
    welded = 0 if rep is None else int(np.sum(rep != np.arange(n)))
    if welded:
        F = rep[F]
    else:
        rep = None
    c = Cleaned(F, rep, welded, split)
    bad = degenerate(F)
    c.degenerate = int(bad.sum())
    F = F[~bad]
    if len(F):
        first = first_faces(F)
        c.duplicate = int(np.sum(~first))
        F = F[first]
    if len(F):
        zero = zero_area(V, F)
        c.zero_area = int(zero.sum())
        F = F[~zero]
    c.F = F
    c.used = np.zeros(n, bool)
    c.used[F.reshape(-1)] = True
    # after welding, the copies are referenced by no face: they are not "set aside", unless all
    # the faces of their welded vertex went
    c.unreferenced = int(n - c.used.sum() - welded)
    if welded:
        c.unreferenced += int(np.sum(~c.used[rep] & (rep != np.arange(n))))
    return c
