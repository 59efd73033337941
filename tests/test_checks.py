"""o3dheat.checks: fields as numpy arrays, lists or Open3D tensors, and resamplings as meshes,
everywhere; absurd counts refused at once."""

import numpy as np
import open3d as o3d
import pytest

import o3dheat
from o3dheat.checks import count, values
from o3dheat.geometry.interpolation import transfer
from o3dheat.geometry.sampling import jitter


@pytest.fixture(scope="module")
def sphere():
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10, float_dtype=o3d.core.float64)
    return m, o3dheat.HeatKernel(o3dheat.eigensolve(m, k=10))


def test_fields_in_every_form_give_the_same_result(sphere):
    m, K = sphere
    f = m.vertex.positions.numpy()[:, 2]
    forms = {"numpy": f, "list": f.tolist(), "tensor": m.vertex.positions[:, 2], "float32 tensor":
             o3d.core.Tensor(f.astype(np.float32))}
    ref_s = K.smooth(f, 0.1)
    ref_c = o3dheat.critical_points(m, f).counts
    ref_d = o3dheat.diffuse(m, f, 1e-3, 3)
    ref_t = transfer(f, m, jitter(m, 0.1))
    for name, g in forms.items():
        tol = 1e-6 if "32" in name else 0
        np.testing.assert_allclose(K.smooth(g, 0.1), ref_s, atol=tol, err_msg=name)
        np.testing.assert_allclose(o3dheat.diffuse(m, g, 1e-3, 3), ref_d, atol=tol, err_msg=name)
        np.testing.assert_allclose(transfer(g, m, jitter(m, 0.1)), ref_t, atol=tol, err_msg=name)
        if not tol:
            assert o3dheat.critical_points(m, g).counts == ref_c
            assert o3dheat.persistence(m, g).pairs.shape == o3dheat.persistence(m, f).pairs.shape
    o3dheat.visualization.plot.field(m, forms["tensor"])
    o3dheat.scale_space(K, forms["tensor"])


def test_a_resampling_is_accepted_wherever_a_mesh_is(sphere):
    m, _ = sphere
    r = jitter(m, 0.2)
    np.testing.assert_allclose(o3dheat.eigensolve(r, k=6).eigenvalues,
                               o3dheat.eigensolve((r.V, r.F), k=6).eigenvalues, rtol=1e-12)
    assert o3dheat.check_mesh(r).genus == 0
    z = r.V[:, 2]
    assert o3dheat.critical_points(r, z).counts == o3dheat.critical_points((r.V, r.F), z).counts
    (V, F) = o3dheat.as_arrays((m.vertex.positions, m.triangle.indices))  # tensors as (V, F)
    assert V.shape[1] == 3 and F.shape[1] == 3
    with pytest.raises(o3dheat.MeshError, match="resampling"):
        o3dheat.eigensolve("mesh.ply", k=3)


def test_absurd_sizes_are_refused_at_once(sphere):
    m, K = sphere
    f = m.vertex.positions.numpy()[:, 2]
    with pytest.raises(o3dheat.MeshError, match="count must be an integer from 1 to 100000"):
        K.scales(10**8)
    with pytest.raises(o3dheat.MeshError, match="count must be an integer from 1 to 10000"):
        o3dheat.level_sets(m, f, count=10**9)
    with pytest.raises(o3dheat.MeshError, match="steps must be an integer from 0 to 1000000"):
        o3dheat.diffuse(m, f, 1e-3, 10**9)
    for bad in (True, 2.5, "3", -1):
        with pytest.raises(o3dheat.MeshError):
            count(bad, "n")


def test_values():
    assert values([1, 2]) == [1, 2]
    a = np.arange(3)
    assert values(a) is a
    np.testing.assert_array_equal(values(o3d.core.Tensor(a)), a)


def test_absurd_remeshing_iterations_are_refused(sphere):
    m, _ = sphere
    from o3dheat.geometry.sampling import anisotropic, remesh

    with pytest.raises(o3dheat.MeshError, match="iterations must be an integer from 1 to 1000"):
        remesh(m, iterations=10**9)
    with pytest.raises(o3dheat.MeshError, match="iterations"):
        anisotropic(m, iterations=10**9)


def test_times_refuse_text_and_emptiness_everywhere():
    """Issue 22: times=[] returned an empty result and a string time ("0.1") was parsed; both are
    refused by the one time check, so HeatKernel.smooth/hks, heat_flow and the rest agree."""
    import open3d as o3d

    import o3dheat
    from o3dheat.checks import times

    for bad, msg in (([], "t is empty"), ("0.1", "must be a number"), (b"1", "must be a number"),
                     (["0.1", "1"], "must be a number"), (np.array([], float), "t is empty")):
        with pytest.raises(o3dheat.MeshError, match=msg):
            times(bad)
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    f = m.vertex.positions.numpy()[:, 2]
    K = o3dheat.HeatKernel(o3dheat.eigensolve(m, k=10, cache=False))
    for call in (lambda t: K.smooth(f, t), lambda t: K.hks(t), lambda t: o3dheat.heat_flow(m, f, t)):
        for bad in ([], "0.1"):
            with pytest.raises(o3dheat.MeshError, match="t is empty|must be a number"):
                call(bad)


@pytest.mark.parametrize("kw, msg", [({"tol": -1}, "tol must be a number in"), ({"tol": 0}, "tol must be"),
                                     ({"tol": "1e-8"}, "tol must be"), ({"block": 0}, "block must be an integer"),
                                     ({"block": -2}, "block must be"), ({"block": 2.5}, "block must be"),
                                     ({"seed": "x"}, "seed must be"), ({"seed": -1}, "seed must be")])
def test_eigensolve_settings_are_checked(kw, msg):
    """Issue 22: tol < 0, block <= 0 were accepted silently."""
    import scipy.sparse as sp

    import o3dheat

    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(o3dheat.MeshError, match=msg):
        o3dheat.eigensolve((V, F), k=2, cache=False, **kw)
    with pytest.raises(o3dheat.MeshError, match=msg):
        o3dheat.spectral.spectrum.eigensolve_operators(sp.identity(4) * 2 - sp.eye(4, k=1) - sp.eye(4, k=-1), sp.identity(4), k=2, **kw)
