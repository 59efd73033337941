"""Shared cases of the topology tests: surfaces, fields, brute-force and previous-implementation
references (imported by the test modules of this folder: ``from topology_cases import ...``)."""

import itertools

import numpy as np
import pytest
from conftest import grid, icosphere, irregular, torus


def genus2():
    """Two tori joined by a triangular tube: a closed genus-2 surface (χ = -2)."""
    V1, F1 = torus(1.0, 0.4, 24, 12)
    V2, F2 = V1 + [3.0, 0.0, 0.0], F1 + len(V1)
    a, b = F1[0], F2[0][::-1]
    tube = []
    for i in range(3):
        j = (i + 1) % 3
        tube += [[a[i], b[i], a[j]], [a[j], b[i], b[j]]]
    return np.concatenate([V1, V2]), np.concatenate([F1[1:], F2[1:], tube])


def annulus():
    """A square with a square hole (whole grid cells removed, so no pinched vertex): χ = 0."""
    V, F = grid(1.0, 1.0, 12, 12)
    q = len(F) // 2
    c = (V[F[:q, 0]] + V[F[:q, 2]]) / 2
    hole = np.all(np.abs(c[:, :2] - 0.5) < 0.2, axis=1)
    return V, F[~np.concatenate([hole, hole])]


def two_spheres():
    V, F = icosphere(1)
    return np.concatenate([V, V + 3.0]), np.concatenate([F, F + len(V)])


# name -> (mesh, χ, genus per component, boundary loops per component, components)
SURFACES = {
    "sphere": (icosphere(2), 2),
    "torus": (torus(1.0, 0.4, 24, 12), 0),
    "genus2": (genus2(), -2),
    "disk": (grid(2.0, 1.0, 12, 8), 1),
    "annulus": (annulus(), 0),
    "irregular": (irregular(), 2),
    "two spheres": (two_spheres(), 4),
}


# essential (minima, saddles, maxima) expected on each surface
ESSENTIAL = {"sphere": (1, 0, 1), "torus": (1, 2, 1), "genus2": (1, 4, 1), "disk": (1, 0, 0),
             "annulus": (1, 1, 0), "irregular": (1, 0, 1), "two spheres": (2, 0, 2)}


def fields(n, seed):
    rng = np.random.default_rng(seed)
    yield "random", rng.standard_normal(n)
    yield "plateaus", np.round(rng.standard_normal(n))  # many exact ties
    yield "constant", np.zeros(n)


def upright_torus_height():
    V, F = torus(1.0, 0.4, 48, 24)  # axis along z: "upright" means the axis horizontal
    return (V, F), V[:, 0]


def link_cycle(faces, v):
    """Ordered neighbours of v walking around its faces, and whether v is on the boundary."""
    opp = [tuple(u for u in t if u != v) for t in faces]
    adj = {}
    for a, b in opp:
        adj.setdefault(a, []).append(b)
        adj.setdefault(b, []).append(a)
    ends = [u for u, nb in adj.items() if len(nb) == 1]
    start = ends[0] if ends else next(iter(adj))
    order, prev = [start], None
    while True:
        nxt = [u for u in adj[order[-1]] if u != prev and u not in order]
        if not nxt:
            break
        prev = order[-1]
        order.append(nxt[0])
    assert len(order) == len(adj)
    return order, bool(ends)


def brute_critical(F, f):
    """Classification by walking each link and counting the lower runs."""
    def key(i):  # simulation of simplicity
        return (f[i], i)

    n = len(f)
    out = {"min": [], "max": [], "saddle": {}}
    star = {}
    for t in F.tolist():
        for v in t:
            star.setdefault(v, []).append(t)
    for v in sorted(star):
        cyc, boundary = link_cycle(star[v], v)
        low = [key(u) < key(v) for u in cyc]
        if not any(low):
            out["min"].append(v)
            continue
        if all(low) and not boundary:
            out["max"].append(v)
            continue
        seq = low if boundary else low + low[:1]
        runs = sum(1 for i in range(len(low)) if low[i] and (i == 0 or not seq[i - 1]))
        if not boundary and low[0] and low[-1]:
            runs -= 1  # the run through the start of the cycle was counted twice
        if runs >= 2:
            out["saddle"][int(v)] = runs - 1
    assert n >= len(out["min"])
    return out


def brute_persistence(F, f):
    """Standard boundary-matrix reduction (Z/2) of the lower-star filtration, by vertex pairs."""
    n = len(f)
    order = np.argsort(f, kind="stable")
    rank = np.empty(n, int)
    rank[order] = np.arange(n)
    E = sorted({tuple(sorted(e)) for t in F for e in itertools.combinations(t, 2)})
    T = [tuple(sorted(t)) for t in F]
    used = set(np.unique(F).tolist())
    simplices = [(v,) for v in range(n) if v in used] + E + T
    simplices.sort(key=lambda s: (sorted((rank[v] for v in s), reverse=True), len(s)))
    index = {s: i for i, s in enumerate(simplices)}
    cols = [{index[tuple(sorted(c))] for c in itertools.combinations(s, len(s) - 1)} if len(s) > 1
            else set() for s in simplices]
    low_of = {}
    pairs = []
    def top(s):
        return max(s, key=lambda v: rank[v])

    for j, col in enumerate(cols):
        while col and max(col) in low_of:
            col ^= cols[low_of[max(col)]]
        if col:
            i = max(col)
            low_of[i] = j
            a, b = top(simplices[i]), top(simplices[j])
            if a != b:
                pairs.append((len(simplices[i]) - 1, a, b))
    return pairs


def gudhi_diagrams(F, f):
    gudhi = pytest.importorskip("gudhi")
    st = gudhi.SimplexTree()
    used = np.unique(F)  # unreferenced vertices are not part of the surface
    st.insert_batch(used[None, :], f[used])
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [0, 2]]]), axis=1), axis=0)
    st.insert_batch(E.T, f[E].max(axis=1))
    st.insert_batch(F.T, f[F].max(axis=1))
    st.compute_persistence(homology_coeff_field=2, min_persistence=-1, persistence_dim_max=True)
    return [st.persistence_intervals_in_dimension(k) for k in (0, 1, 2)]


def finite(D):
    D = D[np.isfinite(D[:, 1])] if len(D) else D.reshape(0, 2)
    D = D[D[:, 1] > D[:, 0]]
    return D[np.lexsort((D[:, 1], D[:, 0]))]


# The numpy implementation that the compiled loops (issue 14) replaced, kept as the reference:
# ranks, lower links from the edge list, union-find over edges with a Python loop over saddles.
def _ref_classify(S, rank):
    E = S.E
    hi0 = rank[E[:, 0]] > rank[E[:, 1]]
    top = np.where(hi0, E[:, 0], E[:, 1])
    bottom = np.where(hi0, E[:, 1], E[:, 0])
    lv = np.bincount(top, minlength=S.n)
    ftop = S.F[np.arange(len(S.F)), np.argmax(rank[S.F], axis=1)]
    le = np.bincount(ftop, minlength=S.n)
    minima = S.used & (lv == 0)
    maxima = S.used & ~S.boundary & (lv == S.degree)
    mult = np.where(minima | maxima, 0, np.maximum(lv - le - 1, 0))
    return top, bottom, mult, minima, maxima


def _ref_jump(parent):
    while True:
        nxt = parent[parent]
        if np.array_equal(nxt, parent):
            return parent
        parent = nxt


def _ref_sweep(rank, top, bottom, merge):
    N = len(rank)
    vertex_of_rank = np.empty(N, np.int64)
    vertex_of_rank[rank] = np.arange(N)
    sel = ~merge[top]
    best = np.full(N, N, np.int64)
    np.minimum.at(best, top[sel], rank[bottom[sel]])
    parent = np.arange(N)
    has = best < N
    parent[has] = vertex_of_rank[best[has]]
    parent = _ref_jump(parent)
    sel = merge[top]
    ts, bs = top[sel], parent[bottom[sel]]
    o = np.argsort(rank[ts], kind="stable")
    ts, bs = ts[o], bs[o]
    uf, creators, destroyers = list(range(N)), [], []
    for s in np.unique(ts)[np.argsort(rank[np.unique(ts)])].tolist() if len(ts) else []:
        roots = set()
        for u in bs[ts == s].tolist():
            while uf[u] != u:
                u = uf[u]
            roots.add(u)
        elder = min(roots, key=lambda r: rank[r])
        for r in roots - {elder}:
            creators.append(r)
            destroyers.append(s)
            uf[r] = elder
        uf[s] = elder
    root = _ref_jump(np.asarray(uf, dtype=np.int64))[parent]
    return np.asarray(creators, np.int64), np.asarray(destroyers, np.int64), root


def reference_critical(S, f):
    rank = np.argsort(np.argsort(f, kind="stable"))
    _, _, mult, minima, maxima = _ref_classify(S, rank)
    saddles = np.flatnonzero(mult > 0)
    return np.flatnonzero(minima), saddles, mult[saddles], np.flatnonzero(maxima)


def reference_persistence(S, f):
    """(pairs, dimension, essential, essential_dimension) as the previous implementation made them."""
    n = S.n
    rank = np.argsort(np.argsort(f, kind="stable"))
    top, bottom, mult, _, _ = _ref_classify(S, rank)
    merge = mult > 0
    c0, d0, root0 = _ref_sweep(rank, top, bottom, merge)
    bverts = np.flatnonzero(S.boundary)
    c1, d1, root1 = _ref_sweep(np.append(n - rank, 0), np.concatenate([bottom, bverts]),
                               np.concatenate([top, np.full(len(bverts), n)]), np.append(merge, False))
    ess_min = np.unique(root0[:n][S.used])
    ess_max = np.unique(root1[:n][S.used])
    ess_max = ess_max[ess_max != n]
    left = mult - np.bincount(np.concatenate([d0, d1]), minlength=n)
    assert np.all(left >= 0)
    pairs = np.concatenate([np.stack([c0, d0], 1), np.stack([c1, d1], 1)]).reshape(-1, 2)
    dim = np.concatenate([np.zeros(len(c0), np.int8), np.ones(len(c1), np.int8)])
    pers = np.abs(f[pairs[:, 1]] - f[pairs[:, 0]])
    o = np.lexsort((pairs[:, 1], pairs[:, 0], -pers, dim))
    essential = np.concatenate([ess_min, np.repeat(np.arange(n), left), ess_max])
    edim = np.repeat([0, 1, 2], [len(ess_min), int(left.sum()), len(ess_max)])
    return pairs[o], dim[o], essential, edim


def moebius(nu=16, nv=3):
    """A Möbius strip: non-orientable, one boundary curve, χ = 0."""
    u = np.arange(nu) * 2 * np.pi / nu
    w = np.linspace(-0.3, 0.3, nv)
    V = np.array([[(1 + s * np.cos(a / 2)) * np.cos(a), (1 + s * np.cos(a / 2)) * np.sin(a),
                   s * np.sin(a / 2)] for a in u for s in w])
    F = []
    for i in range(nu):
        for j in range(nv - 1):
            a, b = i * nv + j, i * nv + j + 1
            if i + 1 < nu:
                c, d = a + nv, b + nv
            else:  # the half twist: the strip comes back upside down
                c, d = nv - 1 - j, nv - 2 - j
            F += [[a, c, d], [a, d, b]]
    return V, np.array(F)


def bipyramid(k=200):
    """A sphere with two vertices of degree k, numbered first (0 and 1): the lower end of all
    their edges, which exercises the high-degree path of the edge sort."""
    ang = 2 * np.pi * np.arange(k) / k
    V = np.concatenate([[[0, 0, 1.0], [0, 0, -1.0]], np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], 1)])
    F = [[2 + i, 2 + (i + 1) % k, 0] for i in range(k)] + [[2 + (i + 1) % k, 2 + i, 1] for i in range(k)]
    return V, np.array(F)


def several():
    """Four components: a sphere, a disk, an annulus and a Möbius strip, numbered interleaved."""
    parts = [icosphere(1), grid(1.0, 1.0, 4, 3), annulus(), moebius(8, 3)]
    V = np.concatenate([p[0] + 3.0 * i for i, p in enumerate(parts)])
    offs = np.cumsum([0] + [len(p[0]) for p in parts])
    F = np.concatenate([p[1] + o for p, o in zip(parts, offs, strict=False)])  # offs ends with the total
    perm = np.random.default_rng(0).permutation(len(V))  # a component is not a block of indices
    inv = np.argsort(perm)
    return V[perm], inv[F]


RANDOM_MESHES = {"sphere": icosphere(1), "torus": torus(1.0, 0.4, 9, 6), "disk": grid(1.0, 1.0, 5, 4),
                 "annulus": annulus(), "genus2": genus2(), "moebius": moebius(), "bipyramid": bipyramid(40),
                 "several": several()}


def field_strategy():
    from hypothesis import strategies as st

    def values(kind, n, seed):
        rng = np.random.default_rng(seed)
        if kind == "normal":
            return rng.standard_normal(n)
        if kind == "few levels":  # plateaus: ties everywhere, resolved by the vertex index
            return rng.integers(0, 3, n).astype(float)
        if kind == "two levels":
            return (rng.random(n) < 0.5).astype(float)
        if kind == "constant":
            return np.zeros(n)
        return np.round(rng.standard_normal(n), 1)  # "rounded": some ties

    return st.tuples(st.sampled_from(sorted(RANDOM_MESHES)),
                     st.sampled_from(["normal", "few levels", "two levels", "constant", "rounded"]),
                     st.integers(0, 2**32 - 1)).map(
        lambda t: (t[0], t[1], values(t[1], len(RANDOM_MESHES[t[0]][0]), t[2])))


def reference_edges(F, n):
    """Unique edges, faces per edge and the edge of each half-edge, by sorting keys (numpy)."""
    a, b = F.reshape(-1), F[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * n + np.maximum(a, b)
    uk, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return np.stack([uk // n, uk % n], 1), counts, inv.reshape(-1, 3)


def brute_bad_fans(F, n):
    """Vertices whose faces form several fans (faces joined across edges through the vertex)."""
    bad = 0
    for v in range(n):
        faces = [t for t in F.tolist() if v in t]
        if not faces:
            continue
        comp = list(range(len(faces)))

        def root(i, comp=comp):  # this vertex's list (bound now: the loop rebinds the name)
            while comp[i] != i:
                i = comp[i]
            return i

        for i, j in itertools.combinations(range(len(faces)), 2):
            if len(set(faces[i]) & set(faces[j])) == 2:  # they share an edge, which contains v
                comp[root(i)] = root(j)
        bad += len({root(i) for i in range(len(faces))}) > 1
    return bad
