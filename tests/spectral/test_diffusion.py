"""o3dheat.spectral.diffusion: eq. (8) and backward Euler converge to the spectral solution as dt -> 0."""

import numpy as np
import pytest
from conftest import icosphere, irregular

import o3dheat


@pytest.fixture(scope="module")
def small():
    V, F = icosphere(2)
    V = V * [1.2, 1.0, 0.8] + 0.03 * np.random.default_rng(0).standard_normal(V.shape)
    return V, F


@pytest.mark.parametrize("scheme", ["explicit", "implicit"])
@pytest.mark.parametrize("variant", list(o3dheat.VARIANTS))
def test_converges_to_spectral_solution(small, scheme, variant):
    """Time stepping with each variant's mass converges to that variant's heat kernel."""
    V, F = small
    mass = o3dheat.VARIANTS[variant][0]
    spec = o3dheat.eigensolve((V, F), k=len(V), mass=mass)  # complete spectrum: exact reference
    K = o3dheat.HeatKernel(spec, variant=variant)
    f = np.random.default_rng(1).standard_normal((len(V), 2))  # two fields at once
    T = 1.0 if mass == "identity" else 0.02  # "identity": dimensionless eigenvalues, larger
    exact = K.smooth(f, T)
    errs = []
    for steps in (40, 80, 160):
        g = o3dheat.diffuse((V, F), f, dt=T / steps, steps=steps, scheme=scheme, mass=mass)
        errs.append(np.abs(g - exact).max())
    # first order in dt: halving dt halves the error
    assert 1.7 < errs[0] / errs[1] < 2.3 and 1.7 < errs[1] / errs[2] < 2.3
    assert errs[-1] < 0.02 * np.abs(exact).max()


def test_history_and_single_field(small):
    V, F = small
    f = V[:, 2].copy()
    h = o3dheat.diffuse((V, F), f, dt=1e-3, steps=5, scheme="implicit", return_history=True)
    assert h.shape == (len(V), 6)
    np.testing.assert_array_equal(h[:, 0], f)
    last = o3dheat.diffuse((V, F), f, dt=1e-3, steps=5, scheme="implicit")
    np.testing.assert_allclose(h[:, -1], last)


def test_mass_is_conserved(small):
    V, F = small
    B = o3dheat.mass_matrix((V, F))
    f = np.random.default_rng(3).random(len(V))
    for scheme in ("explicit", "implicit"):
        g = o3dheat.diffuse((V, F), f, dt=1e-4, steps=20, scheme=scheme)
        assert np.ones(len(V)) @ B @ g == pytest.approx(np.ones(len(V)) @ B @ f, rel=1e-10)


def test_explicit_unstable_step_refused(small):
    V, F = small
    with pytest.raises(o3dheat.MeshError, match="unstable"):
        o3dheat.diffuse((V, F), V[:, 0], dt=10.0, steps=3)
    # the implicit scheme takes any step
    g = o3dheat.diffuse((V, F), V[:, 0], dt=10.0, steps=3, scheme="implicit")
    assert np.all(np.isfinite(g))


@pytest.mark.parametrize("kwargs, match", [
    (dict(dt=-1.0, steps=3), "dt"), (dict(dt=np.nan, steps=3), "dt"), (dict(dt=0.1, steps=-1), "steps"),
    (dict(dt=0.1, steps=2, scheme="rk4"), "scheme"),
    (dict(dt=0.1, steps=2, mass="area"), ", ".join(o3dheat.spectral.fem.MASS_KINDS))])
def test_bad_arguments(small, kwargs, match):
    V, F = small
    with pytest.raises(o3dheat.MeshError, match=match):
        o3dheat.diffuse((V, F), V[:, 0], **kwargs)


def test_bad_field(small):
    V, F = small
    with pytest.raises(o3dheat.MeshError, match="shape"):
        o3dheat.diffuse((V, F), np.ones(3), dt=0.1, steps=1)
    f = V[:, 0].copy()
    f[0] = np.inf
    with pytest.raises(o3dheat.MeshError, match="NaN"):
        o3dheat.diffuse((V, F), f, dt=0.1, steps=1)


@pytest.mark.parametrize("alpha", [1e-90, 1e90])
@pytest.mark.parametrize("scheme", ["explicit", "implicit"])
def test_extreme_scales_are_covariant(alpha, scheme):
    import warnings

    V, F = irregular()
    f = V[:, 0]
    ref = o3dheat.diffuse((V, F), f, 1e-5, 5, scheme=scheme)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow on the way
        g = o3dheat.diffuse((alpha * V, F), f, 1e-5 * alpha**2, 5, scheme=scheme)
    np.testing.assert_allclose(g, ref, atol=1e-12)


def reference_limit(V, F, mass="consistent"):
    """4 / λ_max from the complete dense spectrum of L x = λ B x (the paper's e^{-λt/2}: eq. (8)
    multiplies a mode by 1 − λ dt/2, stable for dt <= 4/λ)."""
    import scipy.linalg

    L, B, _ = o3dheat.spectral.fem.operators(V, F, mass)
    return 4.0 / scipy.linalg.eigh(L.toarray(), B.toarray(), eigvals_only=True)[-1], B


@pytest.mark.parametrize("level, mass", [(2, "consistent"), (3, "consistent"), (3, "lumped")])
def test_explicit_step_limit_is_the_one_checked_and_stated(level, mass):
    """Just below 4/λ_max is accepted (and the B-norm never grows over many steps), just above is
    refused, and the message's number is that limit (it said 0.00293 where 4/λ_max was 0.00307:
    the check used a raised estimate of λ_max). Level 2 takes the dense path, level 3 Lanczos."""
    import re

    V, F = icosphere(level)
    V = V * [1.2, 1.0, 0.8]
    limit, B = reference_limit(V, F, mass)
    f = np.random.default_rng(2).standard_normal(len(V))
    h = o3dheat.diffuse((V, F), f, dt=limit * (1 - 1e-6), steps=200, mass=mass, return_history=True)
    norms = np.sqrt(np.einsum("it,it->t", h, B @ h))
    assert np.all(np.diff(norms) <= 1e-12 * norms[0])
    with pytest.raises(o3dheat.MeshError, match="unstable") as e:
        o3dheat.diffuse((V, F), f, dt=limit * (1 + 1e-6), steps=1, mass=mass)
    stated = float(re.search(r"4/λ_max = ([0-9.e+-]+)", str(e.value)).group(1))
    assert stated == pytest.approx(limit, rel=1e-5)


def test_explicit_step_limit_formula():
    from o3dheat.spectral.diffusion import explicit_step_limit

    assert explicit_step_limit(2.0) == 2.0 and explicit_step_limit(0.0) == np.inf


def test_a_text_time_step_is_a_one_line_error():
    """Issue 30: diffuse(dt='0.1') gave a raw TypeError from numpy."""
    V, F = icosphere(1)
    for dt in ("0.1", True, None):
        with pytest.raises(o3dheat.MeshError, match="dt must be a positive number"):
            o3dheat.diffuse((V, F), V[:, 2], dt=dt, steps=2)
