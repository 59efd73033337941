"""o3dheat.spectral.spectrum: analytic spectra, B-orthonormality, backends, caching, reproducibility."""

import logging

import numpy as np
import open3d as o3d
import pytest
from conftest import grid, icosphere, torus
from hypothesis import given, settings
from hypothesis import strategies as st

import o3dheat
from o3dheat.errors import OutOfMemory
from o3dheat.spectral.linalg import available_backends


def sphere_truth(k, R=1.0):
    lam = []
    l = 0
    while len(lam) < k:
        lam += [l * (l + 1) / R**2] * (2 * l + 1)
        l += 1
    return np.array(lam[:k])


@pytest.mark.parametrize("R", [1.0, 3.0])
def test_unit_sphere_spectrum(sphere4, R):
    V, F = sphere4
    s = o3dheat.eigensolve((R * V, F), k=25, method="arpack")
    truth = sphere_truth(25, R)
    assert s.eigenvalues[0] == pytest.approx(0, abs=1e-10)
    np.testing.assert_allclose(s.eigenvalues[1:], truth[1:], rtol=0.02)
    # multiplicities 2l + 1: the gaps between clusters are the analytic ones
    clusters = np.split(s.eigenvalues, [1, 4, 9, 16])
    for l, c in enumerate(clusters):
        assert len(c) == 2 * l + 1
        assert np.ptp(c) < 0.02 * max(l * (l + 1), 1) / R**2


def test_sphere_converges_under_refinement():
    errs = []
    for level in (2, 3, 4):
        s = o3dheat.eigensolve(icosphere(level), k=16)
        errs.append(np.abs(s.eigenvalues[1:] - sphere_truth(16)[1:]).max())
    assert errs[0] > 2.5 * errs[1] > 2.5 * 2.5 * errs[2]  # about O(h²): x4 per level


def test_flat_rectangle_neumann():
    a, b = 2.0, 1.0
    s = o3dheat.eigensolve(grid(a, b, 60, 30), k=12)
    truth = np.sort([np.pi**2 * ((i / a) ** 2 + (j / b) ** 2) for i in range(8) for j in range(8)])[:12]
    np.testing.assert_allclose(s.eigenvalues, truth, rtol=1e-2, atol=1e-9)


def test_torus_first_eigenvalue_zero_and_orthonormal(torus_mesh):
    s = o3dheat.eigensolve(torus_mesh, k=20)
    assert s.eigenvalues[0] == pytest.approx(0, abs=1e-9)
    assert np.all(np.diff(s.eigenvalues) >= 0)
    # the constant eigenvector: L·1 = 0 and x_1 = 1 / sqrt(area)
    area = s.mass.sum()
    np.testing.assert_allclose(s.eigenvectors[:, 0], 1 / np.sqrt(area), rtol=1e-8)
    X, B = s.eigenvectors, s.mass
    np.testing.assert_allclose(X.T @ B @ X, np.eye(20), atol=1e-10)
    assert s.residuals.max() < 1e-10
    np.testing.assert_allclose(s.stiffness @ X, (B @ X) * s.eigenvalues, atol=1e-8 * s.eigenvalues.max())


@pytest.mark.parametrize("mass", ["consistent", "lumped", "voronoi", "identity"])
def test_mass_kinds(irregular_mesh, mass):
    s = o3dheat.eigensolve(irregular_mesh, k=10, mass=mass, method="arpack")
    d = o3dheat.eigensolve(irregular_mesh, k=10, mass=mass, method="dense")
    np.testing.assert_allclose(s.eigenvalues, d.eigenvalues, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(10), atol=1e-10)
    assert s.mass_kind == mass


def test_lumped_and_consistent_bracket_truth(sphere3):
    # consistent mass over-estimates, lumped mass under-estimates the sphere's eigenvalues
    c = o3dheat.eigensolve(sphere3, k=9, mass="consistent").eigenvalues[1:]
    l = o3dheat.eigensolve(sphere3, k=9, mass="lumped").eigenvalues[1:]
    t = sphere_truth(9)[1:]
    assert np.all(c > t) and np.all(l < t)


@pytest.mark.parametrize("backend", ["cholmod", "cholespy", "superlu"])
def test_backends_agree(irregular_mesh, backend):
    if backend not in available_backends():
        pytest.skip(f"{backend} not installed")
    ref = o3dheat.eigensolve(irregular_mesh, k=15, method="dense")
    s = o3dheat.eigensolve(irregular_mesh, k=15, backend=backend, method="arpack")
    assert s.backend == backend
    np.testing.assert_allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-9, atol=1e-10)
    # eigenvectors equal up to the fixed sign (the irregular mesh has simple eigenvalues)
    np.testing.assert_allclose(np.abs(s.eigenvectors.T @ ref.mass @ ref.eigenvectors).diagonal(), 1, atol=1e-7)
    np.testing.assert_allclose(s.eigenvectors, ref.eigenvectors, atol=1e-6)


def test_cholmod_is_installed_by_setup():
    # the project's set-up installs scikit-sparse (unless asked for the pip-only fallback)
    import os
    from pathlib import Path

    stamp = Path(__file__).resolve().parents[1] / ".venv" / ".o3dheat-setup"
    if os.environ.get("O3DHEAT_PIP_ONLY") or (stamp.exists() and "piponly" in stamp.read_text()):
        pytest.skip("pip-only set-up")
    assert "cholmod" in available_backends()


def test_fallback_warns(monkeypatch, irregular_mesh, caplog):
    import o3dheat.spectral.linalg as la

    def broken(A, mode, analysis=None):
        raise ImportError("no CHOLMOD here")

    monkeypatch.setattr(la, "_cholmod", broken)
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve(irregular_mesh, k=5, method="arpack")
    assert s.backend in ("cholespy", "superlu")
    assert "cholmod" in caplog.text and "falling back" in caplog.text


def test_inputs_agree(sphere3):
    V, F = sphere3
    t = o3d.t.geometry.TriangleMesh()
    t.vertex.positions = o3d.core.Tensor(V)
    t.triangle.indices = o3d.core.Tensor(F)
    leg = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(V), o3d.utility.Vector3iVector(F))
    a, b, c = (o3dheat.eigensolve(m, k=8, method="arpack") for m in ((V, F), t, leg))
    np.testing.assert_array_equal(a.eigenvalues, b.eigenvalues)
    np.testing.assert_array_equal(a.eigenvectors, c.eigenvectors)


def test_reproducible_and_signs_fixed(irregular_mesh):
    a = o3dheat.eigensolve(irregular_mesh, k=12, method="arpack")
    b = o3dheat.eigensolve(irregular_mesh, k=12, method="arpack")
    np.testing.assert_array_equal(a.eigenvectors, b.eigenvectors)
    X = a.eigenvectors
    assert np.all(X[np.argmax(np.abs(X), axis=0), np.arange(12)] > 0)


def test_several_components():
    V, F = icosphere(2)
    V2 = np.concatenate([V, 0.5 * V + [4, 0, 0], V + [0, 5, 0]])
    F2 = np.concatenate([F, F + len(V), F + 2 * len(V)])
    s = o3dheat.eigensolve((V2, F2), k=6, method="arpack")
    np.testing.assert_allclose(s.eigenvalues[:3], 0, atol=1e-9)
    assert s.eigenvalues[3] > 1
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(6), atol=1e-10)


def test_full_spectrum_dense():
    V, F = icosphere(1)
    s = o3dheat.eigensolve((V, F), k=len(V))
    assert s.backend == "dense" and s.k == len(V)
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(len(V)), atol=1e-10)


@pytest.mark.parametrize("k", [0, -3, 2.5, True, "10"])
def test_bad_k(k):
    with pytest.raises(o3dheat.MeshError, match="k must"):
        o3dheat.eigensolve(icosphere(1), k=k)


def test_k_larger_than_n():
    with pytest.raises(o3dheat.MeshError, match="exceeds the number"):
        o3dheat.eigensolve(icosphere(1), k=1000)


def test_bad_sigma_and_mass():
    with pytest.raises(o3dheat.MeshError, match="sigma"):
        o3dheat.eigensolve(icosphere(1), k=3, sigma=0.5)
    with pytest.raises(o3dheat.MeshError, match="unknown mass"):
        o3dheat.eigensolve(icosphere(1), k=3, mass="cotan")
    with pytest.raises(o3dheat.MeshError, match="unknown backend"):
        o3dheat.eigensolve(icosphere(3), k=3, backend="mkl", method="arpack")


def test_dense_refused_when_too_large(monkeypatch):
    import o3dheat.spectral._solvers as S

    V, F = icosphere(2)  # 162 vertices
    ref = o3dheat.eigensolve((V, F), k=100).eigenvalues  # k > n/2: dense
    monkeypatch.setattr(S, "DENSE_LIMIT_N", 100)
    with pytest.raises(o3dheat.MeshError, match="GiB"):
        o3dheat.eigensolve((V, F), k=10, method="dense")
    s = o3dheat.eigensolve((V, F), k=100)  # too large for dense here: iterative instead
    assert s.backend != "dense"
    np.testing.assert_allclose(s.eigenvalues, ref, rtol=1e-9, atol=1e-9)


def test_eigensolve_operators_matches_eigensolve():
    import scipy.sparse as sp
    from conftest import icosphere

    from o3dheat.spectral.spectrum import eigensolve_operators

    V, F = icosphere(3)
    ref = o3dheat.eigensolve((V, F), k=12)
    s = eigensolve_operators(ref.stiffness, ref.mass, k=12)
    assert np.allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-8, atol=1e-10)
    assert s.faces is None and s.mass_kind == "given"
    with pytest.raises(o3dheat.MeshError, match="symmetric"):
        eigensolve_operators(sp.triu(ref.stiffness), ref.mass, k=3)
    with pytest.raises(o3dheat.MeshError, match="exceeds"):
        eigensolve_operators(ref.stiffness, ref.mass, k=10**6)


def test_auto_method_follows_the_measured_crossovers():
    from o3dheat.spectral._solvers import _choose_method

    assert _choose_method("auto", 1000, 10) == "dense"
    assert _choose_method("auto", 5000, 30) == "arpack"
    assert _choose_method("auto", 5000, 100) == "lanczos"  # many eigenpairs: blocks pay off early
    assert _choose_method("auto", 2500, 100) == "arpack"
    assert _choose_method("auto", 20000, 10) == "lanczos"
    assert _choose_method("auto", 5000, 4999) == "dense"
    assert _choose_method("arpack", 50000, 10) == "arpack"


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(8, 40), frac=st.floats(0.2, 0.95),
       method=st.sampled_from(["lanczos", "arpack", "auto"]))
def test_small_meshes_every_method_matches_dense(seed, n, frac, method):
    """Random Delaunay disks of 8-40 vertices: every method succeeds (falling back where it must)
    and gives the dense solver's eigenvalues and B-orthonormal eigenvectors."""
    import scipy.spatial

    rng = np.random.default_rng(seed)
    r, a = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    P = np.c_[r * np.cos(a), r * np.sin(a)]
    V = np.c_[P, 0.3 * rng.standard_normal(n)]  # a random height: not flat
    F = scipy.spatial.Delaunay(P).simplices
    k = max(1, min(n - 1, int(frac * n)))
    dense = o3dheat.eigensolve((V, F), k=k, method="dense")
    s = o3dheat.eigensolve((V, F), k=k, method=method)
    scale = max(dense.eigenvalues[-1], 1.0)
    np.testing.assert_allclose(s.eigenvalues, dense.eigenvalues, atol=1e-8 * scale)
    np.testing.assert_allclose(s.eigenvectors.T @ (s.mass @ s.eigenvectors), np.eye(k), atol=1e-8)
    assert s.residuals.max() < 1e-7  # the Lanczos tolerance 1e-8 is on its own residual estimate


def test_lanczos_failure_falls_back(monkeypatch, irregular_mesh, caplog):
    import o3dheat.spectral._solvers as S
    from o3dheat.errors import ConvergenceError

    def broken(*a, **kw):
        raise ConvergenceError("block Lanczos did not converge after 100 restarts")

    monkeypatch.setattr(S, "_solve_lanczos", broken)
    ref = o3dheat.eigensolve(irregular_mesh, k=12, method="arpack")
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve(irregular_mesh, k=12, method="lanczos")
    assert "falling back to 'arpack'" in caplog.text
    np.testing.assert_allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-10, atol=1e-12)


# ---------------------------------------------------------------- unwelded meshes (issue 13)
def _split(V, F):
    """Every face with its own three vertex copies (an STL file), and the reference weld: the
    welded mesh numbered by first copies, and the map input vertex -> welded vertex."""
    Vs, Fs = V[F].reshape(-1, 3), np.arange(3 * len(F)).reshape(-1, 3)
    _, first, inv = np.unique(Vs, axis=0, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    w = rank[inv.reshape(-1)]
    return (Vs, Fs), (Vs[np.sort(first)], w[Fs]), w


def _check_welded_spectrum(su, sw, w, k):
    np.testing.assert_allclose(su.eigenvalues, sw.eigenvalues, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(su.eigenvectors, sw.eigenvectors[w], rtol=0, atol=1e-12)
    X, L, B = su.eigenvectors, su.stiffness, su.mass
    np.testing.assert_allclose(X.T @ (B @ X), np.eye(k), atol=1e-10)
    scale = abs(L).max() * max(abs(X).max(), 1)
    np.testing.assert_allclose(L @ X, (B @ X) * su.eigenvalues, atol=1e-8 * scale)
    np.testing.assert_allclose(B.sum(), sw.mass.sum(), rtol=1e-12)
    np.testing.assert_allclose(su.areas.sum(), sw.areas.sum(), rtol=1e-12)


@pytest.mark.parametrize("mass", ["consistent", "voronoi", "identity"])
def test_split_vertex_mesh_equals_welded(mass):
    V, F = icosphere(2)
    soup, welded, w = _split(V, F)
    su, sw = o3dheat.eigensolve(soup, k=12, mass=mass), o3dheat.eigensolve(welded, k=12, mass=mass)
    assert su.n == len(soup[0]) and sw.n == len(V)
    _check_welded_spectrum(su, sw, w, 12)
    np.testing.assert_array_equal(su.faces, np.sort(np.unique(w, return_index=True)[1])[welded[1]])
    # the kernel: a field equal on the copies gives the welded result on every copy; constants kept
    Ku, Kw = o3dheat.HeatKernel(su), o3dheat.HeatKernel(sw)
    t = Kw.scales(4)
    g = welded[0][:, 0] + np.sin(3 * welded[0][:, 2])
    np.testing.assert_allclose(Ku.smooth(g[w], t), Kw.smooth(g, t)[w], atol=1e-12)
    np.testing.assert_allclose(Ku.smooth(np.ones(su.n), t), 1.0, atol=1e-12)
    # a field that differs between copies is averaged over them
    f = np.random.default_rng(0).standard_normal(su.n)
    mean = np.bincount(w, f) / np.bincount(w)
    np.testing.assert_allclose(Ku.smooth(f, t), Kw.smooth(mean, t)[w], atol=1e-12)


def test_split_vertex_diffusion_equals_welded():
    V, F = grid(1, 1, 8, 6)
    soup, welded, w = _split(V, F)
    f = np.cos(3 * welded[0][:, 0]) + welded[0][:, 1]
    for scheme in ("explicit", "implicit"):
        a = o3dheat.diffuse(soup, f[w], dt=1e-4, steps=5, scheme=scheme)
        b = o3dheat.diffuse(welded, f, dt=1e-4, steps=5, scheme=scheme)
        np.testing.assert_allclose(a, b[w], atol=1e-13)


def test_stl_round_trip_is_welded(tmp_path, caplog):
    from o3dheat.io import sample_mesh

    path = str(tmp_path / "bunny.stl")
    m = sample_mesh("bunny").to_legacy()
    assert o3d.io.write_triangle_mesh(path, m.compute_triangle_normals())
    stl = o3d.io.read_triangle_mesh(path)
    Vs, Fs = o3dheat.as_arrays(stl)
    assert len(Vs) > 2.99 * len(Fs) and len(Vs) > 5 * len(m.vertices)  # (nearly) 3 copies per face
    _, first, inv = np.unique(Vs, axis=0, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    w = rank[inv.reshape(-1)]
    welded = (Vs[np.sort(first)], w[Fs])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        su = o3dheat.eigensolve(stl, k=10)
    assert f"welded {len(Vs) - len(first)} duplicate vertices" in caplog.text
    sw = o3dheat.eigensolve(welded, k=10)
    assert su.eigenvalues[1] > 1.0  # not the all-zero spectrum of 56k one-triangle components
    _check_welded_spectrum(su, sw, w, 10)
    r, rw = o3dheat.check_mesh(stl), o3dheat.check_mesh(welded)
    assert rw.ok and not r.ok and r.welded_vertices == len(Vs) - len(first)
    assert (r.components, r.euler_characteristic, r.genus, r.boundary_loops) == \
        (rw.components, rw.euler_characteristic, rw.genus, rw.boundary_loops) == (1, 2, 0, 0)
    assert "welded" in str(r).splitlines()[-1]


def test_k_not_above_the_number_of_components_is_explained(caplog):
    V, F = icosphere(1)
    parts = [(V + [3.0 * i, 0, 0], F + len(V) * i) for i in range(3)]
    mesh = (np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts]))
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve(mesh, k=3)
    assert "3 connected components" in caplog.text and "k > 3" in caplog.text
    with pytest.raises(o3dheat.MeshError, match="connected"):
        o3dheat.HeatKernel(s).scales()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        s = o3dheat.eigensolve(mesh, k=4)
    assert "connected components" not in caplog.text and s.eigenvalues[3] > 1


@pytest.mark.parametrize("alpha", [1e-90, 1e-20, 1e20, 1e90])
@pytest.mark.parametrize("method", ["arpack", "lanczos", "dense"])
def test_extreme_coordinate_scales_are_exactly_covariant(irregular_mesh, alpha, method):
    """Micrometres or astronomical units: solved at a power-of-two scale, λ(αM) = λ(M)/α² and
    Φ_{α² t}(αM) = Φ_t(M) to rounding; beyond 1e±100 the mesh is refused (areas overflow)."""
    V, F = irregular_mesh
    ref = o3dheat.eigensolve((V, F), k=8, method=method)
    s = o3dheat.eigensolve((alpha * V, F), k=8, method=method)
    np.testing.assert_allclose(s.eigenvalues[1:] * alpha**2, ref.eigenvalues[1:], rtol=1e-8)
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(8), atol=1e-10)
    f = V[:, 0]
    np.testing.assert_allclose(o3dheat.HeatKernel(s).smooth(f, 0.1 * alpha**2), o3dheat.HeatKernel(ref).smooth(f, 0.1),
                               atol=1e-7)


def test_beyond_the_representable_scales_the_mesh_is_refused(irregular_mesh):
    V, F = irregular_mesh
    for alpha in (1e-150, 1e150):
        with pytest.raises(o3dheat.MeshError, match="rescale it"):
            o3dheat.eigensolve((alpha * V, F), k=4)


def test_eigensolve_refuses_what_does_not_fit_in_memory(monkeypatch, irregular_mesh):
    import o3dheat.memory as mm
    import o3dheat.spectral._solvers as S

    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": 10_000})  # bytes
    monkeypatch.setattr(S, "available_memory", lambda: 10_000)
    analyze = S.analyze
    monkeypatch.setattr(S, "analyze", lambda *a: pytest.fail("the ordering ran before the refusal"))
    # the basis alone does not fit: refused before the ordering (minutes at 10M vertices)
    with pytest.raises(OutOfMemory, match="eigenpairs on .* vertices, its factor aside, needs about .* GiB"):
        o3dheat.eigensolve(irregular_mesh, k=20, method="lanczos")
    # the rest fits, the factor does not: refused after its symbolic analysis, by the whole estimate
    n = len(irregular_mesh[0])
    room = mm.peak_memory(n, 20, 8, 0) + 1
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": room})
    monkeypatch.setattr(S, "analyze", analyze)
    with pytest.raises(OutOfMemory, match="eigenpairs on .* vertices needs about .* GiB"):
        o3dheat.eigensolve(irregular_mesh, k=20, method="lanczos")
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": 10_000})
    with pytest.raises(OutOfMemory, match="dense eigensolve"):
        o3dheat.eigensolve(irregular_mesh, k=20, method="dense")


def test_the_supernodal_path_gives_the_same_spectrum(monkeypatch):
    import o3dheat.spectral.linalg as la

    V, F = torus()
    ref = o3dheat.eigensolve((V, F), k=40, method="lanczos")  # simplicial LDLᵀ (small mesh)
    monkeypatch.setattr(la, "SUPERNODAL_MIN_N", 0)  # large meshes' factorization, on a small one
    s = o3dheat.eigensolve((V, F), k=40, method="lanczos")
    np.testing.assert_allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-9, atol=1e-9)
    assert s.residuals.max() < 1e-8


def test_multiple_eigenvalues_have_one_basis_whatever_the_solver():
    """Issue 22: the icosphere's multiple eigenvalues (icosahedral symmetry: clusters of 3, 5, 3+4)
    got a different basis from each solver and from concurrent dense solves; now the canonical one
    (the polar factor against a seeded block), signs included, to rounding."""
    from concurrent.futures import ThreadPoolExecutor

    V, F = icosphere(3)
    ref = o3dheat.eigensolve((V, F), k=16, method="dense", cache=False)
    lam = ref.eigenvalues
    assert np.sum(np.diff(lam[1:4]) < 1e-9 * lam[3]) == 2  # a genuine triple eigenvalue
    others = [o3dheat.eigensolve((V, F), k=16, method=m, cache=False) for m in ("arpack", "lanczos")]
    with ThreadPoolExecutor(4) as pool:
        others += list(pool.map(lambda _: o3dheat.eigensolve((V, F), k=16, method="dense", cache=False),
                                range(4)))
    for s in others:
        np.testing.assert_allclose(s.eigenvectors, ref.eigenvectors, atol=1e-7)
    # a basis rotated inside the eigenspace by hand is brought back to the same one
    from o3dheat.spectral._solvers import _canonical_bases
    Q = np.linalg.qr(np.random.default_rng(3).standard_normal((3, 3)))[0]
    X = ref.eigenvectors.copy()
    X[:, 1:4] = X[:, 1:4] @ Q
    _canonical_bases(lam, X, ref.mass.tocsr(), 1.0)
    np.testing.assert_allclose(X, ref.eigenvectors, atol=1e-10)


def _uv_sphere():
    """Open3D's UV sphere (762 vertices): double eigenvalues (its rotations by 2π/40), and simple
    eigenvectors whose largest magnitudes are equal at mirrored vertices, with opposite signs."""
    return o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)


def _assert_same_spectrum(s, ref, simple_atol):
    """Eigenvalues to 1e-12 relative; eigenvectors of multiple eigenvalues (equal to 1e-9) to 1e-10,
    the others to ``simple_atol`` (which a sign flip, 2 max |x| ~ 1, exceeds)."""
    lam = ref.eigenvalues
    np.testing.assert_allclose(s.eigenvalues, lam, rtol=1e-12, atol=1e-12)
    tied = np.diff(lam) <= 1e-9 * np.maximum(lam[1:], 1.0)
    multiple = np.r_[tied, False] | np.r_[False, tied]
    assert multiple.sum() >= 10  # the mesh has them
    d = np.abs(s.eigenvectors - ref.eigenvectors).max(axis=0)
    assert d[multiple].max() < 1e-10, f"columns {np.flatnonzero(d > 1e-10).tolist()} differ by {d.max():.3g}"
    assert d.max() < simple_atol, f"columns {np.flatnonzero(d > simple_atol).tolist()} differ by {d.max():.3g}"


def test_concurrent_eigensolves_give_the_serial_result(monkeypatch):
    """Issue 30: four threads solving one sphere at once: one result's eigenvectors differed from the
    serial run's by 1.1-1.6. A dense solve pins BLAS to one thread (process-wide); the first
    thread to leave its pin put two threads back under another thread still solving, whose
    rounding then differed, and a largest entry tied to rounding flipped its eigenvector. Forced
    here: the second solve runs its LAPACK call after the first solve has ended."""
    import threading
    import types

    import scipy.linalg as sla
    from threadpoolctl import OpenBLASController, ThreadpoolController, threadpool_info

    import o3dheat.spectral._solvers as solvers

    def blas_threads():
        return {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}

    mesh = _uv_sphere()
    ref = o3dheat.eigensolve(mesh, k=30, method="dense", cache=False)
    limiter = ThreadpoolController().select(user_api="blas").limit(limits=2)  # as a fresh process with 2+ cores
    OpenBLASController.clear_controlling_thread()
    try:
        if min(blas_threads()) < 2:
            pytest.skip("BLAS cannot run two threads here")
        first_in, second_in, first_done = threading.Event(), threading.Event(), threading.Event()
        seen, out = {}, {}

        def eigh(*args, **kwargs):
            name = threading.current_thread().name
            if name == "first":
                first_in.set()
                second_in.wait(20)  # both solves inside their BLAS pins
            else:
                second_in.set()
                first_done.wait(20)  # the first solve has ended: the second goes on
            seen[name] = blas_threads()
            return sla.eigh(*args, **kwargs)

        monkeypatch.setattr(solvers, "sla", types.SimpleNamespace(**{**vars(sla), "eigh": eigh}))

        def solve(name, after=None):
            if after is not None:
                after.wait(20)
            try:
                out[name] = o3dheat.eigensolve(mesh, k=30, method="dense", cache=False)
            finally:
                if name == "first":
                    first_done.set()

        threads = [threading.Thread(target=solve, name="first", args=("first",)),
                   threading.Thread(target=solve, name="second", args=("second", first_in))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        assert seen == {"first": {1}, "second": {1}}, "a dense solve ran on BLAS threads another thread put back"
        for name in ("first", "second"):
            _assert_same_spectrum(out[name], ref, 1e-9)
    finally:
        OpenBLASController.clear_controlling_thread(force=True)
        limiter.restore_original_limits()
        OpenBLASController.clear_controlling_thread()


@pytest.mark.parametrize("method", ["dense", "arpack", "lanczos"])
def test_threads_at_once_give_the_serial_result(method):
    """Issue 30, unforced: 4 threads x 3 rounds of each method against the serial solve."""
    from concurrent.futures import ThreadPoolExecutor

    mesh = _uv_sphere()
    ref = o3dheat.eigensolve(mesh, k=30, method=method, cache=False)
    for _ in range(3):
        with ThreadPoolExecutor(4) as pool:
            outs = list(pool.map(lambda _: o3dheat.eigensolve(mesh, k=30, method=method, cache=False), range(4)))
        for s in outs:
            _assert_same_spectrum(s, ref, 1e-9)


def test_signs_do_not_follow_rounding():
    """Issue 30: the sign rule "largest magnitude positive" was decided by rounding where two
    largest magnitudes are equal with opposite signs (mirrored vertices): a solve rounded otherwise
    returned -x. Magnitudes within 1e-6 of the largest tie, and the first of them decides."""
    from o3dheat.spectral._solvers import SIGN_TIE, _fix_signs

    s = o3dheat.eigensolve(_uv_sphere(), k=30, method="dense", cache=False)
    X, lam = s.eigenvectors, s.eigenvalues
    A = np.abs(X)
    top2 = -np.sort(-A, axis=0)[:2]
    assert np.any((top2[0] - top2[1]) / top2[0] < 1e-11)  # ties to rounding: the case at stake
    tied = np.diff(lam) <= 1e-9 * np.maximum(lam[1:], 1.0)
    simple = ~(np.r_[tied, False] | np.r_[False, tied])  # (a multiple one's basis has its own signs)
    first = np.argmax(A >= (1 - SIGN_TIE) * A.max(axis=0), axis=0)
    assert np.all(X[first, np.arange(30)][simple] > 0)  # the rule, as documented
    for seed in range(8):  # a rounding-sized change of any solve gives the same signs
        noise = np.random.default_rng(seed).standard_normal(X.shape) * 1e-12 * A.max()
        for sign in (1.0, -1.0):
            np.testing.assert_allclose(_fix_signs(sign * X + noise)[:, simple], X[:, simple], atol=1e-10)


def test_methods_agree_on_a_symmetric_mesh():
    """Issue 30: on the UV sphere each method rounded the tied largest entries its own way, and
    flipped other eigenvectors than the dense solver (differences up to 2.6 at k = 60). k = 30
    ends a cluster; the near-double eigenvalues (relative gaps 3e-9..1e-8) leave their vectors
    determined to about 1e-6."""
    mesh = _uv_sphere()
    ref = o3dheat.eigensolve(mesh, k=31, method="dense", cache=False)
    assert ref.eigenvalues[30] > ref.eigenvalues[29] * (1 + 1e-6)  # k = 30 cuts no cluster
    dense = o3dheat.eigensolve(mesh, k=30, method="dense", cache=False)
    for method in ("arpack", "lanczos"):
        s = o3dheat.eigensolve(mesh, k=30, method=method, cache=False)
        np.testing.assert_allclose(s.eigenvalues, dense.eigenvalues, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(s.eigenvectors, dense.eigenvectors, atol=1e-5)


def test_save_and_load_give_back_the_spectrum_and_refuse_what_is_not_one(tmp_path, irregular_mesh):
    """Issue 22: a saved spectrum had no loader. Spectrum.save writes everything (operators, areas,
    faces, bounds); Spectrum.load checks it before returning it."""
    import dataclasses

    V, F = irregular_mesh
    V2 = np.vstack([V, [[9.0, 9.0, 9.0]]])  # an unreferenced vertex: expanded operators round-trip too
    s = o3dheat.eigensolve((V2, F), k=8, cache=False)
    p = tmp_path / "s.npz"
    s.save(p)
    t = o3dheat.Spectrum.load(p)
    for f in dataclasses.fields(s):
        a, b = getattr(s, f.name), getattr(t, f.name)
        if f.name == "timings":
            assert b == {"cache": True}
        elif hasattr(a, "nnz"):
            assert a.shape == b.shape and (a != b).nnz == 0
        elif isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b)
        elif isinstance(a, float) and np.isnan(a):
            assert np.isnan(b)
        else:
            assert a == b, f.name
    # the loaded spectrum works like the computed one
    f = V2[:, 2]
    np.testing.assert_allclose(o3dheat.HeatKernel(t).smooth(f, 0.01), o3dheat.HeatKernel(s).smooth(f, 0.01))
    with pytest.raises(o3dheat.MeshError, match="exists: pass overwrite=True"):
        s.save(p)
    s.save(p, overwrite=True)
    with pytest.raises(o3dheat.MeshError, match="saved as .npz"):
        s.save(tmp_path / "s.txt")
    # crafted or foreign files: named refusals
    with np.load(p) as z:
        data = dict(z)
    bad = {
        "copies of one eigenvector": dict(data, eigenvectors=np.repeat(data["eigenvectors"][:, 1:2], 8, axis=1),
                                          eigenvalues=np.full(8, data["eigenvalues"][1])),
        "do not solve": dict(data, eigenvalues=data["eigenvalues"] * 1.01),
        "not ascending": dict(data, eigenvalues=data["eigenvalues"][::-1]),
        "non-finite": dict(data, eigenvectors=np.where(data["eigenvectors"] > 0.5, np.nan, data["eigenvectors"])),
        "not a spectrum saved by o3dheat": {"eigenvalues": data["eigenvalues"]},
        "broken spectrum file": {k: v for k, v in data.items() if k != "mass_indptr"},
    }
    patterns = {"copies of one eigenvector": "not B-orthonormal|do not solve"}
    for name, d in bad.items():
        q = tmp_path / "bad.npz"
        np.savez(q, **d)
        with pytest.raises(o3dheat.MeshError, match=patterns.get(name, name)):
            o3dheat.Spectrum.load(q)
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(o3dheat.MeshError, match="not a readable .npz"):
        o3dheat.Spectrum.load(tmp_path / "junk.npz")
    with pytest.raises(o3dheat.MeshError, match="no such file"):
        o3dheat.Spectrum.load(tmp_path / "absent.npz")


def test_load_refuses_out_of_range_indices_and_other_crafted_fields(tmp_path, irregular_mesh):
    """Found in review: a mass with an index past n crashed Spectrum.load (segfault in the
    residuals); k = 0, NaN residuals, an unknown mass kind, a bound of the wrong shape and
    negative areas were not refused."""
    s = o3dheat.eigensolve(irregular_mesh, k=4, cache=False)
    p = tmp_path / "s.npz"
    s.save(p)
    with np.load(p) as z:
        data = dict(z)
    bad_idx = data["mass_indices"].copy()
    bad_idx[3] = 10**9
    cases = {"broken spectrum file": dict(data, mass_indices=bad_idx),
             "non-empty vector": dict(data, eigenvalues=np.zeros(0), eigenvectors=data["eigenvectors"][:, :0]),
             "non-finite": dict(data, residuals=np.full(4, np.nan)),
             "unknown mass": dict(data, mass_kind=np.array("bogus")),
             "inverse_mass_bound has shape": dict(data, inverse_mass_bound=np.ones(3)),
             "negative areas": dict(data, areas=-data["areas"])}
    for msg, d in cases.items():
        q = tmp_path / "bad.npz"
        np.savez(q, **d)
        with pytest.raises(o3dheat.MeshError, match=msg):
            o3dheat.Spectrum.load(q)


def test_load_refuses_float_or_text_faces_fifos_devices_and_lying_flags(tmp_path, irregular_mesh):
    """Issue 30: float faces (0.5, 1.7) were truncated to other vertices, text faces gave a raw
    UFuncTypeError, a FIFO blocked for good, save(overwrite="no") replaced the file ("no" is truthy),
    save onto a folder gave a bare IsADirectoryError."""
    import os
    import threading

    s = o3dheat.eigensolve(irregular_mesh, k=4, cache=False)
    p = tmp_path / "s.npz"
    s.save(p)
    with np.load(p) as z:
        data = dict(z)
    for faces in (data["faces"] + 0.5, data["faces"].astype(str)):
        q = tmp_path / "bad.npz"
        np.savez(q, **dict(data, faces=faces))
        with pytest.raises(o3dheat.MeshError, match="faces must be integer vertex indices"):
            o3dheat.Spectrum.load(q)
    fifo = tmp_path / "pipe.npz"
    os.mkfifo(fifo)
    outcome = []

    def load(path):
        try:
            o3dheat.Spectrum.load(path)
        except o3dheat.MeshError as e:
            outcome.append(str(e))

    for path, kind in ((fifo, "a FIFO"), ("/dev/zero", "a character device")):
        worker = threading.Thread(target=load, args=(path,), daemon=True)
        worker.start()
        worker.join(10)
        assert not worker.is_alive() and kind in outcome[-1]
    before = p.read_bytes()
    with pytest.raises(o3dheat.MeshError, match="overwrite must be True or False"):
        s.save(p, overwrite="no")
    with pytest.raises(o3dheat.MeshError, match="is a folder"):
        s.save(tmp_path)
    assert p.read_bytes() == before
