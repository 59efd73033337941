"""o3dheat.geometry.mesh and welding: conversion, the validation report, the welding every computation applies, and bad input."""

import logging

import numpy as np
import open3d as o3d
import pytest
from conftest import grid, icosphere, torus

import o3dheat
from o3dheat.geometry.welding import prepare


def as_tensor(V, F):
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(V)
    m.triangle.indices = o3d.core.Tensor(F)
    return m


def as_legacy(V, F):
    return o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))


def test_inputs_agree(sphere3):
    V, F = sphere3
    for m in (as_tensor(V, F), as_legacy(V, F), (V, F), [V.tolist(), F.tolist()]):
        V2, F2 = o3dheat.as_arrays(m)
        assert V2.dtype == np.float64 and F2.dtype == np.int64
        np.testing.assert_array_equal(V2, V)
        np.testing.assert_array_equal(F2, F)


def test_as_arrays_copies():
    V, F = icosphere(1)
    V2, _ = o3dheat.as_arrays((V, F))
    V2[0] = 99
    assert V[0, 0] != 99


@pytest.mark.parametrize("mesh, chi, genus, loops", [
    (icosphere(2), 2, 0, 0), (torus(), 0, 1, 0), (grid(), 1, 0, 1)])
def test_report_topology(mesh, chi, genus, loops):
    r = o3dheat.check_mesh(mesh)
    assert (r.euler_characteristic, r.genus, r.boundary_loops, r.components) == (chi, genus, loops, 1)
    assert r.ok and "status: ok" in str(r)


def test_report_genus2_and_components():
    # two tori side by side: 2 components, chi 0
    V, F = torus()
    V2 = np.concatenate([V, V + [5, 0, 0]])
    F2 = np.concatenate([F, F + len(V)])
    r = o3dheat.check_mesh((V2, F2))
    assert r.components == 2 and r.euler_characteristic == 0 and r.genus == 2


def test_report_counts_problems():
    V, F = icosphere(1)
    V = np.concatenate([V, V[:1], [[9.0, 9, 9]]])  # one duplicate vertex, one unreferenced
    F = np.concatenate([F, F[:1], [[0, 0, 1]]])  # a duplicate and a degenerate face
    r = o3dheat.check_mesh((V, F))
    assert r.duplicate_faces == 1 and r.degenerate_faces == 1
    assert r.unreferenced_vertices == 2 and r.duplicate_vertices == 1
    assert not r.ok and "degenerate" in str(r)


def test_non_manifold_edge_reported_and_usable():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # edge 0-1 has three faces
    r = o3dheat.check_mesh((V, F))
    assert r.non_manifold_edges == 1 and r.genus is None
    s = o3dheat.eigensolve((V, F), k=3)  # the FEM sums over all three triangles
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(3), atol=1e-10)


def test_non_manifold_vertex():
    # two triangles touching at one vertex only (a bow tie)
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.0]])
    F = np.array([[0, 1, 2], [0, 3, 4]])
    assert o3dheat.check_mesh((V, F)).non_manifold_vertices == 1


# ----------------------------------------------------------------------------------- bad input
def test_empty_mesh():
    with pytest.raises(o3dheat.MeshError, match="empty"):
        o3dheat.as_arrays((np.zeros((0, 3)), np.zeros((0, 3), int)))
    with pytest.raises(o3dheat.MeshError, match="empty|no vertex"):
        o3dheat.eigensolve(o3d.t.geometry.TriangleMesh(), k=1)


def test_no_faces():
    with pytest.raises(o3dheat.MeshError, match="no faces"):
        o3dheat.eigensolve((np.random.rand(10, 3), np.zeros((0, 3), int)), k=2)


def test_point_cloud_rejected():
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.random.rand(5, 3)))
    with pytest.raises(o3dheat.MeshError, match="point cloud"):
        o3dheat.as_arrays(pcd)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_coordinates(bad):
    V, F = icosphere(1)
    V = V.copy()
    V[3, 1] = bad
    with pytest.raises(o3dheat.MeshError, match="NaN or infinite"):
        o3dheat.eigensolve((V, F), k=2)


@pytest.mark.parametrize("index", [-1, 10**6])
def test_face_index_out_of_range(index):
    V, F = icosphere(1)
    F = F.copy()
    F[0, 0] = index
    with pytest.raises(o3dheat.MeshError, match="out of range"):
        o3dheat.eigensolve((V, F), k=2)


def test_wrong_shapes():
    with pytest.raises(o3dheat.MeshError, match=r"\(n, 3\)"):
        o3dheat.as_arrays((np.zeros((4, 2)), np.array([[0, 1, 2]])))
    with pytest.raises(o3dheat.MeshError, match="triangles"):
        o3dheat.as_arrays((np.zeros((4, 3)), np.array([[0, 1, 2, 3]])))
    with pytest.raises(o3dheat.MeshError, match="expected"):
        o3dheat.as_arrays("mesh.ply")


def test_degenerate_and_duplicate_faces_dropped(caplog):
    V, F = icosphere(2)
    F2 = np.concatenate([F, [[0, 0, 1]], F[:2]])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        p = prepare((V, F2))
    assert len(p.F) == len(F)
    assert "degenerate" in caplog.text and "duplicate" in caplog.text
    a = o3dheat.eigensolve((V, F), k=5).eigenvalues
    b = o3dheat.eigensolve((V, F2), k=5).eigenvalues
    np.testing.assert_allclose(a, b, atol=1e-10)


def test_zero_area_faces_dropped(caplog):
    V, F = grid(1, 1, 4, 4)
    # a sliver with three collinear vertices on the boundary line y = 0
    F2 = np.concatenate([F, [[0, 5, 10]]])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve((V, F2), k=4)
    assert "zero-area" in caplog.text
    assert np.all(np.isfinite(s.eigenvalues))


def test_all_faces_degenerate():
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    with pytest.raises(o3dheat.MeshError, match="degenerate"):
        o3dheat.eigensolve((V, np.array([[0, 1, 2]])), k=1)


def test_unreferenced_vertices_mapped_back(sphere3):
    V, F = sphere3
    V2 = np.concatenate([[[7.0, 7, 7]], V])  # vertex 0 is unreferenced
    F2 = F + 1
    s1 = o3dheat.eigensolve((V, F), k=6)
    s2 = o3dheat.eigensolve((V2, F2), k=6)
    assert s2.eigenvectors.shape == (len(V2), 6)
    np.testing.assert_allclose(s2.eigenvalues, s1.eigenvalues, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(s2.eigenvectors[0], 0)
    np.testing.assert_allclose(s2.eigenvectors.T @ s2.mass @ s2.eigenvectors, np.eye(6), atol=1e-10)
    K = o3dheat.HeatKernel(s2)
    g = K.smooth(np.arange(len(V2), dtype=float), 0.1)
    assert g[0] == 0 and np.all(np.isfinite(g))


def test_duplicate_vertex_reported_and_welded():
    # one face uses a copy of vertex 0 (a seam of one face): welded, it is the sphere again
    V, F = icosphere(2)
    i = int(np.flatnonzero((F == 0).any(axis=1))[0])
    F2 = F.copy()
    F2[i] = np.where(F[i] == 0, len(V), F[i])
    mesh = (np.concatenate([V, V[:1]]), F2)
    r = o3dheat.check_mesh(mesh)
    assert r.duplicate_vertices == 1 and r.welded_vertices == 1 and r.boundary_loops == 0
    assert (r.components, r.euler_characteristic, r.genus) == (1, 2, 0) and not r.ok
    p = prepare(mesh)
    assert p.weld.tolist() == list(range(len(V))) + [0]
    np.testing.assert_array_equal(p.F, F)
    # opt-out: the copy stays apart, on a boundary
    r = o3dheat.check_mesh(mesh, weld=False)
    assert r.welded_vertices == 0 and r.boundary_loops == 1 and r.duplicate_vertices == 1
    assert prepare(mesh, weld=False).weld is None


def split_vertices(V, F):
    """Every face with its own three vertex copies (what an STL file stores)."""
    return V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)


def first_copy_weld(V):
    """Reference weld map: vertices numbered by their first copy (np.unique, not o3dheat)."""
    _, first, inv = np.unique(V, axis=0, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inv.reshape(-1)], np.sort(first)


@pytest.mark.parametrize("mesh", [icosphere(2), torus(), grid(1, 1, 6, 5)])
def test_weld_split_mesh(mesh, caplog):
    V, F = mesh
    Vs, Fs = split_vertices(V, F)
    w, first = first_copy_weld(Vs)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        p = prepare((Vs, Fs))
    assert f"welded {len(Vs) - len(V)} duplicate vertices" in caplog.text
    np.testing.assert_array_equal(p.weld, w)
    np.testing.assert_array_equal(p.keep, first)
    np.testing.assert_array_equal(p.V, Vs[first])
    np.testing.assert_array_equal(p.vertex_map, w)
    assert p.multiplicity.sum() == len(Vs) and len(p.F) == len(F)
    np.testing.assert_array_equal(p.F, w[Fs])  # no face lost, in the input's order
    # expand copies each welded value; restrict takes the mean over the copies
    x = np.arange(len(p.V), dtype=float)
    np.testing.assert_array_equal(p.expand(x), x[w])
    np.testing.assert_array_equal(p.restrict(p.expand(x)), x)
    f = np.random.default_rng(0).standard_normal((len(Vs), 2))
    want = np.stack([np.bincount(w, f[:, j]) / np.bincount(w) for j in range(2)], 1)
    np.testing.assert_allclose(p.restrict(f), want, rtol=1e-13, atol=1e-15)
    # the report: the welded mesh's topology, and not "ok"
    r, r0 = o3dheat.check_mesh((Vs, Fs)), o3dheat.check_mesh(mesh)
    assert (r.components, r.euler_characteristic, r.genus, r.boundary_loops) == \
        (r0.components, r0.euler_characteristic, r0.genus, r0.boundary_loops)
    assert r.welded_vertices == len(Vs) - len(V) and not r.ok
    assert "welded" in str(r) and f"({len(V)} after welding)" in str(r)
    assert o3dheat.check_mesh((Vs, Fs), weld=False).components == len(F)


def test_weld_leaves_unreferenced_copies_and_clean_meshes(sphere3):
    V, F = sphere3
    p = prepare((V, F))
    assert p.weld is None and np.array_equal(p.vertex_map, np.arange(len(V)))
    x = np.arange(len(V), dtype=float)
    assert p.expand(x) is x and p.restrict(x) is x
    # an unreferenced vertex on a referenced one is not welded: it is set aside (value 0)
    p = prepare((np.concatenate([V, V[:1]]), F))
    assert p.weld is None and p.vertex_map[-1] == -1
    s = o3dheat.eigensolve((np.concatenate([V, V[:1]]), F), k=4)
    np.testing.assert_array_equal(s.eigenvectors[-1], 0)


@pytest.mark.parametrize("high", [5, 1000, 10**7])  # 10**7: three columns do not fit one int64 key
def test_unique_rows_matches_numpy(high):
    from o3dheat.geometry._tables import unique_rows as _unique_rows

    A = np.random.default_rng(1).integers(0, high, (500, 3))
    A[300:400] = A[:100]
    want = np.unique(A, axis=0, return_index=True, return_counts=True)
    got = _unique_rows(A, return_index=True, return_counts=True)
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(w, g)
    np.testing.assert_array_equal(_unique_rows(A), want[0])
    assert _unique_rows(np.zeros((0, 3), int)).shape == (0, 3)


@pytest.mark.parametrize("V, F, message", [
    (np.random.default_rng(0).random((10, 2)), np.array([[0, 1, 2]]), "shape \\(n, 3\\)"),
    (np.random.default_rng(0).random((10, 3)), np.array([[0, 1, 2, 3]]), "shape \\(m, 3\\)"),
    (np.random.default_rng(0).random((10, 3)), np.array([[0, 1, 2.5]]), "integers"),
    (np.random.default_rng(0).random((10, 3)), np.array([["a", "b", "c"]]), "integers"),
    ("a", "b", "numeric"),
])
def test_check_mesh_validates_shapes_exactly_as_eigensolve(V, F, message):
    for fn in (o3dheat.check_mesh, lambda m: o3dheat.eigensolve(m, k=2), o3dheat.as_arrays):
        with pytest.raises(o3dheat.MeshError, match=message):
            fn((V, F))


def test_first_copies_match_brute_force_even_when_the_hash_collides_everywhere():
    from o3dheat.geometry._tables import first_copies, first_faces

    g = np.linspace(-1, 1, 41)  # grid-like coordinates: many zero low bits (a weak hash collides)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    np.testing.assert_array_equal(first_copies(P), np.arange(len(P)))
    rng = np.random.default_rng(3)
    Q = np.concatenate([P[:500], P[rng.integers(0, 500, 40)], -0.0 * P[:1]])  # 40 copies, and -0.0
    rng.shuffle(Q)
    first = {}
    expected = np.array([first.setdefault(tuple(q + 0.0), i) for i, q in enumerate(Q)])
    np.testing.assert_array_equal(first_copies(Q), expected)
    for bits in (0, 2):  # a hash of 0 or 2 bits: every row collides, each is compared exactly
        np.testing.assert_array_equal(first_copies(Q, bits=bits), expected)
    R = np.concatenate([Q[:5], [[np.nan, 0.0, 0.0]], Q[:2], [[np.nan, 0.0, 0.0]]])  # NaN equals nothing
    first = {}
    expected = np.array([i if np.isnan(r).any() else first.setdefault(tuple(r + 0.0), i) for i, r in enumerate(R)])
    for bits in (64, 0):
        np.testing.assert_array_equal(first_copies(R, bits=bits), expected)
    # faces: the first of each set with the same vertices, in any order
    F = np.array([[0, 1, 2], [2, 1, 0], [1, 2, 3], [3, 1, 2], [0, 1, 2], [4, 5, 6]])
    assert first_faces(F).tolist() == [True, False, True, False, False, True]


# ------------------------------------------------------------- one answer per surface (issue items)
def sample_mesh_path(name):
    import importlib.resources

    return importlib.resources.files("pymeshlab") / "tests" / "sample_meshes" / name


def obj_arrays(name):
    """The vertices and triangles of a sample OBJ by plain text parsing (v and f lines)."""
    V, F = [], []
    for line in sample_mesh_path(name).read_text().splitlines():
        w = line.split()
        if w and w[0] == "v":
            V.append([float(x) for x in w[1:4]])
        elif w and w[0] == "f":
            c = [int(t.split("/")[0]) - 1 for t in w[1:]]
            F.extend([c[0], c[i], c[i + 1]] for i in range(1, len(c) - 1))
    return np.array(V), np.array(F)


def test_a_soup_welds_to_the_files_vertices_and_reports_its_splits(caplog):
    """cow.obj has two vertices at one position (45 and 2904), a fan each: its triangle soup (an
    STL) welds to the same two (chi 2, the same spectrum), and the weld says it kept them apart.
    Merged into one vertex (what Open3D's OBJ reader makes of the file) it is another surface: a
    pinched vertex, chi 1, not a 2-manifold, and the report says so."""
    V, F = obj_arrays("cow.obj")
    assert len(V) == 2904 and np.array_equal(V[44], V[2903])
    Vs, Fs = split_vertices(V, F)
    r, rs = o3dheat.check_mesh((V, F)), o3dheat.check_mesh((Vs, Fs))
    assert (r.euler_characteristic, r.non_manifold_vertices, r.split_vertices, r.ok) == (2, 0, 1, True)
    assert (rs.euler_characteristic, rs.non_manifold_vertices, rs.components, rs.split_vertices) == \
        (2, 0, 1, 1)
    assert "1 coincident vertices kept apart (split" in str(rs)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        p = prepare((Vs, Fs))
    assert "1 vertices coincide with another but are kept apart (split" in caplog.text
    q = prepare((V, F))
    np.testing.assert_array_equal(q.V[q.F], p.V[p.F])  # the same triangles, vertex for vertex
    a = o3dheat.eigensolve((V, F), k=5).eigenvalues
    b = o3dheat.eigensolve((Vs, Fs), k=5).eigenvalues
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    merged = (V[:-1], np.where(F == 2903, 44, F))
    rm = o3dheat.check_mesh(merged)
    assert (rm.euler_characteristic, rm.non_manifold_vertices, rm.ok) == (1, 1, False)
    assert abs(o3dheat.eigensolve(merged, k=5).eigenvalues[1] - a[1]) > 0.05  # another surface


def non_manifold_edge():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    return V, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])


def pinched_vertex():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.0]])
    return V, np.array([[0, 1, 2], [0, 3, 4]])


@pytest.mark.parametrize("mesh", [non_manifold_edge(), pinched_vertex()], ids=["edge", "vertex"])
def test_report_status_agrees_with_topology(mesh):
    """The report said 'status: ok' for meshes critical_points refuses."""
    r = o3dheat.check_mesh(mesh)
    assert not r.ok and not r.manifold and "not a 2-manifold" in str(r) and "status: ok" not in str(r)
    with pytest.raises(o3dheat.MeshError, match="non-manifold"):
        o3dheat.critical_points(mesh, mesh[0][:, 0])
    fixed = o3dheat.repair(mesh)
    r = o3dheat.check_mesh(fixed)
    assert r.ok and r.manifold and str(r).endswith("status: ok")
    o3dheat.critical_points(fixed, fixed.mesh.vertex.positions.numpy()[:, 0])


def test_report_topology_is_that_of_the_faces_used(caplog):
    """Faces prepare drops (duplicate, degenerate, zero-area) are not in the report's topology."""
    V, F = icosphere(2)
    far = np.r_[V, [[5.0, 0, 0], [6.0, 0, 0], [7.0, 0, 0]]]  # a zero-area face away from the sphere
    n = len(V)
    F2 = np.r_[F, F[:3], [[0, 0, 1]], [[n, n + 1, n + 2]]]
    r, r0 = o3dheat.check_mesh((far, F2)), o3dheat.check_mesh((V, F))
    assert (r.duplicate_faces, r.degenerate_faces, r.zero_area_faces) == (3, 1, 1)
    assert (r.euler_characteristic, r.components, r.genus, r.non_manifold_edges, r.used_faces) == \
        (r0.euler_characteristic, r0.components, r0.genus, 0, len(F))
    assert r.unreferenced_vertices == 3 and r.manifold and not r.ok
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        p = prepare((far, F2))
    assert len(p.F) == r.used_faces and len(p.keep) == n
    assert "3 unreferenced vertices" in caplog.text


def test_mesh_likes_are_meshes_everywhere():
    """A repair's result went to critical_points, a resampling's to the filters: refused."""
    from o3dheat.geometry.sampling import subdivide

    V, F = pinched_vertex()
    r = o3dheat.repair((V, F))
    cp = o3dheat.critical_points(r, r.mesh.vertex.positions.numpy()[:, 0])
    assert cp.n == len(r.source) and len(cp.minima) == 2  # each fan its own minimum
    V2, F2 = icosphere(1)
    res = subdivide((V2, F2))
    s = o3dheat.eigensolve(res, k=4)
    assert s.eigenvectors.shape == (len(res.V), 4)
    np.testing.assert_array_equal(o3dheat.as_arrays(res)[1], res.F)
    assert o3dheat.check_mesh(r).ok
    assert o3dheat.geometry.mesh.mesh_of(r) is r.mesh

    class Wrapper:  # any object with a mesh attribute
        def __init__(self, mesh):
            self.mesh = mesh

    np.testing.assert_array_equal(o3dheat.as_arrays(Wrapper(Wrapper((V2, F2))))[0], V2)
    with pytest.raises(o3dheat.MeshError, match="mesh` attribute"):
        o3dheat.as_arrays(Wrapper(None))


_RNG = np.random.default_rng(5)
_DEGENERATE_CLOUDS = {
    "collinear": (np.c_[np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)], "lie on one line"),
    "coincident": (np.ones((50, 3)), "all coincide"),
    "three points": (np.eye(3), "3 distinct points"),
    "nearly collinear": (np.c_[np.linspace(0, 1, 50), 1e-15 * _RNG.random(50), np.zeros(50)], "one line"),
    "few distinct": (np.repeat(np.eye(3), 10, axis=0), "3 distinct points \\(30 in all\\)"),
}


@pytest.mark.parametrize("case", list(_DEGENERATE_CLOUDS))
def test_degenerate_point_clouds_are_named(case):
    """They ended in raw Qhull (QH6239) or geometry-central (GC_SAFETY_ASSERT) errors."""
    from o3dheat.geometry.mesh import check_points

    P, why = _DEGENERATE_CLOUDS[case]
    for planar in (True, False):
        with pytest.raises(o3dheat.MeshError, match=why):
            check_points(P, planar=planar)


def test_a_flat_patch_is_a_surface_for_point_operators_not_for_reconstruction():
    from o3dheat.geometry.mesh import check_points

    flat = np.c_[_RNG.random((200, 2)), np.zeros(200)]
    np.testing.assert_array_equal(check_points(flat), flat)
    with pytest.raises(o3dheat.MeshError, match="lie in one plane"):
        check_points(flat, planar=False)
    with pytest.raises(o3dheat.MeshError, match="NaN"):
        check_points(np.r_[flat, [[np.nan, 0, 0]]])
    with pytest.raises(o3dheat.MeshError, match="at least 31"):
        check_points(flat[:20], min_points=31)
    sphere = _RNG.standard_normal((100, 3))
    assert check_points(sphere, planar=False).shape == (100, 3)


def test_a_repair_is_reported_once_per_mesh(caplog):
    """Issue 22: the same repair was reported by prepare (the spectrum) and again by the topology
    (the critical points) of the same mesh; now once per geometry, and again for another mesh."""
    import logging

    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    F2 = np.vstack([F, F[:3]])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve((V, F2), k=6, cache=False)
        o3dheat.critical_points((V, F2), o3dheat.HeatKernel(s).smooth(V[:, 2], 0.01))
        o3dheat.critical_points((V, F2), V[:, 0])
    assert caplog.text.count("dropping 3 duplicate faces") == 1
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        o3dheat.critical_points((V * 2, F2), V[:, 0])  # another geometry: its own report
    assert caplog.text.count("dropping 3 duplicate faces") == 1


def test_non_manifold_vertex_mask_is_the_fan_count():
    """The O(m) mask (one label per vertex compared with each corner's) equals the definition: a
    vertex whose corners fall into more than one edge-connected fan. Random face soups glued at
    shared vertices (bowties, fans split in two) and closed meshes."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    from o3dheat.geometry._tables import non_manifold_vertex_mask

    def fans_by_definition(F, n):
        m = len(F)
        vert = F.reshape(-1)
        corners = {}
        for c, v in enumerate(vert):
            corners.setdefault(int(v), []).append(c)
        # corners c, d at one vertex are adjacent when their faces share an edge through it
        edges = [(c, d) for cs in corners.values() for i, c in enumerate(cs) for d in cs[i + 1:]
                 if len((set(F[c // 3]) & set(F[d // 3])) - {vert[c]}) > 0]
        a, b = (np.array(x, dtype=np.int64) for x in zip(*edges, strict=True)) if edges else (np.zeros(0, int),) * 2
        _, lab = connected_components(sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(3 * m, 3 * m)), directed=False)
        return np.array([len({int(lab[c]) for c in corners.get(v, [])}) > 1 for v in range(n)])

    rng = np.random.default_rng(0)
    for trial in range(40):
        n = int(rng.integers(4, 12))
        F = np.array([rng.choice(n, 3, replace=False) for _ in range(int(rng.integers(1, 14)))], dtype=np.int64)
        assert np.array_equal(non_manifold_vertex_mask(F, n), fans_by_definition(F, n)), (trial, F.tolist())
    V, F = icosphere(2)
    assert not non_manifold_vertex_mask(F, len(V)).any()
    bowtie = np.array([[0, 1, 2], [0, 3, 4]])
    assert non_manifold_vertex_mask(bowtie, 5).tolist() == [True, False, False, False, False]
