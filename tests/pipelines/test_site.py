"""The filter SDK: point clouds, capped k, mesh-likes, the shared reconstruction (o3dheat.pipelines.site)."""

import numpy as np
import open3d as o3d
import pytest
from conftest import sphere_points, tmesh

import o3dheat
import o3dheat.pipelines.filters as flt


# ------------------------------------------------------------------------------- point clouds
@pytest.mark.parametrize("operators, tol", [("reconstruct", 0.02), ("robust", 0.1)])
def test_point_cloud_spectrum_of_the_unit_sphere(operators, tol):
    pytest.importorskip("robust_laplacian") if operators == "robust" else None
    from o3dheat.pipelines.site import Site

    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(sphere_points()))
    lam = Site(pc, operators).spectrum(k=16).eigenvalues
    ref = np.array([2] * 3 + [6] * 5 + [12] * 7)
    assert abs(lam[0]) < 1e-6 and np.allclose(lam[1:], ref, rtol=tol)


@pytest.mark.parametrize("operators", ["reconstruct", "robust"])
def test_filters_on_point_clouds(operators):
    pytest.importorskip("robust_laplacian") if operators == "robust" else None
    P = sphere_points(3000, seed=1)
    for pc in (o3d.t.geometry.PointCloud(o3d.core.Tensor(P)),
               o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))):
        out = flt.Chain([("scalar", {"kind": "height", "operators": operators}),
                         ("heat_smooth", {"k": 20, "operators": operators, "times": [0.05]}),
                         ("heat_smooth", {"operators": operators, "times": [0.05], "method": "exact",
                                          "output": "height_exact"}),
                         ("hks", {"k": 20, "operators": operators, "scales": 3}),
                         ("colorize", {"attribute": "hks", "column": 0})])(pc)
        assert isinstance(out, o3d.t.geometry.PointCloud)
        s = out.point["height_smooth"].numpy()
        # Φ_t of the height on the unit sphere: exp(-2 t / 2) z (an l = 1 harmonic)
        assert np.corrcoef(s, P[:, 2])[0, 1] > 0.99
        assert np.allclose(s, np.exp(-0.05) * P[:, 2], atol=0.05)
        assert np.allclose(out.point["height_exact"].numpy(), np.exp(-0.05) * P[:, 2], atol=0.05)
        assert out.point["hks"].shape == (3000, 3)
    if operators == "robust":
        with pytest.raises(o3dheat.MeshError, match="surface"):
            flt.apply(out, "critical_points", attribute="height", operators="robust")
    else:
        lab = flt.apply(out, "critical_points", attribute="height").point["height_critical"].numpy()
        assert lab.shape == (3000,) and set(np.unique(lab)) <= {0, 1, 2, 3}


def test_disk_cache_skips_the_eigensolve(sphere, tmp_path):
    o3dheat.spectral.cache.clear_cache()
    flt.set_disk_cache(tmp_path)
    try:
        flt.apply(sphere, "hks", k=12)
        assert len(list(tmp_path.glob("spectrum-*.npz"))) == 1
        o3dheat.spectral.cache.clear_cache()  # a new session: the disk cache answers
        spec = flt.shared_spectrum(sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy(), k=12)
        assert spec.timings["cache"] is True
    finally:
        flt.set_disk_cache(None)


@pytest.mark.parametrize("name, params", [("hks", {}), ("heat_smooth", {"attribute": "positions", "column": 2}),
                                          ("feature_approx", {"attribute": "positions", "column": 2})])
def test_a_capped_k_is_a_warning(name, params, caplog):
    """A tetrahedron has 4 vertices: k=100 eigenpairs were silently 4."""
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with caplog.at_level("WARNING", logger="o3dheat"):
        flt.apply(tmesh(V, F), name, k=100, **params)
    capped = [r for r in caplog.records if "k=100 eigenpairs asked for" in r.getMessage()]
    assert capped and capped[0].name == "o3dheat" and capped[0].levelname == "WARNING"
    assert "this surface allows 4: using k=4" in capped[0].getMessage()
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        flt.apply(tmesh(V, F), name, k=4, **params)
    assert not [r for r in caplog.records if "asked for" in r.getMessage()]


def test_filters_take_every_mesh_like():
    """Issue 22: a resampling result (Resampled) and a repair result (Repaired) were refused by the
    filters; they take any mesh-like, and (V, F) arrays, as the rest of o3dheat does."""
    import o3dheat.geometry.sampling as sampling

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    chain = flt.Chain([flt.get("scalar", kind="height"), flt.get("heat_smooth", attribute="height")])
    direct = chain(m)
    ref = direct.vertex["height_smooth"].numpy()
    for like in (o3dheat.repair(m), (V, F)):
        out = chain(like)
        np.testing.assert_allclose(out.vertex["height_smooth"].numpy(), ref, atol=1e-8)
    r = sampling.jitter(m, 0.1, seed=1)
    out = chain(r)
    assert out.vertex["height_smooth"].shape[0] == r.mesh.vertex.positions.shape[0]
    with pytest.raises(o3dheat.MeshError, match="mesh-like"):
        flt.apply(object(), "scalar", kind="height")


def test_a_point_cloud_is_reconstructed_once_per_chain_and_degenerate_clouds_are_named(monkeypatch, caplog):
    """Issue 22: each step of a chain reconstructed the cloud again (and its repairs were reported
    at every step: "dropping 24 duplicate faces" twice); degenerate clouds (collinear, coincident,
    three points, flat for a reconstruction) ended in raw Qhull or geometry-central errors."""
    import logging

    import o3dheat.geometry.points as points
    import o3dheat.spectral.cache as S

    S.clear_cache()
    calls = []
    real = points.reconstruct
    monkeypatch.setattr(points, "reconstruct", lambda *a, **kw: calls.append(1) or real(*a, **kw))
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(sphere_points()))
    chain = flt.Chain([flt.get("scalar", kind="height"), flt.get("heat_smooth", attribute="height"),
                       flt.get("hks", times=[0.1])])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        chain(pc)
    assert len(calls) == 1
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == len(set(messages))  # no repair reported twice
    rng = np.random.default_rng(0)
    line = np.c_[np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)]
    flat = np.c_[rng.random((200, 2)), np.zeros(200)]
    cases = {"all coincide": np.ones((50, 3)), "one line": line, "distinct points": rng.random((3, 3)),
             "one plane": flat}
    for operators in ("reconstruct", "robust"):
        for msg, P in cases.items():
            if operators == "robust" and msg == "one plane":
                continue  # a flat patch is a surface for point-cloud operators
            with pytest.raises(o3dheat.MeshError, match=msg):
                flt.apply(o3d.t.geometry.PointCloud(o3d.core.Tensor(P)), "hks", times=[0.1], operators=operators)


def test_k_is_capped_at_the_welded_vertices_of_a_triangle_soup(caplog):
    """Issue 22 (found in review): a filter capped k at the soup's vertex count before welding,
    then eigensolve refused k > the welded count; the cap is now the vertices it solves on."""
    import logging

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    soup = o3d.t.geometry.TriangleMesh()
    soup.vertex.positions = o3d.core.Tensor(V[F.reshape(-1)])
    soup.triangle.indices = o3d.core.Tensor(np.arange(3 * len(F)).reshape(-1, 3))
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        out = flt.apply(soup, "hks", times=[0.1], k=100)
    assert out.vertex["hks"].shape[0] == 3 * len(F) and f"this surface allows {len(V)}" in caplog.text
