"""The topology's compiled loops (numba) and their callers: :func:`kernel`, :func:`edges`, :func:`classified`.

:func:`kernel` gives the compiled version of a loop by name (the surface's tables, the lower links,
the persistence sweeps, the tracking's climb), :func:`edges` the edge tables of faces,
:func:`classified` the classification of a field on a Surface; :func:`warn_constant` is the
warning the critical points and persistence share.

The loops are plain Python functions compiled on first use (:func:`o3dheat._jit.compiled`: numba,
imported only then, cached once per installation, beside this module). Vertex ids are int32 inside,
indices of faces and edges int64.
"""

from __future__ import annotations

import logging

import numpy as np

from o3dheat._jit import compiled

log = logging.getLogger("o3dheat")

#: the loops of Surface, critical_points and persistence (those warm_up loads); tracking adds ``climb``
LOOPS = ("sorted_half_edges", "number_edges", "fans", "classify", "arcs", "sweeps")


def kernel(name):
    """The compiled version of the loop ``name`` of this module (one of :data:`LOOPS`, or ``climb``)."""
    return compiled(globals()[name])


def edges(F, n):
    """The edge tables of faces ``F`` on ``n`` vertices (:func:`sorted_half_edges`, then
    :func:`number_edges`): ``E``, ``count``, ``face_edges``, ``he``, ``first``, ``ptr``, ``adj``."""
    start, hi, he, ne = kernel("sorted_half_edges")(F, n)
    E, count, face_edges, first, ptr, adj = kernel("number_edges")(start, hi, he, ne, n)
    return E, count, face_edges, he, first, ptr, adj


def classified(S, f, pointers=False):
    """(kind, mult, crit, low, high) of :func:`classify` for the field ``f`` on the Surface ``S``."""
    ptr, adj = S.adjacency
    return kernel("classify")(np.ascontiguousarray(f), ptr, adj, S.F, S.boundary, pointers)


def warn_constant(f, S):
    """Log a warning when ``f`` is constant on the vertices of ``S`` that faces use."""
    used = S.used
    vals = f if used.all() else f[used]
    if len(vals) and vals.min() == vals.max():
        log.warning("the field is constant: its critical points only reflect the vertex order")


def sorted_half_edges(F, n):
    """The half-edges of the faces in buckets by their lower vertex (a counting sort), each bucket
    sorted by the higher vertex (small: a vertex's edges).

    Returns ``start`` (n + 1,) int64 (the bucket of vertex ``v``: ``start[v]:start[v + 1]``),
    ``hi`` (3m,) int32 the higher vertex and ``he`` (3m,) int32 the half-edge (``3 t + s``, from
    ``F[t, s]`` to ``F[t, s + 1]``) at each place, and ``ne`` the number of unique edges.
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
    return start, hi, he, ne


def number_edges(start, hi, he, ne, n):
    """The edge tables from :func:`sorted_half_edges`: unique edges in ``(lo, hi)`` order and the
    vertex adjacency.

    Returns ``E`` (e, 2) int64, faces per edge ``count`` (e,) int32, ``face_edges`` (3m,) int64
    (edge of each half-edge), ``first`` (e,) int32 the position in ``he`` (the half-edges in edge
    order) of each edge's first one, and the vertex adjacency: ``ptr`` (n + 1,) int64, ``adj``
    (2e,) int32.
    """
    E = np.empty((ne, 2), np.int64)
    count = np.zeros(ne, np.int32)
    first = np.empty(ne, np.int32)
    face_edges = np.empty(he.shape[0], np.int64)
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
    return E, count, face_edges, first, ptr, adj


def fans(F, E, count, he, first, n):
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
    nfans = np.zeros(n, np.int32)
    for c in range(3 * m):
        if uf[c] == c:
            nfans[F[c // 3, c % 3]] += 1
    bad = 0
    for v in range(n):
        if nfans[v] > 1:
            bad += 1
    return bad


def classify(f, ptr, adj, F, boundary, pointers):
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


def arcs(f, ptr, adj, boundary, kind, low, high, crit):
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


def sweeps(keys0, keys1, shift, kind, left):
    """Elder-rule union–find over the critical ids (see :func:`arcs`), from sorted keys.

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


def climb(f, ptr, adj, starts, up):
    """From each start, steepest ascent (``up``) or descent in the order of ``(f, vertex index)``:
    each step to the highest (lowest) neighbour while it is higher (lower); the vertex it stops on."""
    out = starts.copy()
    for s in range(len(starts)):
        v = starts[s]
        while True:
            best = v
            for k in range(ptr[v], ptr[v + 1]):
                u = adj[k]
                if up:
                    if f[u] > f[best] or (f[u] == f[best] and u > best):
                        best = u
                elif f[u] < f[best] or (f[u] == f[best] and u < best):
                    best = u
            if best == v:
                break
            v = best
        out[s] = v
    return out
