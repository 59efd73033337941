"""o3dheat.spectral.lanczos: the block shift-invert Lanczos against dense LAPACK."""

import numpy as np
import pytest
from conftest import icosphere, irregular, torus

import o3dheat
from o3dheat.spectral import fem
from o3dheat.spectral.lanczos import block_lanczos
from o3dheat.spectral.linalg import factorize


def operators(mesh):
    V, F = mesh
    L, B = fem.stiffness_matrix((V, F)).tocsr(), fem.mass_matrix((V, F)).tocsr()
    sigma = -0.01 * 4 * np.pi / B.sum()
    return L, B, sigma, factorize(L - sigma * B).solve


@pytest.mark.parametrize("mesh, k", [(irregular(), 30), (torus(), 40), (icosphere(3), 36)])
def test_matches_dense(mesh, k):
    ref = o3dheat.eigensolve(mesh, k=k, method="dense")
    s = o3dheat.eigensolve(mesh, k=k, method="lanczos")
    # multiple eigenvalues (the torus' pairs, the sphere's 2l+1 copies) are all found
    np.testing.assert_allclose(s.eigenvalues, ref.eigenvalues, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(s.eigenvectors.T @ s.mass @ s.eigenvectors, np.eye(k), atol=1e-10)
    assert s.residuals.max() < 1e-8  # backward error of the default tol=1e-8
    # same invariant subspaces: projections of the dense eigenvectors are kept
    P = s.eigenvectors.T @ (s.mass @ ref.eigenvectors[:, : k - 4])
    np.testing.assert_allclose(np.linalg.norm(P, axis=0), 1, atol=1e-7)


def test_restarts_and_small_blocks():
    L, B, sigma, solve = operators(irregular())
    ref = o3dheat.eigensolve(irregular(), k=20, method="dense").eigenvalues
    for block, basis in ((1, 30), (3, 32), (8, 40)):
        lam, X, info = block_lanczos(L, B, solve, 20, sigma, block=block, max_basis=basis)
        assert info["restarts"] > 0 and info["block"] == block
        np.testing.assert_allclose(lam, ref, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(X.T @ B @ X, np.eye(20), atol=1e-10)


@pytest.mark.parametrize("mesh, k", [(torus(), 40), (icosphere(3), 36)])
def test_locking_keeps_multiple_eigenvalues(mesh, k):
    """Converged Ritz pairs locked at restarts: multiple eigenvalues (pairs, 2l+1 copies) are still
    all found, the residuals stay below the tolerance, the result equals the dense solver's."""
    L, B, sigma, solve = operators(mesh)
    ref = o3dheat.eigensolve(mesh, k=k, method="dense").eigenvalues
    lam, X, info = block_lanczos(L, B, solve, k, sigma, block=4, max_basis=k + 12)
    assert info["restarts"] > 1 and 0 < info["locked"] < k
    np.testing.assert_allclose(lam, ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(X.T @ B @ X, np.eye(k), atol=1e-10)
    R = L @ X - (B @ X) * lam
    assert np.linalg.norm(R, axis=0).max() < 1e-7 * abs(L).sum(axis=0).max()


def test_reproducible():
    L, B, sigma, solve = operators(torus())
    a = block_lanczos(L, B, solve, 10, sigma, seed=3)
    b = block_lanczos(L, B, solve, 10, sigma, seed=3)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_too_small_for_lanczos():
    L, B, sigma, solve = operators(icosphere(0))
    with pytest.raises(o3dheat.SolverError, match="dense"):
        block_lanczos(L, B, solve, 11, sigma)


def test_auto_method_choice(irregular_mesh):
    s = o3dheat.eigensolve(irregular_mesh, k=800)  # k > n / 2: dense
    assert s.backend == "dense"
    with pytest.raises(o3dheat.MeshError, match="unknown method"):
        o3dheat.eigensolve(irregular_mesh, k=5, method="lobpcg")


def test_results_do_not_depend_on_the_thread_count(monkeypatch):
    """The row-parallel passes add their parts in a fixed order and the threaded solves split
    on CHOLMOD's column groups: 1, 2 or 3 threads give the same spectrum, bit for bit."""
    from o3dheat import parallel

    monkeypatch.setattr(parallel, "CHUNK", 256)  # 1152 vertices: 8 parts per pass
    out = []
    for t in (1, 2, 3):
        with parallel.threads(t):
            out.append(o3dheat.eigensolve(torus(), k=20, method="lanczos"))
    for s in out[1:]:
        np.testing.assert_array_equal(s.eigenvalues, out[0].eigenvalues)
        np.testing.assert_array_equal(s.eigenvectors, out[0].eigenvectors)
        np.testing.assert_array_equal(s.residuals, out[0].residuals)


def test_a_warm_start_block_gives_the_same_spectrum_with_fewer_solves():
    from o3dheat.geometry import interpolation, sampling

    V, F = icosphere(4)
    ref = o3dheat.eigensolve((V, F), k=40, method="dense")
    solves = {"cold": 0, "warm": 0}
    for seed in (1, 2, 3):  # a restart more or less decides one run: the saving shows on several
        Vj = sampling.jitter((V, F), amount=0.2, seed=seed)
        L, B, sigma, solve = operators((Vj.V, Vj.F))
        X0 = interpolation.transfer(ref.eigenvectors, (V, F), Vj.V)  # the reference's eigenvectors, moved over
        cold = block_lanczos(L, B, solve, 40, sigma)
        for s in (1, 2):
            start = X0 @ np.random.default_rng(s).standard_normal((40, 8))
            warm = block_lanczos(L, B, solve, 40, sigma, start=start)
            np.testing.assert_allclose(warm[0], cold[0], rtol=1e-10, atol=1e-12)
            solves["cold"] += cold[2]["solves"]
            solves["warm"] += warm[2]["solves"]
    assert solves["warm"] < solves["cold"]
    for bad in (start[:, :3], np.full_like(start, np.nan)):
        with pytest.raises(o3dheat.MeshError, match="start block"):
            block_lanczos(L, B, solve, 40, sigma, start=bad)
