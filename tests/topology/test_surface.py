"""o3dheat.topology.surface: the Surface's tables, mesh inputs, manifold checks, repairs and welding."""

import logging

import numpy as np
import open3d as o3d
import pytest
from conftest import grid, icosphere, irregular, torus
from topology_cases import RANDOM_MESHES, brute_bad_fans, reference_edges, reference_persistence

import o3dheat
from o3dheat.topology import Surface


def test_mesh_inputs_agree():
    m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.4, 30, 15)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    f = V[:, 0] + np.sin(5 * V[:, 1])
    ref = o3dheat.critical_points((V, F), f)
    for mesh in (m, m.to_legacy(), Surface(m)):
        cp = o3dheat.critical_points(mesh, f)
        assert cp.same_as(ref)
        assert len(o3dheat.persistence(mesh, f)) == len(o3dheat.persistence((V, F), f))


def test_bad_fields():
    V, F = icosphere(1)
    for f, msg in [(np.zeros(len(V) + 1), "one value per vertex"), (np.full(len(V), np.nan), "NaN"),
                   (np.zeros((len(V), 2)), "one value per vertex"), (np.array(["a"] * len(V)), "numeric")]:
        for fn in (o3dheat.critical_points, o3dheat.persistence):
            with pytest.raises(o3dheat.MeshError, match=msg):
                fn((V, F), f)


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


@pytest.mark.parametrize("name", list(RANDOM_MESHES))
def test_surface_tables(name):
    V, F = RANDOM_MESHES[name]
    S = Surface((V, F))
    E, counts, fe = reference_edges(S.F, S.n)
    np.testing.assert_array_equal(S.E, E)
    np.testing.assert_array_equal(S.boundary_edge, counts == 1)
    np.testing.assert_array_equal(S.face_edges, fe)
    np.testing.assert_array_equal(S.degree, np.bincount(E.reshape(-1), minlength=S.n))
    for v in range(S.n):  # the adjacency lists every neighbour once
        nb = S._adj[S._ptr[v]:S._ptr[v + 1]]
        want = np.concatenate([E[E[:, 0] == v, 1], E[E[:, 1] == v, 0]])
        assert sorted(nb.tolist()) == sorted(want.tolist())


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
        bad = brute_bad_fans(F, len(V))
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


@pytest.mark.parametrize("name", list(RANDOM_MESHES))
def test_adjacency_is_in_link_order(name):
    """Issue 31: each vertex's neighbours go round its link: consecutive ones span a face with it,
    and so do the last and the first unless it is on the boundary; faces turned over too."""
    V, F = RANDOM_MESHES[name]
    rng = np.random.default_rng(1)
    for flip in (np.zeros(len(F), bool), rng.random(len(F)) < 0.5):
        F2 = F.copy()
        F2[flip] = F2[flip][:, ::-1]
        S = Surface((V, F2))
        faces = {frozenset(t) for t in F2.tolist()}
        ptr, adj = S.adjacency
        for v in np.flatnonzero(S.used):
            nb = adj[ptr[v]:ptr[v + 1]].tolist()
            spans = list(zip(nb, nb[1:] + nb[:1], strict=True))[: len(nb) - 1 if S.boundary[v] else len(nb)]
            assert all(frozenset((v, a, b)) in faces for a, b in spans), (name, v)
            assert len(set(nb)) == len(nb)


def test_arrays_and_other_inputs_give_the_same_surface(caplog):
    """The compiled checks of (V, F) arrays (one pass, a hash table for duplicate vertices) give
    what as_arrays and weld_map give: the same errors, the same welding, the same tables."""
    V, F = icosphere(2)
    for bad, msg in [(np.where(np.arange(len(V))[:, None] == 3, np.nan, V), "NaN or infinite"),
                     (V * 1e101, "the mesh spans"), (V * 1e-101, "the mesh spans")]:
        with pytest.raises(o3dheat.MeshError, match=msg):
            Surface((bad, F))
    for badF in (np.where(F == 5, len(V), F), np.where(F == 5, -1, F)):
        with pytest.raises(o3dheat.MeshError, match="face indices out of range"):
            Surface((V, badF))
    # a split copy of every vertex of one face, with -0.0 for 0.0: welded, as by weld_map
    V2 = np.concatenate([V, V[F[0]] * np.where(V[F[0]] == 0, -1.0, 1.0)])
    F2 = F.copy()
    F2[0] = len(V) + np.arange(3)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        S = Surface((V2, F2))
    assert "welded 3 duplicate" in caplog.text
    np.testing.assert_array_equal(S.representative, np.concatenate([np.arange(len(V)), F[0]]))
    for mesh in [(V2, F2.astype(np.int32)), [V2, F2], (V2.astype(np.float32).astype(float), F2)]:
        S2 = Surface(mesh)
        np.testing.assert_array_equal(S2.representative, S.representative)
        np.testing.assert_array_equal(S2.F, S.F)
        np.testing.assert_array_equal(S2.adjacency[1], S.adjacency[1])
    assert Surface((V, F)).representative is None
