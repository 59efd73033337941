"""WKS and SI-HKS (o3dheat.spectral.signatures): the formula on o3dheat's spectrum, pyFM's WKS on the
same eigenpairs and energies, the truncation bound against the complete spectrum, scale invariance of
the SI-HKS (and the exact one of the lambda2-normalised HKS), bad input in one line."""

import numpy as np
import open3d as o3d
import pytest
import scipy.linalg as sla
from conftest import icosphere, irregular

import o3dheat
from o3dheat.spectral import signatures


def formula(lam, X, e, sigma):
    """WKS(v, e) = Σ x_i(v)² g_i(e) / Σ g_i(e) over the non-zero eigenvalues, written out."""
    out = np.zeros((len(X), len(e)))
    for j, ej in enumerate(e):
        g = np.array([np.exp(-(ej - np.log(li)) ** 2 / (2 * sigma**2)) if li > 1e-9 else 0.0 for li in lam])
        out[:, j] = (X**2 @ g) / g.sum()
    return out


def test_wks_is_the_formula_and_pyfm_on_the_same_eigenpairs():
    pyfm = pytest.importorskip("pyFM.signatures")
    V, F = irregular()
    for mass in ("consistent", "lumped"):
        K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=40, mass=mass, cache=False))
        e, sigma = signatures.wks_energies(K, 12)
        W = K.wks(12)
        lam, X = K.spectrum.eigenvalues, K.spectrum.eigenvectors
        assert np.allclose(W, formula(lam, X, e, sigma), rtol=1e-12, atol=0)
        ref = pyfm.WKS(lam, X, e, sigma, scaled=True)
        assert np.allclose(W, ref, rtol=1e-10, atol=0), mass
    e = np.linspace(np.log(lam[1]), np.log(lam[-1]), 5)
    assert np.allclose(K.wks(e, sigma=0.3), pyfm.WKS(lam, X, e, 0.3, scaled=True), rtol=1e-10, atol=0)


def test_wks_truncation_bound_holds_against_the_complete_spectrum():
    V, F = icosphere(2)  # 162 vertices: the complete generalised eigenproblem, dense
    spec = o3dheat.eigensolve((V, F), k=60, cache=False)
    lam_all, X_all = sla.eigh(spec.stiffness.toarray(), spec.mass.toarray())
    K = o3dheat.HeatKernel(spec)
    e, sigma = signatures.wks_energies(K, 20)
    W, bound = K.wks(e, sigma=sigma / 3, return_bound=True)
    full = formula(np.maximum(lam_all, 0), X_all, e, sigma / 3)
    assert np.all(np.abs(full - W) <= bound * (1 + 1e-9) + 1e-12)
    assert bound[:, :5].max() < 1e-6 * W.max()  # far below log λ_k the truncation costs nothing


def test_si_hks_is_scale_invariant_and_lambda2_hks_exactly_so():
    V, F = irregular()
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=60, cache=False))
    a = K.si_hks()
    for s in (0.5, 2.0):
        Ks = o3dheat.HeatKernel(o3dheat.eigensolve((s * V, F), k=60, cache=False))
        b = Ks.si_hks()
        assert np.abs(a - b).max() < 0.02 * np.abs(a).max(), s  # "within a few per cent": to rounding here
        # the paper's normalisation: times in units of 1/λ_2, densities in 1/area: s² h_s = h exactly
        N, Ns = (o3dheat.HeatKernel(k.spectrum, normalize="lambda2") for k in (K, Ks))
        t = N.scales(5, grid="log")
        assert np.allclose(s**2 * Ns.hks(t), N.hks(t), rtol=1e-6)
    # not trivially constant: the descriptor tells vertices apart
    assert np.std(a[:, 1]) > 1e-3 * np.abs(a[:, 1]).mean()


def test_bad_input_is_one_line():
    V, F = icosphere(2)
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=20, cache=False))
    lam = K.spectrum.eigenvalues
    with pytest.raises(o3dheat.MeshError, match="log-energies must lie within the spectrum"):
        K.wks([np.log(lam[-1]) + 1.0])
    with pytest.raises(o3dheat.MeshError, match="sigma must be a positive number"):
        K.wks(5, sigma=0.0)
    with pytest.raises(o3dheat.MeshError, match="energies must be an integer from 2"):
        K.wks(1)
    with pytest.raises(o3dheat.MeshError, match="does not contain this surface's scale space"):
        o3dheat.HeatKernel(o3dheat.eigensolve((1e-6 * V, F), k=20, cache=False)).si_hks()
    with pytest.raises(o3dheat.MeshError, match="at least 2 non-zero eigenvalues"):
        o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=1, cache=False)).wks(4)
    with pytest.raises(o3dheat.MeshError, match="grid needs"):
        K.si_hks(grid=(1.0, 0, 1, 0.1))


def test_the_filters_write_the_kernels_descriptors(sphere=None):
    import o3dheat.pipelines.filters as flt

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)
    out = flt.apply(m, "wks", k=20, energies=7)
    K = o3dheat.HeatKernel(o3dheat.eigensolve(m, k=20))
    assert np.allclose(out.vertex["wks"].numpy(), K.wks(7))
    out = flt.apply(m, "si_hks", k=20, frequencies=5)
    assert np.allclose(out.vertex["si_hks"].numpy(), K.si_hks(5))
    with pytest.raises(o3dheat.MeshError, match="sigma must be > 0"):
        flt.get("wks", sigma=-1.0)
