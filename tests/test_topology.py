"""Critical points, persistence, simplification and level sets (PAPER.md rows P12, P15, P16)."""

import itertools
import logging

import numpy as np
import open3d as o3d
import pytest
from conftest import grid, icosphere, irregular, torus

import o3dheat
from o3dheat.topology import Surface


# ------------------------------------------------------------------------------------ meshes
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


# --------------------------------------------------------------------- brute-force references
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


# ------------------------------------------------------------------------------------ tests
def test_upright_torus_height_function():
    mesh, h = upright_torus_height()
    cp = o3dheat.critical_points(mesh, h)
    assert cp.counts == (1, 2, 1)
    V = mesh[0]
    assert V[cp.minima[0], 0] == V[:, 0].min() and V[cp.maxima[0], 0] == V[:, 0].max()
    assert np.allclose(np.abs(V[cp.saddles, 0]), 0.6, atol=0.02)  # the inner equator R - r


@pytest.mark.parametrize("name", list(SURFACES))
def test_morse_count_equals_euler_characteristic(name, caplog):
    (V, F), chi = SURFACES[name]
    assert Surface((V, F)).euler_characteristic == chi
    for _, f in fields(len(V), 1):
        with caplog.at_level(logging.WARNING, logger="o3dheat"):
            cp = o3dheat.critical_points((V, F), f)
        assert cp.euler_characteristic == chi


@pytest.mark.parametrize("name", ["sphere", "torus", "disk", "annulus", "irregular"])
def test_critical_points_match_brute_force(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 2):
        cp = o3dheat.critical_points((V, F), f)
        ref = brute_critical(F, f)
        assert cp.minima.tolist() == sorted(ref["min"]), label
        assert cp.maxima.tolist() == sorted(ref["max"]), label
        assert dict(zip(cp.saddles.tolist(), cp.saddle_multiplicity.tolist(), strict=True)) == ref["saddle"], label


def test_monkey_saddle_has_multiplicity_two():
    # a vertex whose cyclic link alternates low/high three times: Re((x + iy)^3)
    k = 12
    ang = 2 * np.pi * np.arange(k) / k
    V = np.concatenate([[[0, 0, 0]], np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], 1)])
    F = np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)])
    f = np.concatenate([[0.0], np.cos(3 * ang)])
    cp = o3dheat.critical_points((V, F), f)
    assert cp.saddles.tolist() == [0] and cp.saddle_multiplicity.tolist() == [2]
    assert cp.euler_characteristic == 1  # a disk


def test_boundary_rule():
    V, F = grid(2.0, 1.0, 12, 8)  # a disk, χ = 1
    cp = o3dheat.critical_points((V, F), V[:, 0] + 0.1 * V[:, 1])  # a tilted plane
    # the minimum is the lowest boundary corner; the highest corner is regular (boundary maximum)
    assert cp.counts == (1, 0, 0)
    assert cp.minima.tolist() == [int(np.argmin(V[:, 0] + 0.1 * V[:, 1]))]
    # a boundary vertex with two lower runs along its path is a saddle: a valley on each side
    cp = o3dheat.critical_points((V, F), -np.abs(V[:, 0] - 1.0) + 0.01 * V[:, 1])
    assert cp.counts[1] >= 1 and cp.euler_characteristic == 1


@pytest.mark.parametrize("name", list(SURFACES))
def test_persistence_accounts_for_every_critical_point(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 3):
        cp = o3dheat.critical_points((V, F), f)
        d = o3dheat.persistence((V, F), f)
        want = np.zeros(len(V), int)
        want[cp.minima] += 1
        want[cp.maxima] += 1
        np.add.at(want, cp.saddles, cp.saddle_multiplicity)
        got = np.bincount(np.concatenate([d.pairs.reshape(-1), d.essential]), minlength=len(V))
        assert np.array_equal(got, want), label
        kinds = cp.kind
        assert np.all(kinds[d.pairs[d.dimension == 0, 0]] == 1)  # minimum - saddle
        assert np.all(kinds[d.pairs[d.dimension == 1, 0]] == 3)  # maximum - saddle
        assert np.all(kinds[d.pairs[:, 1]] == 2)
        assert tuple(np.bincount(d.essential_dimension, minlength=3)) == ESSENTIAL[name], label
        assert np.all(d.persistence >= 0) and np.allclose(d.persistence, np.abs(d.death - d.birth))


@pytest.mark.parametrize("name", ["sphere", "torus", "annulus", "disk"])
def test_persistence_matches_matrix_reduction(name):
    (V, F), _ = SURFACES[name]
    rng = np.random.default_rng(4)
    f = rng.standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    ours = sorted((0, int(a), int(b)) for a, b in d.pairs[d.dimension == 0])
    ours += sorted((1, int(b), int(a)) for a, b in d.pairs[d.dimension == 1])  # (saddle, max)
    assert sorted(ours) == sorted(brute_persistence(F, f))


def _gudhi_diagrams(F, f):
    gudhi = pytest.importorskip("gudhi")
    st = gudhi.SimplexTree()
    used = np.unique(F)  # unreferenced vertices are not part of the surface
    st.insert_batch(used[None, :], f[used])
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [0, 2]]]), axis=1), axis=0)
    st.insert_batch(E.T, f[E].max(axis=1))
    st.insert_batch(F.T, f[F].max(axis=1))
    st.compute_persistence(homology_coeff_field=2, min_persistence=-1, persistence_dim_max=True)
    return [st.persistence_intervals_in_dimension(k) for k in (0, 1, 2)]


def _finite(D):
    D = D[np.isfinite(D[:, 1])] if len(D) else D.reshape(0, 2)
    D = D[D[:, 1] > D[:, 0]]
    return D[np.lexsort((D[:, 1], D[:, 0]))]


@pytest.mark.parametrize("name", list(SURFACES))
def test_persistence_matches_gudhi(name):
    (V, F), _ = SURFACES[name]
    for label, f in fields(len(V), 5):
        g = _gudhi_diagrams(F, f)
        d = o3dheat.persistence((V, F), f)
        D0 = _finite(d.intervals(0))
        D1 = _finite(d.intervals(1)[:, ::-1])  # read as sublevel (saddle, maximum)
        assert np.array_equal(D0, _finite(g[0])), label
        assert np.array_equal(D1, _finite(g[1])), label
        # essential classes: components, 1-cycles, closed components
        inf = [int(np.sum(~np.isfinite(x[:, 1]))) if len(x) else 0 for x in g]
        assert tuple(inf) == ESSENTIAL[name], label


def test_persistence_is_stable():
    gudhi = pytest.importorskip("gudhi")
    V, F = irregular()
    rng = np.random.default_rng(6)
    f = V[:, 0] + 0.2 * rng.standard_normal(len(V))
    for eps in (1e-3, 1e-2, 0.1):
        e = eps * rng.uniform(-1, 1, len(V))
        d1, d2 = o3dheat.persistence((V, F), f), o3dheat.persistence((V, F), f + e)
        for k in (0, 1):
            assert gudhi.bottleneck_distance(d1.intervals(k), d2.intervals(k)) <= np.abs(e).max() + 1e-12


def test_simplification_is_monotone_and_keeps_essentials():
    V, F = irregular()
    f = V[:, 2] + 0.05 * np.random.default_rng(7).standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    cp = o3dheat.critical_points((V, F), f)
    all_critical = np.unique(np.concatenate([cp.minima, cp.saddles, cp.maxima]))
    assert np.array_equal(o3dheat.simplify_critical_points((V, F), f), all_critical)
    prev = None
    for delta in np.linspace(0, d.persistence.max() * 1.01, 12):
        keep = o3dheat.simplify_critical_points((V, F), f, delta=delta, diagram=d)
        assert set(d.essential) <= set(keep)
        if prev is not None:
            assert set(keep) <= set(prev)
        prev = keep
    assert set(prev) == set(d.essential)
    sizes = [len(o3dheat.simplify_critical_points((V, F), f, keep_fraction=q, diagram=d))
             for q in (0.0, 0.1, 0.5, 1.0)]
    assert sizes == sorted(sizes) and sizes[-1] == len(all_critical)


@pytest.mark.parametrize("kwargs", [dict(delta=-1.0), dict(delta=np.nan), dict(keep_fraction=1.5),
                                    dict(delta=0.1, keep_fraction=0.5), dict(diagram="no")])
def test_simplification_bad_arguments(kwargs):
    V, F = icosphere(1)
    with pytest.raises(o3dheat.MeshError):
        o3dheat.simplify_critical_points((V, F), V[:, 0], **kwargs)


def test_mesh_inputs_agree():
    m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.4, 30, 15)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    f = V[:, 0] + np.sin(5 * V[:, 1])
    ref = o3dheat.critical_points((V, F), f)
    for mesh in (m, m.to_legacy(), Surface(m)):
        cp = o3dheat.critical_points(mesh, f)
        assert cp.same_as(ref)
        assert len(o3dheat.persistence(mesh, f)) == len(o3dheat.persistence((V, F), f))


# ------------------------------------------------------------------------------- bad input
def test_bad_fields():
    V, F = icosphere(1)
    for f, msg in [(np.zeros(len(V) + 1), "one value per vertex"), (np.full(len(V), np.nan), "NaN"),
                   (np.zeros((len(V), 2)), "one value per vertex"), (np.array(["a"] * len(V)), "numeric")]:
        for fn in (o3dheat.critical_points, o3dheat.persistence):
            with pytest.raises(o3dheat.MeshError, match=msg):
                fn((V, F), f)


def test_constant_field_is_documented_behaviour(caplog):
    V, F = torus(1.0, 0.4, 24, 12)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        cp = o3dheat.critical_points((V, F), np.ones(len(V)))
    assert "constant" in caplog.text and cp.euler_characteristic == 0
    d = o3dheat.persistence((V, F), np.ones(len(V)))
    assert np.all(d.persistence == 0)


def test_non_manifold_meshes_are_refused():
    V, F = icosphere(1)
    # an edge with three faces: a fin on the sphere
    a, b = F[0, 0], F[0, 1]
    V2 = np.concatenate([V, [[3.0, 3.0, 3.0]]])
    with pytest.raises(o3dheat.MeshError, match="non-manifold"):
        o3dheat.critical_points((V2, np.concatenate([F, [[a, b, len(V)]]])), V2[:, 0])
    # two spheres sharing one vertex: a pinched (non-manifold) vertex
    F2 = F + len(V) - 1
    F2[F2 == len(V) - 1] = 0
    F2[F2 == 2 * len(V) - 1] = len(V) - 1
    Vb = np.concatenate([V, V[1:] + 5.0])
    with pytest.raises(o3dheat.MeshError, match="non-manifold"):
        o3dheat.persistence((Vb, np.concatenate([F, F2])), Vb[:, 0])


def test_unreferenced_and_degenerate(caplog):
    V, F = icosphere(1)
    V2 = np.concatenate([V, [[9.0, 9.0, 9.0]]])  # an isolated vertex: never critical
    F2 = np.concatenate([F, [[0, 0, 1]], F[:1]])  # a degenerate and a duplicate face
    f = np.append(V[:, 2], -100.0)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        cp = o3dheat.critical_points((V2, F2), f)
    assert "degenerate" in caplog.text and "duplicate" in caplog.text
    assert len(V) not in cp.minima and cp.euler_characteristic == 2


# -------------------------------------------------------------------------------- level sets
def test_level_sets_of_the_height_on_a_sphere():
    V, F = icosphere(3)
    ls = o3dheat.level_sets((V, F), V[:, 2], values=[0.0, 0.5])
    P, L = np.asarray(ls.points), np.asarray(ls.lines)
    assert len(L) > 0 and np.all(np.isin(np.round(P[:, 2], 12), [0.0, 0.5]))
    # each level set is a closed curve: every point is the end of exactly two segments
    assert np.all(np.bincount(L.reshape(-1), minlength=len(P)) == 2)
    length = np.linalg.norm(P[L[:, 0]] - P[L[:, 1]], axis=1)
    eq = np.abs(P[L[:, 0], 2]) < 1e-12
    assert abs(length[eq].sum() - 2 * np.pi) < 0.05  # the equator of the unit sphere
    assert len(o3dheat.level_sets((V, F), V[:, 2], count=5).lines) > len(L)


def test_level_sets_bad_input():
    V, F = icosphere(1)
    for kwargs in (dict(values=[np.nan]), dict(count=0), dict(values=[0.0], count=3)):
        with pytest.raises(o3dheat.MeshError):
            o3dheat.level_sets((V, F), V[:, 2], **kwargs)
    assert len(o3dheat.level_sets((V, F), V[:, 2], values=[5.0]).lines) == 0


# ---------------------------------------------------------------- unwelded meshes (issue 13)
@pytest.mark.parametrize("mesh", [torus(1.0, 0.4, 24, 12), grid(1, 1, 9, 7), irregular()])
def test_split_vertex_mesh_topology_equals_welded(mesh, caplog):
    V, F = mesh
    Vs, Fs = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)  # an STL file's soup
    _, first, inv = np.unique(Vs, axis=0, return_index=True, return_inverse=True)
    keep = np.sort(first)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    w = rank[inv.reshape(-1)]
    welded = (Vs[keep], w[Fs])
    f = np.sin(4 * welded[0][:, 0]) + welded[0][:, 2] + 0.1 * welded[0][:, 1] ** 2
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        S = Surface((Vs, Fs))
    assert "welded" in caplog.text
    np.testing.assert_array_equal(S.representative, keep[w])
    assert S.euler_characteristic == Surface(welded).euler_characteristic
    assert S.components == 1
    cu, cw = o3dheat.critical_points((Vs, Fs), f[w]), o3dheat.critical_points(welded, f)
    assert cu.counts == cw.counts and cu.euler_characteristic == cw.euler_characteristic
    np.testing.assert_array_equal(cu.minima, keep[cw.minima])
    np.testing.assert_array_equal(cu.saddles, keep[cw.saddles])
    np.testing.assert_array_equal(cu.maxima, keep[cw.maxima])
    np.testing.assert_array_equal(cu.kind, cw.kind[w])  # per input vertex: every copy labelled
    du, dw = o3dheat.persistence((Vs, Fs), f[w]), o3dheat.persistence(welded, f)
    np.testing.assert_array_equal(du.pairs, keep[dw.pairs])
    np.testing.assert_array_equal(du.persistence, dw.persistence)
    np.testing.assert_array_equal(du.essential, keep[dw.essential])
    np.testing.assert_array_equal(o3dheat.simplify_critical_points((Vs, Fs), f[w], keep_fraction=0.3),
                                  keep[o3dheat.simplify_critical_points(welded, f, keep_fraction=0.3)])
    # a field that differs between copies: their mean is used
    g = np.random.default_rng(0).standard_normal(len(Vs))
    mean = np.bincount(w, g) / np.bincount(w)
    assert o3dheat.critical_points((Vs, Fs), g).counts == o3dheat.critical_points(welded, mean).counts
    # the spectrum's faces (first copies) give the welded answer too
    spec = o3dheat.eigensolve((Vs, Fs), k=8)
    cs = o3dheat.critical_points(Surface.from_faces(spec.n, spec.faces), f[w])
    assert cs.counts == cw.counts


def test_critical_points_filter_on_split_mesh():
    V, F = torus(1.0, 0.4, 24, 12)
    Vs, Fs = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(Vs)
    m.triangle.indices = o3d.core.Tensor(Fs.astype(np.int32))
    mw = o3d.t.geometry.TriangleMesh()
    mw.vertex.positions = o3d.core.Tensor(V)
    mw.triangle.indices = o3d.core.Tensor(F.astype(np.int32))
    for kw in ({}, {"delta": 0.05}):
        a = o3dheat.pipelines.filters.apply(m, "critical_points", attribute="positions", column=0, **kw)
        b = o3dheat.pipelines.filters.apply(mw, "critical_points", attribute="positions", column=0, **kw)
        np.testing.assert_array_equal(a.vertex["positions_critical"].numpy(),
                                      b.vertex["positions_critical"].numpy()[F].reshape(-1))


# ------------------------------------------------- the compiled loops against the previous code
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


def _field_strategy():
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


def test_hypothesis_same_as_previous_implementation_and_gudhi():
    """Critical points and persistence equal the previous implementation's, pair for pair, and the
    finite diagrams equal gudhi's, on random fields with ties and plateaus, on surfaces with
    boundaries, several components, non-orientable ones and high-degree vertices."""
    from hypothesis import HealthCheck, given, settings

    @settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(_field_strategy())
    def check(case):
        name, _, f = case
        V, F = RANDOM_MESHES[name]
        S = Surface((V, F))
        cp = o3dheat.critical_points(S, f)
        mins, sads, mult, maxs = reference_critical(S, f)
        assert np.array_equal(cp.minima, mins) and np.array_equal(cp.maxima, maxs)
        assert np.array_equal(cp.saddles, sads) and np.array_equal(cp.saddle_multiplicity, mult)
        assert cp.euler_characteristic == S.euler_characteristic
        d = o3dheat.persistence(S, f)
        pairs, dim, ess, edim = reference_persistence(S, f)
        np.testing.assert_array_equal(d.pairs, pairs)
        np.testing.assert_array_equal(d.dimension, dim)
        np.testing.assert_array_equal(d.essential, ess)
        np.testing.assert_array_equal(d.essential_dimension, edim)
        np.testing.assert_array_equal(d.birth, f[pairs[:, 0]])
        np.testing.assert_array_equal(d.death, f[pairs[:, 1]])
        g = _gudhi_diagrams(F, f)
        assert np.array_equal(_finite(d.intervals(0)), _finite(g[0]))
        assert np.array_equal(_finite(d.intervals(1)[:, ::-1]), _finite(g[1]))

    check()


def test_generic_fields_follow_a_renumbering():
    """Without ties, the diagram does not depend on the vertex numbering."""
    rng = np.random.default_rng(11)
    for name in ("torus", "annulus", "several"):
        V, F = RANDOM_MESHES[name]
        f = rng.standard_normal(len(V))
        perm = rng.permutation(len(V))  # new vertex i is old vertex perm[i]
        inv = np.argsort(perm)
        d, dp = o3dheat.persistence((V, F), f), o3dheat.persistence((V[perm], inv[F]), f[perm])
        assert sorted(map(tuple, d.pairs.tolist())) == sorted(map(tuple, perm[dp.pairs].tolist()))
        assert sorted(d.essential.tolist()) == sorted(perm[dp.essential].tolist())


def _reference_edges(F, n):
    """Unique edges, faces per edge and the edge of each half-edge, by sorting keys (numpy)."""
    a, b = F.reshape(-1), F[:, [1, 2, 0]].reshape(-1)
    key = np.minimum(a, b) * n + np.maximum(a, b)
    uk, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    return np.stack([uk // n, uk % n], 1), counts, inv.reshape(-1, 3)


@pytest.mark.parametrize("name", list(RANDOM_MESHES))
def test_surface_tables(name):
    V, F = RANDOM_MESHES[name]
    S = Surface((V, F))
    E, counts, fe = _reference_edges(S.F, S.n)
    np.testing.assert_array_equal(S.E, E)
    np.testing.assert_array_equal(S.boundary_edge, counts == 1)
    np.testing.assert_array_equal(S.face_edges, fe)
    np.testing.assert_array_equal(S.degree, np.bincount(E.reshape(-1), minlength=S.n))
    for v in range(S.n):  # the adjacency lists every neighbour once
        nb = S._adj[S._ptr[v]:S._ptr[v + 1]]
        want = np.concatenate([E[E[:, 0] == v, 1], E[E[:, 1] == v, 0]])
        assert sorted(nb.tolist()) == sorted(want.tolist())


def test_high_degree_vertex_is_classified():
    V, F = bipyramid(200)
    f = V[:, 0] + 0.01 * V[:, 2] + 0.001 * np.arange(len(V))
    cp = o3dheat.critical_points((V, F), f)
    ref = brute_critical(F, f)
    assert cp.minima.tolist() == sorted(ref["min"]) and cp.maxima.tolist() == sorted(ref["max"])
    assert dict(zip(cp.saddles.tolist(), cp.saddle_multiplicity.tolist(), strict=True)) == ref["saddle"]
    # the apexes see the whole cycle: sin(3θ) alternates six times, a saddle of multiplicity 2
    g = np.concatenate([[0.0, 0.0], np.sin(3 * 2 * np.pi * np.arange(200) / 200)])
    cp = o3dheat.critical_points((V, F), g)
    assert cp.saddles[:2].tolist() == [0, 1] and cp.saddle_multiplicity[:2].tolist() == [2, 2]
    S = Surface((V, F))
    np.testing.assert_array_equal(S.E, _reference_edges(S.F, S.n)[0])
    assert S.degree[:2].tolist() == [200, 200]


def _brute_bad_fans(F, n):
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


def test_hypothesis_fan_check_on_random_face_subsets():
    """Random holes punched in a sphere and a grid: pinched vertices are found, and only them."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    meshes = [icosphere(1), grid(1.0, 1.0, 5, 5)]

    @settings(max_examples=60, deadline=None)
    @given(st.integers(0, 1), st.integers(0, 2**32 - 1), st.floats(0.05, 0.6))
    def check(which, seed, drop):
        V, F = meshes[which]
        F = F[np.random.default_rng(seed).random(len(F)) >= drop]
        if len(F) == 0:
            return
        bad = _brute_bad_fans(F, len(V))
        if bad:
            with pytest.raises(o3dheat.MeshError, match=f"^{bad} vertices are non-manifold"):
                Surface.from_faces(len(V), F)
        else:
            S = Surface.from_faces(len(V), F)
            f = np.random.default_rng(seed).standard_normal(len(V))
            d = o3dheat.persistence(S, f)
            pairs, dim, ess, edim = reference_persistence(S, f)
            np.testing.assert_array_equal(d.pairs, pairs)
            np.testing.assert_array_equal(d.essential, ess)

    check()


def test_too_many_vertices_are_refused():
    with pytest.raises(o3dheat.MeshError, match="at most"):
        Surface.from_faces(2**31, np.array([[0, 1, 2]]))


def test_compiled_loops_are_cached():
    """The numba cache of the compiled loops is written (beside the module, or NUMBA_CACHE_DIR),
    so that only the first call of an installation compiles."""
    from pathlib import Path

    from o3dheat.topology._loops import LOOPS, kernel

    V, F = icosphere(1)
    o3dheat.persistence((V, F), V[:, 0])
    for name in LOOPS:
        k = kernel(name)
        assert k.signatures, name
        assert Path(k._cache._cache_file._index_path).is_file(), name


def test_compiled_in_this_process_says_whether_the_loops_were_compiled_or_loaded(tmp_path):
    import os
    import subprocess
    import sys

    code = ("import open3d as o3d, o3dheat, o3dheat.topology as T;"
            "m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8);"
            "o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 2]);"
            "print(T.compiled_in_this_process())")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    # a cache folder of its own: numba uses it only when the module's own folder is not writable,
    # so compare a first run with a second one (the second loads what the first wrote or found)
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert first.returncode == 0 and second.returncode == 0, first.stderr[-500:] + second.stderr[-500:]
    assert first.stdout.strip() in ("True", "False")
    assert second.stdout.strip() == "False"  # cached by then


def test_compiled_in_this_process_counts_cache_misses(monkeypatch):
    import types

    import o3dheat._jit as J
    import o3dheat.topology.critical as T

    def fake(misses):
        return types.SimpleNamespace(stats=types.SimpleNamespace(cache_misses={("sig",): misses}))

    mod = "o3dheat.topology._loops"
    monkeypatch.setattr(J, "_COMPILED", {(mod, "a"): fake(0), (mod, "b"): fake(0), ("other", "c"): fake(1)})
    assert T.compiled_in_this_process() is False  # another module's compilation is not this one's
    monkeypatch.setattr(J, "_COMPILED", {(mod, "a"): fake(0), (mod, "b"): fake(1)})
    assert T.compiled_in_this_process() is True


def test_warm_up_loads_every_compiled_loop():
    """topology.warm_up() (run by each Dask worker at start) leaves no loop to load in a task."""
    import subprocess
    import sys

    code = ("import o3dheat.topology.critical as T, o3dheat._jit as J; T.warm_up(); "
            "print(sorted(name for mod, name in J._COMPILED if mod == 'o3dheat.topology._loops'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == str(sorted(["arcs", "classify", "fans", "number_edges", "sorted_half_edges",
                                                       "sweeps"]))


def test_critical_points_have_a_length_the_number_of_critical_vertices():
    """Issue 22: CriticalPoints had no len(). len counts vertices; counts weigh saddles by
    multiplicity (a monkey saddle: one vertex, multiplicity 2)."""
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh.create_torus()
    cp = o3dheat.critical_points(m, m.vertex.positions.numpy()[:, 0])
    assert len(cp) == 4 == sum(cp.counts) and len(cp) == int((cp.kind > 0).sum())
    # a monkey saddle: Re (x + iy)^3 at the centre of a fan of 6 triangles
    ang = np.arange(6) * np.pi / 3
    V = np.vstack([[0, 0, 0], np.c_[np.cos(ang), np.sin(ang), np.zeros(6)]])
    F = np.array([[0, 1 + i, 1 + (i + 1) % 6] for i in range(6)])
    f = np.real((V[:, 0] + 1j * V[:, 1]) ** 3)
    mk = o3dheat.critical_points((V, F), f)
    assert list(mk.saddles) == [0] and mk.saddle_multiplicity.tolist() == [2]
    assert len(mk) == len(mk.minima) + 1 + len(mk.maxima) == sum(mk.counts) - 1
