"""o3dheat.spectral.fem: identities of the FEM operators and agreement with independent implementations
(LaPy's FEM and libigl's cotangent, mass and Voronoi matrices)."""

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import grid, icosphere, irregular, torus

import o3dheat
from o3dheat.geometry.mesh import face_areas
from o3dheat.spectral import fem
from o3dheat.spectral.fem import voronoi_areas

MESHES = {"sphere": icosphere(2), "torus": torus(), "grid": grid(2, 1, 12, 6, jitter=0.3), "irregular": irregular()}


@pytest.fixture(params=list(MESHES))
def mesh(request):
    return MESHES[request.param]


def test_stiffness_identities(mesh):
    V, F = mesh
    L = o3dheat.stiffness_matrix((V, F))
    assert abs(L - L.T).max() < 1e-12
    np.testing.assert_allclose(L @ np.ones(len(V)), 0, atol=1e-11)
    w = np.linalg.eigvalsh(L.toarray())
    assert w.min() > -1e-10  # positive semi-definite
    # L = Gᵀ diag(|t|) G with G the per-face gradient of the hat functions (independent formula)
    v0, v1, v2 = (V[F[:, i]] for i in range(3))
    nrm = np.cross(v1 - v0, v2 - v0)
    dbl = np.linalg.norm(nrm, axis=1)
    unit = nrm / dbl[:, None]
    grads = [np.cross(unit, e) / dbl[:, None] for e in (v2 - v1, v0 - v2, v1 - v0)]
    m, n = len(F), len(V)
    rows = np.concatenate([np.arange(3 * m).reshape(m, 3)[:, d] for i in range(3) for d in range(3)])
    cols = np.concatenate([F[:, i] for i in range(3) for d in range(3)])
    vals = np.concatenate([grads[i][:, d] for i in range(3) for d in range(3)])
    G = sp.csr_matrix((vals, (rows, cols)), shape=(3 * m, n))
    A = sp.diags(np.repeat(dbl / 2, 3))
    np.testing.assert_allclose((G.T @ A @ G).toarray(), L.toarray(), atol=1e-10)


def test_stiffness_scale_invariant(mesh):
    V, F = mesh
    L1 = o3dheat.stiffness_matrix((V, F))
    L2 = o3dheat.stiffness_matrix((7.5 * V, F))
    assert abs(L1 - L2).max() < 1e-10


def test_mass_identities(mesh):
    V, F = mesh
    area = face_areas(V, F).sum()
    one = np.ones(len(V))
    for kind in ("consistent", "lumped", "voronoi"):
        B = o3dheat.mass_matrix((V, F), kind)
        assert abs(B - B.T).max() < 1e-15
        assert one @ B @ one == pytest.approx(area, rel=1e-12)
        assert np.linalg.eigvalsh(B.toarray()).min() > 0
    B = o3dheat.mass_matrix((V, F))
    np.testing.assert_allclose(o3dheat.mass_matrix((V, F), "lumped").diagonal(), B @ one, rtol=1e-12)
    # B(i, i) = sum |t| / 6 and B(i, j) = (|t_r| + |t_s|) / 12 on one hand-checked triangle pair
    assert (2 ** 2 * o3dheat.mass_matrix((V, F))).sum() == pytest.approx((o3dheat.mass_matrix((2 * V, F))).sum())


def test_mass_hand_example():
    # two right triangles of area 1/2 sharing the edge 1-2
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    B = o3dheat.mass_matrix((V, F)).toarray()
    assert B[1, 2] == pytest.approx((0.5 + 0.5) / 12)
    assert B[0, 1] == pytest.approx(0.5 / 12)
    assert B[1, 1] == pytest.approx((0.5 + 0.5) / 6)
    assert B[0, 3] == 0
    L = o3dheat.stiffness_matrix((V, F)).toarray()
    # the diagonal edge 1-2 is opposite two right angles: cot 90° = 0
    assert L[1, 2] == pytest.approx(0, abs=1e-15)
    assert L[0, 1] == pytest.approx(-0.5)  # cot 45° / 2 (boundary edge)


def test_against_lapy(mesh):
    lapy = pytest.importorskip("lapy")
    V, F = mesh
    s = lapy.Solver(lapy.TriaMesh(V, F.astype(np.int64)), lump=False)
    assert abs(s.stiffness - o3dheat.stiffness_matrix((V, F))).max() < 1e-10
    assert abs(s.mass - o3dheat.mass_matrix((V, F))).max() < 1e-14


def test_against_libigl(mesh):
    igl = pytest.importorskip("igl")
    V, F = mesh
    L = igl.cotmatrix(V, F.astype(np.int64))  # negative semi-definite, cot/2 weights
    assert abs(-L - o3dheat.stiffness_matrix((V, F))).max() < 1e-10
    M = igl.massmatrix(V, F.astype(np.int64), igl.MASSMATRIX_TYPE_VORONOI)
    np.testing.assert_allclose(M.diagonal(), voronoi_areas(V, F), rtol=1e-10, atol=1e-14)
    M = igl.massmatrix(V, F.astype(np.int64), igl.MASSMATRIX_TYPE_FULL)
    assert abs(M - o3dheat.mass_matrix((V, F))).max() < 1e-14


def test_unknown_mass_kind():
    with pytest.raises(o3dheat.MeshError, match="unknown mass"):
        o3dheat.mass_matrix(icosphere(1), kind="diagonal")


def test_zero_area_face_rejected_by_raw_operators():
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]])
    with pytest.raises(o3dheat.MeshError, match="zero area"):
        o3dheat.stiffness_matrix((V, np.array([[0, 1, 2]])))


def test_curvatures_and_gauss_bonnet():
    from conftest import grid, icosphere, torus

    from o3dheat.spectral.fem import gaussian_curvature, mean_curvature, voronoi_areas

    for R in (0.5, 3.0):
        V, F = icosphere(4, radius=R)
        assert np.allclose(mean_curvature(V, F), 1 / R, rtol=0.02)
        assert np.allclose(gaussian_curvature(V, F), 1 / R**2, rtol=0.05)
    for (V, F), chi in ((icosphere(2), 2), (torus(), 0), (grid(jitter=0.3), 1)):
        # discrete Gauss-Bonnet: Σ (angle defect) = 2π χ, exactly, boundaries included
        assert abs(gaussian_curvature(V, F) @ voronoi_areas(V, F) - 2 * np.pi * chi) < 1e-9
    V, F = grid()
    interior = (V[:, 0] > 0) & (V[:, 0] < 2) & (V[:, 1] > 0) & (V[:, 1] < 1)
    assert np.allclose(mean_curvature(V, F)[interior], 0, atol=1e-9)  # a plane
    assert np.allclose(gaussian_curvature(V, F)[interior], 0, atol=1e-9)


@pytest.mark.parametrize("kind", ["consistent", "lumped", "voronoi", "identity"])
def test_operators_equal_the_separate_functions(mesh, kind):
    V, F = mesh
    L, B, a = o3dheat.spectral.fem.operators(V, F, kind)
    assert abs(L - o3dheat.stiffness_matrix((V, F))).max() == 0
    B0 = sp.identity(len(V)) if kind == "identity" else o3dheat.mass_matrix((V, F), kind)
    assert abs(B - B0).max() == 0
    np.testing.assert_array_equal(a, voronoi_areas(V, F))
    assert L.has_canonical_format and B.format == "csc"


def test_out_of_memory_in_the_assembly_is_said_as_out_of_memory(monkeypatch):
    """Issue 30: under a memory cap numba's MemoryError escaped fem.operators (and heat_flow) raw."""
    from o3dheat.errors import OutOfMemory
    from o3dheat.spectral import fem as fem_module

    V, F = icosphere(1)

    def full(*args):
        raise MemoryError("cannot allocate")

    monkeypatch.setattr(fem_module, "_assembled", full)
    with pytest.raises(OutOfMemory, match="out of memory assembling the operators of 42 vertices"):
        fem_module.operators(V, F)


def test_the_operators_take_a_mesh_like_every_function():
    """Issue 30: o3dheat.mass_matrix and stiffness_matrix took (V, F) where every other function takes a
    mesh; they take one mesh now (Open3D tensor or legacy, a (V, F) pair, a mesh-like), without a warning."""
    import warnings

    import open3d as o3d

    tensor = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    V, F = o3dheat.as_arrays(tensor)
    legacy = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F.astype(np.int32)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new call says nothing
        for mesh in (tensor, legacy, (V, F), o3dheat.repair((V, F))):
            assert abs(o3dheat.stiffness_matrix(mesh) - fem.operators(V, F)[0]).max() == 0
            for kind in fem.MASS_KINDS:
                B = fem.operators(V, F, kind)[1]
                assert abs(o3dheat.mass_matrix(mesh, kind) - B).max() == 0
                assert abs(o3dheat.mass_matrix(mesh, kind=kind) - B).max() == 0
        # a mesh is checked like everywhere else (o3dheat.as_arrays)
        with pytest.raises(o3dheat.MeshError, match="face indices out of range"):
            o3dheat.mass_matrix((V[:3], F))


def test_the_former_two_array_call_still_works_and_warns():
    V, F = icosphere(1)
    with pytest.warns(DeprecationWarning, match=r"mass_matrix\(\(V, F\), ...\) or an Open3D mesh"):
        B = o3dheat.mass_matrix(V, F)
    assert abs(B - o3dheat.mass_matrix((V, F))).max() == 0
    for call in (lambda: o3dheat.mass_matrix(V, F, "lumped"), lambda: fem.mass_matrix(V, F, kind="lumped")):
        with pytest.warns(DeprecationWarning, match="is deprecated: pass one mesh"):
            assert abs(call() - o3dheat.mass_matrix((V, F), "lumped")).max() == 0
    with pytest.warns(DeprecationWarning, match=r"stiffness_matrix\(\(V, F\), ...\)"):
        assert abs(o3dheat.stiffness_matrix(V, F) - o3dheat.stiffness_matrix((V, F))).max() == 0
    # the arrays of the former call are taken as before (the same checks and messages)
    with pytest.warns(DeprecationWarning), pytest.raises(o3dheat.MeshError, match="face indices must lie in"):
        o3dheat.stiffness_matrix(V[:4], np.array([[0, 1, 2], [1, 3, 4]]))
    with pytest.warns(DeprecationWarning), pytest.raises(o3dheat.MeshError, match="unknown mass kind"):
        o3dheat.mass_matrix(V, F, None)
