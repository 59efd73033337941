"""o3dheat.geometry.repairs: splitting non-manifold edges and vertices, orientation, small components."""

import numpy as np
import open3d as o3d
import pytest

import o3dheat


def _tet(offset=(0.0, 0.0, 0.0)):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.]]) + offset
    F = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return V, F


def test_repair_splits_a_non_manifold_vertex_and_topology_then_works():
    """Two closed tetrahedra sharing one vertex: a non-manifold vertex that topology refuses;
    repaired: two spheres, χ = 4, the Morse count holds; the repaired mesh is not re-welded."""
    V1, F1 = _tet()
    V2, F2 = _tet((-1.0, -1.0, -1.0))  # its vertex 3 is at the origin, like vertex 0 of the first
    V = np.r_[V1, V2[:3]]
    F = np.r_[F1, np.where(F2 == 3, 0, F2 + 4)]
    with pytest.raises(o3dheat.MeshError, match="o3dheat.repair"):
        o3dheat.critical_points((V, F), V[:, 0])
    r = o3dheat.repair((V, F))
    assert r.split_vertices == 1 and r.orientable and "split 1" in str(r)
    rep = o3dheat.check_mesh(r.mesh)
    assert rep.components == 2 and rep.euler_characteristic == 4 and rep.non_manifold_vertices == 0
    assert rep.welded_vertices == 0  # the copy made by the split stays a copy
    np.testing.assert_array_equal(r.mesh.vertex.positions.numpy(), V[r.source])
    cp = o3dheat.critical_points(r.mesh, r.mesh.vertex.positions.numpy()[:, 0] + 1e-3 * np.arange(len(r.source)))
    assert cp.euler_characteristic == 4


def test_repair_cuts_an_edge_with_three_faces_and_orients():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.]])
    F = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    r = o3dheat.repair((V, F))
    assert o3dheat.check_mesh(r.mesh).non_manifold_edges == 0
    o3dheat.topology.Surface(r.mesh)  # accepted
    # a closed sphere with half of its faces flipped: oriented back, outward or inward consistently
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10, float_dtype=o3d.core.float64)
    Vs, Fs = m.vertex.positions.numpy(), m.triangle.indices.numpy().astype(np.int64)
    bad = Fs.copy()
    bad[::2] = bad[::2, ::-1]
    r = o3dheat.repair((Vs, bad))
    G = r.mesh.triangle.indices.numpy()
    e = np.r_[G[:, [0, 1]], G[:, [1, 2]], G[:, [2, 0]]]
    assert len(np.unique(e, axis=0)) == len(e)  # every directed edge once: consistent orientation
    assert r.flipped_faces in (len(Fs) // 2, len(Fs) - len(Fs) // 2)


def test_repair_reports_a_moebius_band_and_drops_small_components():
    n = 12
    t = np.arange(n) * 2 * np.pi / n
    V = np.r_[np.c_[np.cos(t), np.sin(t), 0 * t] + 0.2 * np.c_[np.cos(t / 2) * np.cos(t), np.cos(t / 2) * np.sin(t),
                                                               np.sin(t / 2)],
              np.c_[np.cos(t), np.sin(t), 0 * t] - 0.2 * np.c_[np.cos(t / 2) * np.cos(t), np.cos(t / 2) * np.sin(t),
                                                               np.sin(t / 2)]]
    i = np.arange(n)
    j = (i + 1) % n
    top_j = np.where(j == 0, n, j)  # after a full turn the band comes back upside down
    bot_j = np.where(j == 0, 0, j + n)
    F = np.r_[np.c_[i, top_j, i + n], np.c_[top_j, bot_j, i + n]]
    r = o3dheat.repair((V, F))
    assert not r.orientable and "not orientable" in str(r)
    Vt, Ft = _tet((5.0, 0, 0))
    both = (np.r_[V, Vt], np.r_[F, Ft + len(V)])
    r = o3dheat.repair(both, min_component_faces=5)
    assert r.removed_components == 1 and len(r.mesh.triangle.indices) == len(F)


def test_repair_carries_attributes_and_never_crashes_on_soups():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    m.vertex["f"] = o3d.core.Tensor(np.arange(len(m.vertex.positions), dtype=np.int32))
    r = o3dheat.repair(m)
    np.testing.assert_array_equal(r.mesh.vertex["f"].numpy(), r.source)
    assert str(r) == "nothing to repair"

    @settings(max_examples=40, deadline=None)
    @given(seed=st.integers(0, 2**31 - 1), n=st.integers(4, 12), m=st.integers(1, 30))
    def soup(seed, n, m):
        rng = np.random.default_rng(seed)
        V = rng.integers(0, 3, (n, 3)).astype(float)  # coincident and collinear points on purpose
        F = rng.integers(0, n, (m, 3))
        try:
            r = o3dheat.repair((V, F))
        except o3dheat.MeshError:
            return  # e.g. nothing with a positive area is left: a clear refusal
        # a 2-manifold (as welded by o3dheat's rule it stays one, except in rare tangles of
        # overlapping copies of faces, about 1 in 3000 of these random soups: weld=False then)
        rep = o3dheat.check_mesh(r.mesh, weld=False)
        assert rep.non_manifold_edges == 0 and rep.non_manifold_vertices == 0
        o3dheat.topology.Surface(r.mesh, weld=False)

    soup()


def test_cli_repair(tmp_path, capsys):
    from o3dheat.cli import main

    V1, F1 = _tet()
    V2, F2 = _tet((-1.0, -1.0, -1.0))
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.r_[V1, V2[:3]]),
                                       o3d.utility.Vector3iVector(np.r_[F1, np.where(F2 == 3, 0, F2 + 4)]))
    src = tmp_path / "in.ply"
    o3d.io.write_triangle_mesh(str(src), legacy)
    before = src.read_bytes()
    out = tmp_path / "out.ply"
    assert main(["repair", str(src), str(out)]) == 0
    text = capsys.readouterr().out
    assert "split 1 vertex" in text and "status: ok" in text and out.exists()
    assert main(["repair", str(src), str(out)]) == 2  # exists
    assert main(["repair", str(src), str(src), "--overwrite"]) == 2  # never the input
    assert "input" in capsys.readouterr().err and src.read_bytes() == before


def test_repaired_copies_stay_apart_and_are_reported_as_split():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.0]])
    F = np.array([[0, 1, 2], [0, 3, 4]])  # a bow tie: repair gives each fan its own vertex 0
    r = o3dheat.repair((V, F))
    rep = o3dheat.check_mesh(r)
    assert rep.non_manifold_vertices == 0 and rep.split_vertices == 1 and rep.ok
