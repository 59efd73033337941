"""o3dheat.spectral.kernel: the paper's properties (§2.1-§3.2) as identities."""

import numpy as np
import pytest
from conftest import icosphere, irregular
from hypothesis import given, settings
from hypothesis import strategies as st

import o3dheat
from o3dheat import HeatKernel


@pytest.fixture(scope="module")
def spec():
    return o3dheat.eigensolve(irregular(), k=40)


@pytest.fixture(scope="module")
def K(spec):
    return HeatKernel(spec)


@pytest.fixture(scope="module")
def full():
    """A complete spectrum (k = n) of a small irregular mesh: exact identities."""
    V, F = icosphere(1)
    V = V * [1.2, 1, 0.7] + 0.05 * np.random.default_rng(1).standard_normal(V.shape)
    return o3dheat.eigensolve((V, F), k=len(V))


def rng_field(n, seed=0, c=None):
    r = np.random.default_rng(seed)
    return r.standard_normal(n if c is None else (n, c))


def bnorm(B, f):
    return float(np.sqrt(f @ (B @ f)))


@settings(max_examples=25, deadline=None)
@given(a=st.floats(-1e3, 1e3), b=st.floats(-1e3, 1e3), t=st.floats(0, 1), seed=st.integers(0, 2**16))
def test_linearity(K, a, b, t, seed):
    n = K.n
    f, g = rng_field(n, seed), rng_field(n, seed + 1)
    lhs = K.smooth(a * f + b * g, t)
    rhs = a * K.smooth(f, t) + b * K.smooth(g, t)
    np.testing.assert_allclose(lhs, rhs, atol=1e-9 * (abs(a) + abs(b) + 1))


@settings(max_examples=25, deadline=None)
@given(t=st.floats(0, 2), seed=st.integers(0, 2**16))
def test_b_self_adjoint(K, t, seed):
    B = K.spectrum.mass
    f, g = rng_field(K.n, seed), rng_field(K.n, seed + 7)
    assert f @ (B @ K.smooth(g, t)) == pytest.approx(K.smooth(f, t) @ (B @ g), rel=1e-10, abs=1e-12)


def test_phi0_is_b_projection(K):
    X, B = K.spectrum.eigenvectors, K.spectrum.mass
    f = rng_field(K.n)
    P = X @ (X.T @ (B @ f))
    np.testing.assert_allclose(K.smooth(f, 0.0), P, atol=1e-12)
    np.testing.assert_allclose(K.smooth(P, 0.0), P, atol=1e-12)  # idempotent
    g = X @ rng_field(K.spectrum.k, 3)  # in the span: reproduced exactly
    np.testing.assert_allclose(K.smooth(g, 0.0), g, atol=1e-10)


def test_large_t_gives_weighted_mean(K):
    B = K.spectrum.mass
    f = rng_field(K.n) + 3.0
    mean = (np.ones(K.n) @ (B @ f)) / B.sum()
    np.testing.assert_allclose(K.smooth(f, 1e4), mean, rtol=1e-8)  # eigenvector accuracy of tol=1e-10


@pytest.mark.parametrize("alpha", [1e-3, 1e3])
def test_scale_covariance(spec, alpha):
    """K_t(αM) = K_{t/α²}(M) on an irregular, non-symmetric mesh (§2.2)."""
    V, F = irregular()
    scaled = o3dheat.eigensolve((alpha * V, F), k=40)
    np.testing.assert_allclose(scaled.eigenvalues[1:], spec.eigenvalues[1:] / alpha**2, rtol=1e-8)
    K1, K2 = HeatKernel(spec), HeatKernel(scaled)
    f = rng_field(len(V), 5)
    for t in (0.01, 0.1, 1.0):
        np.testing.assert_allclose(K2.smooth(f, t * alpha**2), K1.smooth(f, t), rtol=1e-7, atol=1e-9)
        # the kernel diagonal ("paper" HKS) is dimensionless: covariant as well; the density is 1/area
        np.testing.assert_allclose(K2.hks(t * alpha**2, form="paper"), K1.hks(t, form="paper"), rtol=1e-7)
        np.testing.assert_allclose(K2.hks(t * alpha**2) * alpha**2, K1.hks(t), rtol=1e-7)
    np.testing.assert_allclose(K2.scales(), K1.scales() * alpha**2, rtol=1e-8)


@pytest.mark.parametrize("alpha", [1e-3, 1e3])
def test_lambda2_normalised_kernel_is_scale_invariant(spec, alpha):
    V, F = irregular()
    K1 = HeatKernel(spec, normalize="lambda2")
    K2 = HeatKernel(o3dheat.eigensolve((alpha * V, F), k=40), normalize="lambda2")
    f = rng_field(len(V), 2)
    for t in (0.1, 1.0, 10.0):
        np.testing.assert_allclose(K2.smooth(f, t), K1.smooth(f, t), rtol=1e-7, atol=1e-9)
    assert K1.rates[1] == pytest.approx(1.0)


def test_paper_bounds(K):
    """Error, energy and noise bounds of §3.1."""
    X, B = K.spectrum.eigenvectors, K.spectrum.mass
    f = X @ rng_field(K.spectrum.k, 4)  # f in the span: f = Σ <f, x_i>_B x_i
    coef = np.abs(K.coefficients(f)).sum()
    e = 0.1 * rng_field(K.n, 9)
    lamX = np.linalg.norm(X, 2)
    lamB = np.linalg.eigvalsh(B.toarray()).max()
    for t in (0.0, 0.01, 0.1, 1.0):
        Ff = K.smooth(f, t)
        assert bnorm(B, f - Ff) <= 2 * coef + 1e-12
        assert bnorm(B, Ff) <= coef + 1e-12
        assert bnorm(B, Ff) <= bnorm(B, f) + 1e-12  # a contraction in the B-norm
        noise = K.smooth(f + e, t) - Ff
        assert bnorm(B, noise) <= K.n * bnorm(B, e)
        assert bnorm(B, noise) <= bnorm(B, e) + 1e-12
        assert np.linalg.norm(noise) <= lamX**2 * lamB * np.linalg.norm(e) + 1e-12
        assert np.linalg.norm(Ff) <= lamX**2 * lamB * np.linalg.norm(f) + 1e-12


def test_inverse_and_canonic_basis(K):
    f = rng_field(K.n, 11)
    X, B = K.spectrum.eigenvectors, K.spectrum.mass
    P = X @ (X.T @ (B @ f))
    for t in (0.0, 0.01, 0.05):
        np.testing.assert_allclose(K.inverse(K.smooth(f, t), t), P, atol=1e-8)
        np.testing.assert_allclose(K.smooth(K.inverse(f, t), t), P, atol=1e-8)
    e = np.zeros(K.n)
    e[17] = 1.0
    np.testing.assert_allclose(K.canonic_basis(17, 0.02), K.smooth(e, 0.02), atol=1e-14)
    many = K.canonic_basis([3, 17], 0.02)
    np.testing.assert_allclose(many[:, 1], K.canonic_basis(17, 0.02))
    # f_glob = Σ_{i∈A} f_i Φ_t(e_i): the linear combination of the canonic basis
    A = np.array([3, 17, 40])
    np.testing.assert_allclose(K.canonic_basis(A, 0.02) @ f[A], K.smooth(np.where(np.isin(np.arange(K.n), A), f, 0), 0.02),
                               atol=1e-12)


def test_exact_inverse_with_full_spectrum(full):
    for variant, sp_ in (("weighted", full), ("linear", None)):
        if sp_ is None:
            V, F = icosphere(1)
            sp_ = o3dheat.eigensolve((V, F), k=len(V), mass="identity")
        K = HeatKernel(sp_, variant=variant)
        f = rng_field(K.n, 3)
        np.testing.assert_allclose(K.smooth(K.inverse(f, 0.1), 0.1), f, atol=1e-9)
        np.testing.assert_allclose(K.inverse(K.smooth(f, 0.1), 0.1), f, atol=1e-9)
    # the paper's linear-time formula when B := I: α = X D_t^{-1} Xᵀ f
    X, lam = sp_.eigenvectors, sp_.eigenvalues
    np.testing.assert_allclose(K.inverse(f, 0.1), X @ (np.exp(lam * 0.05) * (X.T @ f)), atol=1e-12)


@pytest.fixture(scope="module")
def variant_kernels():
    """Every variant on its own truncated spectrum of the irregular mesh (k = 40 < n)."""
    return {v: o3dheat.heat_kernel(irregular(), k=40, variant=v) for v in o3dheat.VARIANTS}


@pytest.mark.parametrize("variant", list(o3dheat.VARIANTS))
def test_every_variant_is_a_heat_kernel(variant_kernels, variant):
    """K_t 1 = 1, 1ᵀ W K_t f = 1ᵀ W f, K_s K_t = K_{s+t}, K_t f -> W-weighted mean: for each variant,
    on a truncated spectrum of an irregular mesh."""
    K = variant_kernels[variant]
    W = K.spectrum.mass
    assert K.variant == variant and K.spectrum.mass_kind == o3dheat.VARIANTS[variant][0]
    one = np.ones(K.n)
    f = rng_field(K.n, 4) + 2.0
    t = K.scales(4, grid="log")
    np.testing.assert_allclose(K.smooth(one, t), 1.0, atol=1e-10)
    np.testing.assert_allclose(one @ (W @ K.smooth(f, t)), np.full(len(t), one @ (W @ f)), rtol=1e-10)
    for s_, t_ in ((t[0], t[1]), (t[1], t[2])):
        np.testing.assert_allclose(K.smooth(K.smooth(f, s_), t_), K.smooth(f, s_ + t_), atol=1e-10)
    mean = (one @ (W @ f)) / (one @ (W @ one))
    np.testing.assert_allclose(K.smooth(f, 1e3 / K.rates[1]), mean, rtol=1e-9)
    g = K.smooth(f, t[1])  # inverse on the span, in the variant's own inner product
    np.testing.assert_allclose(K.smooth(K.inverse(g, t[1]), t[1]), g, atol=1e-8)


def test_mismatched_variant_is_refused_and_would_not_be_a_kernel(variant_kernels):
    for v, K in variant_kernels.items():
        for other in o3dheat.VARIANTS:
            if other != v:
                with pytest.raises(o3dheat.MeshError, match="mass="):
                    HeatKernel(K.spectrum, variant=other)
    # why: the old "linear" kernel X D_t Xᵀ on the consistent-mass spectrum does not keep constants
    X, lam = variant_kernels["weighted"].spectrum.eigenvectors, variant_kernels["weighted"].spectrum.eigenvalues
    Kt1 = X @ (np.exp(-lam * 0.01 / 2) * (X.T @ np.ones(len(X))))
    assert np.abs(Kt1 - 1).max() > 1.0
    with pytest.raises(o3dheat.MeshError, match="mass"):
        o3dheat.heat_kernel(irregular(), k=5, mass="lumped")
    with pytest.raises(o3dheat.MeshError, match="variant"):
        o3dheat.heat_kernel(irregular(), k=5, variant="sun")


def test_inverse_ill_conditioned(K):
    with pytest.raises(o3dheat.SolverError, match="amplifies"):
        K.inverse(rng_field(K.n), 1e6)


def test_variants_match_dense_formulas():
    """Complete spectra (k = n): each variant is exactly X D_t Xᵀ W of its own generalized
    eigenproblem, an exact heat semigroup with K_0 = I; the HKS forms are the kernel diagonal and
    Σ e^{-λt/2} x²."""
    import scipy.linalg as sla

    V, F = icosphere(1)
    V = V * [1.2, 1, 0.7] + 0.05 * np.random.default_rng(1).standard_normal(V.shape)
    L = o3dheat.stiffness_matrix((V, F)).toarray()
    weights = {"weighted": o3dheat.mass_matrix((V, F)).toarray(), "linear": np.eye(len(V)),
               "voronoi": o3dheat.mass_matrix((V, F), "voronoi").toarray(),
               "lumped": o3dheat.mass_matrix((V, F), "lumped").toarray()}
    t = 0.3
    f = rng_field(len(V), 1)
    for variant, W in weights.items():
        lam, X = sla.eigh(L, W)  # independent dense reference
        lam = np.maximum(lam, 0)
        Kt = X @ np.diag(np.exp(-lam * t / 2)) @ X.T @ W
        K = o3dheat.heat_kernel((V, F), k=len(V), variant=variant)
        np.testing.assert_allclose(K.spectrum.eigenvalues, lam, atol=1e-9)
        np.testing.assert_allclose(K.smooth(f, t), Kt @ f, atol=1e-10)
        np.testing.assert_allclose(K.hks(t, form="paper"), np.diag(Kt), atol=1e-10)
        np.testing.assert_allclose(K.hks(t), np.diag(X @ np.diag(np.exp(-lam * t / 2)) @ X.T), atol=1e-10)
        np.testing.assert_allclose(K.smooth(K.smooth(f, 0.2), 0.1), K.smooth(f, 0.3), atol=1e-12)
        np.testing.assert_allclose(K.smooth(f, 0.0), f, atol=1e-9)
        np.testing.assert_allclose(K.smooth(K.inverse(f, 0.1), 0.1), f, atol=1e-8)


def test_log_grid_spans_the_useful_range(K):
    t = K.scales(10, grid="log")
    assert np.all(np.diff(t) > 0)
    assert t[0] == pytest.approx(1 / K.rates[-1])
    assert t[-1] == pytest.approx(2 * np.log(100) / K.rates[1])
    f = rng_field(K.n, 3)
    mean = (np.ones(K.n) @ (K.spectrum.mass @ f)) / K.spectrum.mass.sum()
    last = K.smooth(f, t[-1])
    first_dev = np.abs(K.smooth(f, 0.0) - mean).max()
    assert np.abs(last - mean).max() < 0.02 * first_dev  # nearly constant at the end of the grid
    paper = K.scales(10)
    assert paper[-1] <= t[0] * (1 + 1e-12)  # the paper's grid lies below the log grid's start
    with pytest.raises(o3dheat.MeshError, match="grid"):
        K.scales(3, grid="linear")
    with pytest.raises(o3dheat.MeshError, match="count"):
        K.scales(10**8)


def test_sphere_hks_density_matches_analytic():
    V, F = icosphere(4)
    R = 2.0
    K = HeatKernel(o3dheat.eigensolve((R * V, F), k=100))
    t = np.array([0.5, 1.0, 2.0]) * R**2
    l = np.arange(60)
    truth = [(2 * l + 1) @ np.exp(-l * (l + 1) * tt / (2 * R**2)) / (4 * np.pi * R**2) for tt in t]
    h = K.hks(t, form="density")
    np.testing.assert_allclose(h.mean(0), truth, rtol=0.01)
    np.testing.assert_allclose(h, np.broadcast_to(truth, h.shape), rtol=0.05)


def test_transfer_functions(spec):
    K = HeatKernel(spec)
    f = rng_field(K.n, 2)
    t = np.array([0.01, 0.1])
    np.testing.assert_allclose(HeatKernel(spec, transfer=[0, 1]).smooth(f, t), K.smooth(f, t))
    np.testing.assert_allclose(HeatKernel(spec, transfer=lambda x: 2 * x).smooth(f, t), K.smooth(f, 2 * t))
    poly = HeatKernel(spec, transfer=[0, 1, 0.5])
    lam = spec.eigenvalues
    X, B = spec.eigenvectors, spec.mass
    expected = X @ (np.exp(-(lam + 0.5 * lam**2) * 0.01 / 2) * (X.T @ (B @ f)))
    np.testing.assert_allclose(poly.smooth(f, 0.01), expected, atol=1e-12)
    with pytest.raises(o3dheat.MeshError, match="transfer"), np.errstate(invalid="ignore", divide="ignore"):
        HeatKernel(spec, transfer=lambda x: np.log(x - 1))
    with pytest.raises(o3dheat.MeshError, match="transfer"):
        HeatKernel(spec, transfer=[[1, 2]])


def test_batched_shapes(K):
    f = rng_field(K.n, 1, c=3)
    t = K.scales(4)
    out = K.smooth(f, t)
    assert out.shape == (K.n, 3, 4)
    for j in range(3):
        np.testing.assert_allclose(out[:, j, :], K.smooth(f[:, j], t), atol=1e-12)
        for i in range(4):
            np.testing.assert_allclose(out[:, j, i], K.smooth(f[:, j], t[i]), atol=1e-12)
    assert K.smooth(f, 0.1).shape == (K.n, 3)
    assert K.hks(0.1).shape == (K.n,) and K.hks(t).shape == (K.n, 4)


def test_scales_and_error(K):
    s = K.scales()
    lk = K.spectrum.eigenvalues[-1]
    np.testing.assert_allclose(s, np.arange(1, 11) / 10 / lk)
    f = rng_field(K.n, 6)
    X, B = K.spectrum.eigenvectors, K.spectrum.mass
    e0 = np.abs(f - X @ (X.T @ (B @ f))).max() / np.abs(f).max()
    assert K.error(f, 0.0) == pytest.approx(e0)
    err = K.error(f, s)
    assert err.shape == (10,) and np.all(np.diff(err) >= -1e-12)
    assert K.error(np.zeros(K.n), s).max() == 0


def test_truncation_bound_holds(full):
    """‖Φ_t f − Φ_t^{(k)} f‖_B <= bound · ‖f‖_B, checked against the complete spectrum."""
    import copy
    Kf = HeatKernel(full)
    f = rng_field(full.n, 4)
    B = full.mass
    for k in (5, 12, 25):
        part = copy.copy(full)
        part.eigenvalues, part.eigenvectors = full.eigenvalues[:k], full.eigenvectors[:, :k]
        Kk = HeatKernel(part)
        for t in (0.0, 0.05, 0.5):
            diff = Kf.smooth(f, t) - Kk.smooth(f, t)
            assert bnorm(B, diff) <= Kk.truncation_bound(f, t) * bnorm(B, f) * (1 + 1e-9) + 1e-14


def test_suggest_k():
    V, F = icosphere(4)
    K = HeatKernel(o3dheat.eigensolve((V, F), k=60))
    t, tol = 0.05, 1e-3
    k = K.suggest_k(t, tol)
    big = o3dheat.eigensolve((V, F), k=k)
    factor = np.exp(-big.eigenvalues[-1] * t / 2)
    assert tol / 5 < factor < 5 * tol


def test_bad_input(K, spec):
    n = K.n
    with pytest.raises(o3dheat.MeshError, match="shape"):
        K.smooth(np.ones(n + 1), 0.1)
    f = np.ones(n)
    f[5] = np.nan
    with pytest.raises(o3dheat.MeshError, match="NaN"):
        K.smooth(f, 0.1)
    with pytest.raises(o3dheat.MeshError, match=">= 0"):
        K.smooth(np.ones(n), -0.1)
    with pytest.raises(o3dheat.MeshError, match="finite"):
        K.hks([0.1, np.nan])
    with pytest.raises(o3dheat.MeshError, match="variant"):
        HeatKernel(spec, variant="cotan")
    with pytest.raises(o3dheat.MeshError, match="normalize"):
        HeatKernel(spec, normalize="area")
    with pytest.raises(o3dheat.MeshError, match="Spectrum"):
        HeatKernel(np.eye(3))
    with pytest.raises(o3dheat.MeshError, match="out of range"):
        K.canonic_basis(n, 0.1)
    with pytest.raises(o3dheat.MeshError, match="form"):
        K.hks(0.1, form="sun")
    with pytest.raises(o3dheat.MeshError, match="count"):
        K.scales(0)


def test_finite_input_never_gives_silent_inf(K, spec):
    f = rng_field(K.n, 5)
    big = f * (1e308 / np.abs(f).max())
    for t in (0.0, 0.01):
        np.testing.assert_allclose(K.smooth(big, t) / 1e308, K.smooth(big / 1e308, t), rtol=1e-12, atol=1e-14)
    assert np.all(np.isfinite(K.smooth(big, [0.01, 0.1])))
    np.testing.assert_allclose(K.error(big, 0.01), K.error(f, 0.01), rtol=1e-12)
    tiny = f * 1e-300
    np.testing.assert_allclose(K.smooth(tiny, 0.01) / 1e-300, K.smooth(f, 0.01), rtol=1e-10)
    with pytest.raises(o3dheat.SolverError, match="overflow"):
        HeatKernel(spec, transfer=lambda lam: -1e300 * lam).smooth(f, 1.0)
    with pytest.raises(o3dheat.SolverError, match="float64 range"):
        K.inverse(big, 2 * np.log(1e10) / K.rates[-1])  # amplifies the top mode by 1e10


# ------------------------------------------------------------------------ truncation certificates
def _certificate_meshes():
    from conftest import grid, irregular
    from test_heatflow import two_parts

    V, F = icosphere(2)
    V2 = np.vstack([V, [[5.0, 5.0, 5.0]], V[F[0]]])  # an unreferenced vertex, welded copies of a face
    F2 = np.vstack([F[1:], len(V) + 1 + np.arange(3)[None]])
    return {"irregular": irregular(), "boundary": grid(2.0, 1.0, 24, 12, jitter=0.3), "two parts": two_parts(),
            "welded": (V2, F2)}


@pytest.mark.parametrize("variant", list(o3dheat.VARIANTS))
def test_truncation_certificates_hold_against_complete_spectra(variant):
    for name, (V, F) in _certificate_meshes().items():
        n_ref = len(o3dheat.geometry.welding.prepare((V, F)).V)
        full = o3dheat.heat_kernel((V, F), k=n_ref, variant=variant)
        part = o3dheat.heat_kernel((V, F), k=30, variant=variant)
        t = np.array([0.0, 1e-3, 1e-2, 0.1, 1.0, 40.0]) / part.spectrum.eigenvalues[-1]
        W = full.spectrum.mass
        f = np.column_stack([V[:, 0] + np.sin(5 * V[:, 1]), V[:, 0] * V[:, 1] + V[:, 2] ** 2])
        F_part, bound = part.smooth(f, t, return_bound=True)
        E = full.smooth(f, t) - F_part
        WE = (W @ E.reshape(len(V), -1)).reshape(E.shape)
        err = np.sqrt(np.maximum(np.einsum("ict,ict->ct", E, WE), 0.0))
        nf = np.sqrt(np.einsum("ic,ic->c", f, W @ f))[:, None]
        assert np.all(err / nf <= bound * (1 + 1e-9) + 1e-12), (name, (err / nf - bound).max())  # = at t = 0
        assert bound[:, -1].max() < 1e-7  # late: exp(-20)
        for form in o3dheat.spectral.variants.HKS_FORMS:
            h, hb = part.hks(t, form=form, return_bound=True)
            d = full.hks(t, form=form) - h
            slack = 1e-9 * np.abs(full.hks(t, form=form)).max()
            if form == "density":
                assert np.all(d >= -slack), (name, form)  # the truncation only leaves out positive terms
            assert np.all(np.abs(d) <= hb + slack), (name, form, (np.abs(d) - hb).max())
        assert hb[:, -1].max() < 1e-5 * np.abs(h[:, -1]).max()  # late: exp(-20) times the tails


def test_certificates_need_an_increasing_transfer_function():
    V, F = icosphere(2)
    spec = o3dheat.eigensolve((V, F), k=20)
    f = V[:, 0]
    ok = o3dheat.HeatKernel(spec, transfer=[0.0, 1.0, 0.1])
    ok.smooth(f, 0.1, return_bound=True)
    ok.hks(0.1, return_bound=True)
    for transfer in ([0.0, 1.0, -0.1], lambda lam: lam):
        K = o3dheat.HeatKernel(spec, transfer=transfer)
        with pytest.raises(o3dheat.MeshError, match="transfer function that increases"):
            K.smooth(f, 0.1, return_bound=True)
        with pytest.raises(o3dheat.MeshError, match="transfer function that increases"):
            K.hks(0.1, return_bound=True)


# -------------------------------------- issue 30: the certificates bound what is returned
def _random_ellipsoid(n=500, seed=3):
    """An irregular closed mesh: the convex hull of random points on a sphere (slivers, triangles of
    very different sizes), stretched to an ellipsoid."""
    from scipy.spatial import ConvexHull

    P = np.random.default_rng(seed).standard_normal((n, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    return P * [1.3, 1.0, 0.8], ConvexHull(P).simplices.astype(np.int64)


_REFERENCES = {}


def _exact(name):
    """(V, F, W, λ, X): the complete dense generalized eigendecomposition of (L, B), its null vector
    replaced by the exact normalised constant (eigh's own is off by 1e-13..1e-12: more than the
    rounding to be checked)."""
    import scipy.linalg as sla

    if name not in _REFERENCES:
        V, F = icosphere(3) if name == "sphere" else _random_ellipsoid()
        L, B = (M.toarray() for M in o3dheat.spectral.fem.operators(V, F, "consistent")[:2])
        lam, X = sla.eigh(L, B)
        lam[0] = 0.0
        X[:, 0] = 1.0 / np.sqrt(B.sum())
        _REFERENCES[name] = V, F, B, lam, X
    return _REFERENCES[name]


@pytest.mark.parametrize("method", ["auto", "lanczos"])
@pytest.mark.parametrize("name", ["sphere", "irregular"])
def test_certificates_bound_what_is_returned_at_every_time(name, method):
    """Issue 30: the certificates of smooth() and hks() underflowed at large t (1e-46 .. 1e-219, then
    0) while the returned values keep their rounding (1e-14 .. 1e-12: the n-term sums, the computed
    eigenvectors; and a constant's eigenvalue of 8e-14 made the mean drift by 1e-11 at t = 500).
    Now the bound holds against the complete dense kernel at every time, never drops below the
    rounding floor ~ n u, and is within 1e6 of it where the truncation has decayed."""
    V, F, B, lam, X = _exact(name)
    spec = o3dheat.eigensolve((V, F), k=30, method=method)
    floor = len(V) * np.finfo(np.float64).eps / 2
    rng = np.random.default_rng(2)
    f = np.column_stack([V[:, 0] + 2.0, rng.standard_normal(len(V))])  # a smooth field with a mean, noise
    t = np.array([0.0, 0.3, 1.0, 10.0, 100.0, 1e3, 1e6]) / lam[1]
    late = t * lam[1] >= 100.0
    for normalize, transfer in ((None, None), ("lambda2", [0.0, 1.0, 0.1])):
        K = HeatKernel(spec, normalize=normalize, transfer=transfer)
        unit = 1.0 / o3dheat.spectral.variants.first_nonzero(spec.eigenvalues) if normalize else 1.0
        rates = np.polynomial.polynomial.polyval(lam * unit, transfer) if transfer else lam
        D = np.exp(-0.5 * np.multiply.outer(rates, t))  # (n, T)
        exact = np.einsum("ik,kt,kc->ict", X, D, X.T @ (B @ f))
        got, bound = K.smooth(f, t, return_bound=True)
        E = got - exact
        err = np.sqrt(np.einsum("ict,ij,jct->ct", E, B, E)) / np.sqrt(np.einsum("ic,ij,jc->c", f, B, f))[:, None]
        assert np.all(err <= bound), (normalize, (err / bound).max())
        assert np.all(bound >= floor) and np.all(bound[:, late] <= 1e6 * floor), (bound.min(), bound[:, late].max())
        for form in o3dheat.spectral.variants.HKS_FORMS:
            h, hb = K.hks(t, form=form, return_bound=True)
            P = X * X if form == "density" else X * (B @ X)
            ref = P @ D
            assert np.all(np.abs(h - ref) <= hb), (form, (np.abs(h - ref) / hb).max())
            assert np.all(hb >= 0.5 * floor * np.abs(ref)), form
            assert np.all(hb[:, late] <= 1e6 * floor * np.abs(ref[:, late])), form
