"""The topology's compiled loops (numba) and their callers: :func:`kernel`, :func:`classified`.

:func:`kernel` gives the compiled version of a loop by name (the checks of (V, F) arrays, the
surface's adjacency in link order, its edges, the lower links, the persistence sweeps, the
tracking's climb; the callers give them arrays numpy allocates: numba's own would get small pages,
slow to touch at this size), :func:`classified` the classification of a field on a Surface;
:func:`warn_constant` is the warning the critical points and persistence share.

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
LOOPS = ("checked_copy", "duplicates", "links", "classify", "pack_keys", "settle_runs", "arcs", "sweeps")


def kernel(name):
    """The compiled version of the loop ``name`` of this module (one of :data:`LOOPS`, ``edge_tables`` or ``climb``)."""
    return compiled(globals()[name])


def classified(S, f, pointers=False):
    """(kind, mult, crit, low, high) of :func:`classify` for the field ``f`` on the Surface ``S``
    (``high`` has an entry more, for :func:`arcs`; both empty unless ``pointers``)."""
    ptr, adj = S.adjacency
    n = S.n
    kind, mult, crit = np.zeros(n, np.int8), np.zeros(n, np.int32), np.empty(n, np.int64)
    low, high = (np.empty(n, np.int32), np.empty(n + 1, np.int32)) if pointers else (mult[:0], mult[:0])
    nc = kernel("classify")(np.ascontiguousarray(f), ptr, adj, S.boundary, kind, mult, crit, low, high)
    return kind, mult, crit[:nc], low, high


def pack_keys(key, ib, words):
    """``words[i]``: the leading ``64 - ib`` order-preserving bits of ``key[i]``, then ``i``."""
    top = np.uint64(1) << np.uint64(63)
    zero = np.uint64(0)
    sh = np.uint64(ib)
    bits = key.view(np.uint64)
    for i in range(key.shape[0]):
        u = bits[i]
        u = zero if u == top else u  # -0.0 as 0.0
        u = ~u if u & top else u | top  # negative: reversed; positive: above them
        words[i] = ((u >> sh) << sh) | np.uint64(i)


def settle_runs(words, ib, key, second, idx):
    """``idx`` from the sorted ``words`` of :func:`pack_keys`: their indices, each run of equal
    leading bits sorted by ``(key, second)`` (an insertion sort of the run, when it is out of
    order: a near-tie, or ties whose ``second`` is not ascending). False, with ``idx`` unfinished,
    when such a run is longer than 32 (many ties: the caller sorts otherwise)."""
    N = words.shape[0]
    low = (np.uint64(1) << np.uint64(ib)) - np.uint64(1)
    sh = np.uint64(ib)
    for i in range(N):
        idx[i] = np.int64(words[i] & low)
    i = 0
    while i < N:
        j = i + 1
        pre = words[i] >> sh
        while j < N and (words[j] >> sh) == pre:
            j += 1
        for k in range(i + 1, j):
            x = idx[k]
            m = k - 1
            while m >= i and (key[idx[m]] > key[x] or (key[idx[m]] == key[x] and second[idx[m]] > second[x])):
                if j - i > 32:
                    return False
                idx[m + 1] = idx[m]
                m -= 1
            idx[m + 1] = x
        i = j
    return True


def warn_constant(f, S):
    """Log a warning when ``f`` is constant on the vertices of ``S`` that faces use."""
    used = S.used
    vals = f if used.all() else f[used]
    if len(vals) and vals.min() == vals.max():
        log.warning("the field is constant: its critical points only reflect the vertex order")


def edge_tables(F, ptr, adj):
    """The edges from the adjacency: ``E`` (e, 2) int64 (``(lo, hi)``, lexicographic), faces per
    edge ``count`` (e,) int32 and ``face_edges`` (3m,) int64 (the edge of ``(F[t, s], F[t, s + 1])``
    at ``3 t + s``)."""
    n = ptr.shape[0] - 1
    first = np.zeros(n + 1, np.int64)  # the edges (v, u > v): first[v]:first[v + 1]
    for v in range(n):
        c = 0
        for k in range(ptr[v], ptr[v + 1]):
            c += adj[k] > v
        first[v + 1] = first[v] + c
    hi = np.empty(first[n], np.int32)
    for v in range(n):
        e = first[v]
        for k in range(ptr[v], ptr[v + 1]):
            if adj[k] > v:
                hi[e] = adj[k]
                e += 1
        hi[first[v]:e].sort()
    E = np.empty((first[n], 2), np.int64)
    for v in range(n):
        for e in range(first[v], first[v + 1]):
            E[e, 0], E[e, 1] = v, hi[e]
    count = np.zeros(first[n], np.int32)
    face_edges = np.empty(3 * F.shape[0], np.int64)
    for t in range(F.shape[0]):
        for s in range(3):
            a, b = F[t, s], F[t, (s + 1) % 3]
            e = first[min(a, b)]
            while hi[e] != max(a, b):
                e += 1
            face_edges[3 * t + s] = e
            count[e] += 1
    return E, count, face_edges


def checked_copy(V, F, lo, hi, Fc, used):
    """The checks of :func:`o3dheat.geometry.mesh.as_arrays` on float64 ``V`` (n, 3) and int64 ``F``
    (m, 3), one pass over each: False if a coordinate is not finite, an index out of range or the
    extent out of ``[lo, hi]``. Fills ``Fc`` (the copy of ``F``) and ``used`` (referenced vertices)."""
    n, m = V.shape[0], F.shape[0]
    for t in range(m):
        for s in range(3):
            x = F[t, s]
            if x < 0 or x >= n:
                return False
            Fc[t, s] = x
            used[x] = True
    a0, a1, a2 = V[0, 0], V[0, 1], V[0, 2]
    b0, b1, b2 = a0, a1, a2
    z = 0.0
    for v in range(n):
        x, y, w = V[v, 0], V[v, 1], V[v, 2]
        z += x * 0.0 + y * 0.0 + w * 0.0  # NaN once anything is not finite
        a0, b0 = min(a0, x), max(b0, x)
        a1, b1 = min(a1, y), max(b1, y)
        a2, b2 = min(a2, w), max(b2, w)
    extent = max(b0 - a0, b1 - a1, b2 - a2)
    return z == 0.0 and not (extent > hi or 0 < extent < lo)


def duplicates(V, used, table):
    """Whether two vertices that ``used`` marks have exactly the same coordinates (-0.0 equal to
    0.0): open addressing in ``table`` (-1: empty; a power of two, at least twice the vertices)."""
    mask = np.uint64(table.shape[0] - 1)
    c1, c2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
    s21, s43, s30, s27, s31 = np.uint64(21), np.uint64(43), np.uint64(30), np.uint64(27), np.uint64(31)
    coords = np.empty(3, np.float64)
    words = coords.view(np.uint64)
    for v in range(V.shape[0]):
        if not used[v]:
            continue
        for c in range(3):
            coords[c] = V[v, c] + 0.0  # -0.0 hashes as 0.0
        x = words[0] ^ ((words[1] << s21) | (words[1] >> s43)) ^ ((words[2] << s43) | (words[2] >> s21))
        x = (x ^ (x >> s30)) * c1  # splitmix64's finalizer
        x = (x ^ (x >> s27)) * c2
        p = np.int64((x ^ (x >> s31)) & mask)
        while True:  # exact comparisons
            j = table[p]
            if j < 0:
                table[p] = v
                break
            if V[j, 0] == coords[0] and V[j, 1] == coords[1] and V[j, 2] == coords[2]:
                return True
            p = np.int64((np.uint64(p) + np.uint64(1)) & mask)
    return False


def links(F, n, start, link, ptr, adj, boundary, first):
    """The vertex adjacency of a surface in link order, with its checks, in O(m).

    The corners are bucketed by vertex (a counting sort in ``start`` (n + 2,), zeros); each corner
    of ``v`` in face ``(v, a, b)`` is an edge ``(a, b)`` of the link of ``v`` (in ``link`` (6m,)).
    Per vertex, the ends of its link edges are grouped by neighbour (``first`` (n,), -1 on entry
    and exit: a neighbour's first end): a group's size is the number of faces on the edge to that
    neighbour (1: a boundary edge; more than 2: non-manifold); the two link edges meeting at a
    neighbour of a group of 2 are joined,
    and the link is walked from an end (a boundary vertex: a path) or from anywhere (a cycle). A
    vertex whose walk leaves link edges unvisited has several fans.

    Fills ``ptr`` (n + 1,), ``adj`` (3m + n,) (the neighbours of ``v`` are ``adj[ptr[v]:ptr[v +
    1]]`` in the order of its link: consecutive ones span a face with ``v``, and so do the last
    and the first when ``v`` is not on the boundary) and ``boundary`` (n,). Returns ``status``
    (0; 1: an index out of range; 2: a face repeats a vertex: nothing else is done then), the
    length of ``adj`` used, the number of edges, of edges with more than two faces and of vertices
    with several fans (when either is not 0, ``adj`` is incomplete).
    """
    m = F.shape[0]
    for t in range(m):
        a, b, c = F[t, 0], F[t, 1], F[t, 2]
        if min(a, b, c) < 0 or max(a, b, c) >= n:
            return 1, 0, 0, 0, 0
        if a == b or b == c or a == c:
            return 2, 0, 0, 0, 0
        start[a + 2] += 1
        start[b + 2] += 1
        start[c + 2] += 1
    maxd = 0
    for v in range(n):
        maxd = max(maxd, start[v + 2])
        start[v + 2] += start[v + 1]
    for t in range(m):  # corner p of v: link[2p], link[2p + 1]; start[v + 1] ends at v's bucket's end
        for s in range(3):
            v = F[t, s]
            p = start[v + 1]
            start[v + 1] = p + 1
            link[2 * p] = F[t, (s + 1) % 3]
            link[2 * p + 1] = F[t, (s + 2) % 3]
    partner = np.empty(2 * maxd, np.int32)  # the other end of a neighbour's two link edges; -1: none
    occ = np.empty(2 * maxd, np.int32)  # at a neighbour's first end: its number of link edges
    seen = np.zeros(maxd, np.bool_)
    ptr[0] = 0
    q, ne, bad_edges, bad_fans = 0, 0, 0, 0
    succ = np.empty(maxd, np.int32)  # the corner after each, around the vertex
    for v in range(n):
        p0, d = start[v], start[v + 1] - start[v]
        w = 2 * d
        if d == 0:
            ptr[v + 1] = q
            continue
        if d <= 16:  # the usual vertex, consistently oriented and closed: each b is one a
            ok = True
            for i in range(d):
                b = link[2 * (p0 + i) + 1]
                c, nx = 0, 0
                for j in range(d):
                    eq = link[2 * (p0 + j)] == b
                    c += eq
                    nx = j if eq else nx
                ok &= c == 1
                succ[i] = nx
            if ok:  # one cycle through all the corners: the link, in order
                i, up = 0, 0
                for k in range(d):
                    u = link[2 * (p0 + i)]
                    adj[q + k] = u
                    up += u > v
                    i = succ[i]
                    if i == 0 and k < d - 1:
                        ok = False
                        break
                if ok:
                    ne += up
                    q += d
                    ptr[v + 1] = q
                    continue
        for i in range(w):  # otherwise: group the ends by neighbour (first: a neighbour's first end, or -1)
            u = link[2 * p0 + i]
            f0 = first[u]
            partner[i] = -1
            if f0 < 0:
                first[u] = i
                occ[i] = 1
            else:
                occ[f0] += 1
                if occ[f0] == 2:
                    partner[f0] = i
                    partner[i] = f0
        end = -1
        for i in range(w):
            u = link[2 * p0 + i]
            if first[u] == i:
                ne += u > v
                if occ[i] == 1:
                    end = i
                elif occ[i] > 2:
                    bad_edges += u > v
        for i in range(w):
            first[link[2 * p0 + i]] = -1
        boundary[v] = end >= 0
        cur = max(end, 0)
        for e in range(d):
            seen[e] = False
        adj[q] = link[2 * p0 + cur]
        q += 1
        nseen = 0
        while True:  # walk the link: along an edge, then across the neighbour to its other edge
            seen[cur >> 1] = True
            nseen += 1
            t = cur ^ 1
            nxt = partner[t]
            if nxt >= 0 and seen[nxt >> 1]:  # back at the start: a cycle
                break
            adj[q] = link[2 * p0 + t]
            q += 1
            if nxt < 0:  # the other end of a path
                break
            cur = nxt
        bad_fans += nseen < d
        ptr[v + 1] = q
    return 0, q, ne, bad_edges, bad_fans


def classify(f, ptr, adj, boundary, kind, mult, crit, low, high):
    """Banchoff's classification in the order (f, index), from the adjacency in link order
    (:func:`links`): the lower link's arcs are the runs of lower neighbours around the vertex.

    Fills ``kind`` (n,) int8 (zeros on entry; 0 regular or unreferenced, 1 minimum, 2 saddle, 3
    maximum), ``mult`` (n,) int32 (zeros on entry; saddle multiplicity), ``crit`` (n,) int64 the
    critical vertices (ascending; returns their number) and, when they have n entries (none:
    not asked for), ``low`` and ``high``: a lower and an upper neighbour of each referenced vertex
    (the last listed; -1: none). Written without branches on the values (selects instead), which
    noisy fields would mispredict.
    """
    n = f.shape[0]
    pointers = low.shape[0] >= n
    nc = 0
    for v in range(n):
        p0, p1 = ptr[v], ptr[v + 1]
        if p0 == p1:
            continue
        fv = f[v]
        u = adj[p1 - 1]
        fu = f[u]
        prev = ((fu < fv) | ((fu == fv) & (u < v))) & (not boundary[v])  # a path starts afresh
        c, runs = 0, 0
        lo, hi = -1, -1
        for k in range(p0, p1):
            u = adj[k]
            fu = f[u]
            below = (fu < fv) | ((fu == fv) & (u < v))
            c += below
            runs += below > prev
            prev = below
            lo = u if below else lo
            hi = hi if below else u
        if pointers:
            low[v] = lo
            high[v] = hi
        if c == 0:
            kind[v] = 1
        elif c == p1 - p0 and not boundary[v]:
            kind[v] = 3
        elif runs >= 2:
            kind[v] = 2
            mult[v] = runs - 1
        crit[nc] = v
        nc += kind[v] != 0
    return nc


def arcs(f, ptr, adj, boundary, kind, mult, uf0, uf1, crit):
    """The saddles' links in the lower and upper forests, as sortable keys.

    ``crit`` lists the critical vertices in increasing (f, index): position ``i`` in it is the
    vertex's *id*, so that of two ids the smaller is the older in the sublevel sweep. A vertex that
    is not critical joins the component of ``low`` (a lower neighbour; its lower link is one arc,
    so all its lower neighbours are connected already), and likewise of ``high`` for superlevel
    sets, where every boundary vertex joins an apex ``n`` above every value (id ``len(crit)``, the
    boundary coned to one point). These links form two forests whose roots are the minima and
    saddles (lower) and the maxima, saddles and apex (upper): ``uf0`` (n,) holds ``low`` and
    ``uf1`` (n + 1,) ``high`` on entry (:func:`classify`'s), the forests after.

    For each saddle, in vertex order (its neighbours are near it in memory), the roots of the
    first neighbour of each run of lower (upper) neighbours around it (a run is connected below
    (above) it already) are found (with path compression) and listed once each as keys
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

    cap0, cap1 = 0, 0
    for v in range(n):
        if boundary[v]:
            uf1[v] = apex
        if kind[v] == 2:  # mult + 1 lower runs; as many upper ones, one more on the boundary, and the apex
            cap0 += mult[v] + 1
            cap1 += mult[v] + 3
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
        p0, p1 = ptr[s], ptr[s + 1]
        u = adj[p0 if boundary[s] else p1 - 1]
        fu = f[u]
        prev = (fu < fs) | ((fu == fs) & (u < s))
        if boundary[s]:  # a path: its first neighbour starts a run
            prev = not prev
        for k in range(p0, p1):  # the first neighbour of each run of lower (upper) ones
            u = adj[k]
            fu = f[u]
            below = (fu < fs) | ((fu == fs) & (u < s))
            if below != prev:
                if below:
                    k0 = push(keys0, j0, k0, hi_s | find(uf0, u))
                else:
                    k1 = push(keys1, j1, k1, hi_s | find(uf1, u))
            prev = below
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
