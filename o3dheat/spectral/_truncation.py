"""The certificates of :class:`o3dheat.HeatKernel <o3dheat.spectral.kernel.HeatKernel>`: how far what it returns is from the full kernel.

Entry points: :func:`truncation_bound` and :func:`suggest_k` (methods of
:class:`~o3dheat.spectral.kernel.HeatKernel`, defined here and bound there), :func:`hks_bound` (the bound of
:meth:`~o3dheat.spectral.kernel.HeatKernel.hks`), :func:`top_rate`, :func:`null_eigenvalues`,
:func:`accuracy` (what the certificates need of the computed eigenpairs, once per kernel).

Notes
-----
A certificate bounds the difference between what is *returned* and the exact quantity, the full
kernel ``E = exp(−(t/2) φ(A))``, ``A = W⁻¹L``, applied to the field: not only the truncation (the
eigenpairs above ``λ_k``), which decays like ``exp(−φ(λ_k) t/2)`` and underflows at large t, but
what stays there: the rounding of the sums and the accuracy of the computed eigenpairs
``(λ̂_b, x̂_b)``. With ``τ = t/2``, ``ψ = φ − φ(0)`` (``φ`` increasing: a polynomial with
coefficients >= 0, or none), ``Π`` the W-orthogonal projection on the null space of L (the
constants of each connected part, known exactly), ``c = X̂ᵀ W f`` and ``r = f − X̂ c``,

    E f − X̂ D c = Σ_b c_b (E x̂_b − e^{−τ φ̂_b} x̂_b) + E r,

and each term is bounded by computable quantities (all in the W-norm):

* a null eigenpair (``φ̂_b = φ(0)`` exactly, see :func:`null_eigenvalues`):
  ``‖E x̂_b − e^{−τφ(0)} x̂_b‖ <= e^{−τφ(0)} ‖(I − Π) x̂_b‖``;
* another: ``<= e^{−τφ(0)} (‖Π x̂_b‖ + Q_b(τ) ‖(A − λ̂_b)(I − Π) x̂_b‖)``, since
  ``|e^{−τψ(λ)} − e^{−τψ(λ̂_b)}| <= Q_b(τ) |λ − λ̂_b|`` for λ >= ``λ_-``, a lower bound of the
  smallest non-zero eigenvalue (the first computed one less its residual). ``Q_b`` (:func:`_divided`)
  is built from the slope bound ``sup_{ξ >= x} |d/dξ e^{−τψ(ξ)}| <= τ c₁ e^{−τ c₁ x}`` for ``ψ = c₁ λ``,
  else ``(d/x) h(τ ψ(x))`` (``λ ψ' <= d ψ`` for a polynomial of degree d with coefficients >= 0,
  ``h(y) = y e^{−y}`` for ``y >= 1``, ``1/e`` below); the residual
  ``‖(L − λ̂_b W) x̂_b‖_{W⁻¹} + λ̂_b ‖Π x̂_b‖`` is computed (with its rounding, ``γ_{m+3}(|L| +
  λ̂_b|W|)|x̂_b|`` per entry), ``W⁻¹ ⪯ diag(w)`` (:attr:`~o3dheat.Spectrum.inverse_mass_bound`;
  ``1/min_i(2W_ii − Σ_j|W_ij|)`` for a diagonally dominant mass built elsewhere). Either is at most
  ``2 e^{−τφ(0)} ‖x̂_b‖``. For the residual part the first-order estimate of Rayleigh–Ritz
  perturbation theory is used where smaller (:func:`_first_order`: it damps the residual of a
  high eigenpair with its own eigenvalue, where ``Q_b`` must assume the worst);
* ``E r``: ``e^{−τφ(0)} (‖Π r‖ + e^{−τψ_k} ‖r‖ + ‖r‖ Σ_b e^{−τψ(λ̂_b − ρ_b)} ρ_b/(λ̂_k − λ̂_b))``: the
  truncation, ``ψ_k = ψ(λ̂_k − ρ_k)`` (the eigenpairs not computed are taken to lie above the
  computed ones, as the eigensolver finds the smallest), plus the first-order part of ``r`` on
  the exact eigenvectors below the top cluster (angle ``<= ρ_b / gap``, ``ρ_b`` the residual);
* rounding: ``γ_n = n u / (1 − n u)``, ``u`` the unit roundoff, ``m`` the most entries of a row of
  W, ``S = diag(Σ_j |W_ij|)`` (``|W| ⪯ S``, so ``|y|ᵀ|W||z| <= ‖y‖_S ‖z‖_S``): the coefficients
  ``fl(X̂ᵀ fl(W f))`` are off by ``γ_{n+m} ‖x̂_b‖_S ‖f‖_S`` at most; the factors ``fl(exp(fl(−τ
  φ̂_b)))`` by ``(2 + 2τ|φ̂_b|) u D_b``, their product with ``ĉ_b`` by ``u``; the final sum over k
  eigenpairs by ``γ_k |X̂||z|`` entrywise, ``<= γ_k Σ_b |z_b| ‖x̂_b‖_S`` in W-norm. Summed:
  ``Σ_b D_b (γ_{n+m} ‖x̂_b‖_W ‖x̂_b‖_S ‖f‖_S + ((3 + 2τ|φ̂_b|) u ‖x̂_b‖_W + γ_k ‖x̂_b‖_S) |ĉ_b|)``, taken
  three times (the computed ``r`` and ``Π r`` of the other terms carry the same rounding, and
  ``D_b >= e^{−τφ̂_k}``). First order in u (products of rounding errors are dropped).

The constants in these terms are where the bound stops decaying: of the order of
``(n + m) u`` (the n-term sums of the coefficients) and of the eigenpairs' residuals, never the
underflowing ``exp(−φ(λ_k) t/2)``. The heat kernel signatures are the same quantities for the
fields ``W⁻¹ e_i`` and ``e_i`` (:func:`hks_bound`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from o3dheat import checks
from o3dheat.errors import MeshError, SolverError
from o3dheat.typing import FieldLike, TimesLike

from ._flow_setup import null_parts
from ._solvers import weyl_gap
from .spectrum import inverse_mass_bound
from .variants import first_nonzero, transfer_function

U = np.finfo(np.float64).eps / 2  # the unit roundoff


def _gamma(n):
    """Higham's ``γ_n = n u / (1 − n u)``: the relative error of an n-term sum."""
    return n * U / (1.0 - n * U)


def null_eigenvalues(eigenvalues, mass) -> np.ndarray:
    """Which eigenvalues are those of the null space (the constants of each part): 0 to rounding,
    below 1e-8 of Weyl's gap ``4π / 1ᵀ W 1`` (as :func:`o3dheat.spectral.spectrum.all_zero`). Their
    rate is ``φ(0)`` exactly: an eigensolver gives them as about ``1e-16 λ_max``, which times a
    large t would let the constants decay (``exp(−8e-14 t/2)``: 1e-11 off at t = 250).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from o3dheat.spectral._truncation import null_eigenvalues
    >>> null_eigenvalues(np.array([8e-14, 2.0, 6.0]), sp.identity(4)).tolist()
    [True, False, False]
    """
    lam = np.asarray(eigenvalues, dtype=np.float64)
    return lam <= 1e-8 * weyl_gap(mass)


def top_rate(kernel):
    """The largest rate φ(λ_k) of a :class:`~o3dheat.spectral.kernel.HeatKernel`, a lower bound of every dropped
    rate when φ increases (refused for a transfer function not known to increase)."""
    phi = transfer_function(kernel.transfer)
    if phi is not None and (phi.coefficients is None or np.any(phi.coefficients < 0)):
        raise MeshError("the truncation bound needs a transfer function that increases: polynomial "
                        "coefficients >= 0 (a callable or a negative coefficient cannot be certified)")
    return float(np.max(kernel.rates))


@dataclass
class Accuracy:
    """What the certificates need of a kernel's computed eigenpairs (:func:`accuracy`).

    ``null`` (k,): the null eigenpairs; ``labels`` (n,), ``masses`` (p,): the parts whose
    constants are in L's null space (-1: none); ``mu`` (p, k): ``Π x̂_b = Σ_p mu[p, b] 1_p``;
    ``wnorm``, ``snorm`` (k,): ``‖x̂_b‖_W``, ``‖x̂_b‖_S``; ``dev`` (k,): ``‖(I − Π) x̂_b‖_W`` (null) or
    ``‖Π x̂_b‖_W`` (others), with their rounding; ``res`` (k,): the residuals (rate units, 0 for
    null pairs); ``lam`` (k,): the eigenvalues in rate units (before φ); ``lam_lo``: ``λ_-`` (0
    when none is known); ``inspan`` (k, k): ``|X̂ᵀ (L x̂_b − λ̂_b W x̂_b)|`` with its rounding (rate
    units: the residuals' part in the computed span, 0 for Rayleigh–Ritz pairs but for rounding);
    ``srow`` (n,): S; ``m``: the most entries of a row of W; ``eta``: ``γ_{n+m}``.
    """

    null: np.ndarray
    labels: np.ndarray
    masses: np.ndarray
    mu: np.ndarray
    wnorm: np.ndarray
    snorm: np.ndarray
    dev: np.ndarray
    res: np.ndarray
    lam: np.ndarray
    lam_lo: float
    inspan: np.ndarray
    srow: np.ndarray
    m: int
    eta: float


def _inverse_mass(spectrum, srow):
    """``w`` with ``W⁻¹ ⪯ diag(w)`` (inf on rows of zero mass), or None."""
    w = spectrum.inverse_mass_bound
    if w is None:
        w = inverse_mass_bound(spectrum.mass, spectrum.mass_kind)
    if w is not None:
        return np.asarray(w, dtype=np.float64)
    d = spectrum.mass.diagonal()
    low = 2.0 * d - srow
    on = d > 0
    if not on.any() or low[on].min() <= 0:
        return None
    return np.where(on, 1.0 / low[on].min(), np.inf)


def accuracy(kernel) -> Accuracy:
    """The :class:`Accuracy` of a kernel's eigenpairs (``O(nnz k)``: a few products of the operators
    with the eigenvectors; cached by the kernel).

    Raises
    ------
    MeshError
        A mass built elsewhere that is neither diagonal nor diagonally dominant (no bound of its
        inverse, so none of the eigenpairs' accuracy).
    """
    spec = kernel.spectrum
    X, W = spec.eigenvectors, sp.csr_matrix(spec.mass)
    L = sp.csr_matrix(spec.stiffness)
    WX = kernel._WX
    n, k = X.shape
    absW = abs(W)
    srow = np.asarray(absW.sum(axis=1)).ravel()
    m = int(np.max(np.diff(W.indptr))) if W.nnz else 1
    eta = _gamma(n + m)
    w = _inverse_mass(spec, srow)
    if w is None:
        raise MeshError("no certificate for this spectrum: its mass is neither diagonal nor diagonally "
                        "dominant (no bound of its inverse, so none of the eigenpairs' accuracy)")
    wnorm = np.sqrt(np.maximum(np.einsum("ij,ij->j", X, WX), 0.0))
    snorm = np.sqrt(np.einsum("i,ij,ij->j", srow, X, X))
    # the exact null space: the constants of the parts of L's graph where L 1 = 0, of positive mass
    count, labels = null_parts(L)
    d = np.asarray(W.sum(axis=1)).ravel()
    on = labels >= 0
    masses = np.bincount(labels[on], weights=d[on], minlength=count)
    keep = masses > 0
    number = np.full(count, -1)
    number[keep] = np.arange(int(keep.sum()))
    labels = np.where(on, number[np.maximum(labels, 0)], -1)
    masses = masses[keep]
    on = labels >= 0
    P = sp.csr_matrix((np.ones(int(on.sum())), (labels[on], np.flatnonzero(on))), shape=(len(masses), n))
    mu = (P @ WX) / masses[:, None] if len(masses) else np.zeros((0, k))
    null = null_eigenvalues(spec.eigenvalues, spec.mass)
    dev = np.sqrt(np.maximum(masses @ (mu * mu), 0.0)) if len(masses) else np.zeros(k)  # ‖Π x̂_b‖_W
    if null.any():
        Y = X[:, null] - np.where(on[:, None], mu[:, null][np.maximum(labels, 0)], 0.0) if len(masses) else X[:, null]
        dev[null] = np.sqrt(np.maximum(np.einsum("ij,ij->j", Y, W @ Y), 0.0))  # ‖(I − Π) x̂_b‖_W
    dev = dev + 2.0 * eta * snorm
    lam_raw = np.where(null, 0.0, np.asarray(spec.eigenvalues, dtype=np.float64))
    absL, wfin = abs(L), np.where(np.isfinite(w), w, 0.0)  # rows of infinite w: no mass, no residual
    rw, inspan = np.empty(k), np.empty((k, k))
    for a in range(0, k, 16):  # blocks of columns: no (n, k) temporary
        z = slice(a, a + 16)
        Xz, lz = X[:, z], lam_raw[z]
        R = L @ Xz - WX[:, z] * lz
        err = _gamma(m + 3) * (absL @ np.abs(Xz) + (absW @ np.abs(Xz)) * lz)  # the rounding of R
        inspan[:, z] = np.abs(X.T @ R) + np.abs(X).T @ (err + _gamma(n) * np.abs(R))
        R = np.abs(R) + err
        rw[z] = np.sqrt(wfin @ (R * R))
    unit = 1.0 / first_nonzero(spec.eigenvalues) if kernel.normalize == "lambda2" else 1.0
    res = np.where(null, 0.0, unit * (rw + lam_raw * dev))
    lam = lam_raw * unit
    live = np.flatnonzero(~null)
    lam_lo = max(float(lam[live[0]] - res[live[0]]), 0.0) if len(live) else 0.0
    inspan = np.where(null[:, None] | null[None, :], 0.0, unit * inspan)
    return Accuracy(null, labels, masses, mu, wnorm, snorm, dev, res, lam, lam_lo, inspan, srow, m, eta)


def _psi(phi):
    """The polynomial coefficients of φ (those of λ without a transfer function), trailing zeros cut."""
    return np.array([0.0, 1.0]) if phi is None else np.trim_zeros(np.asarray(phi.coefficients, float), "b")


def _slope(coef, x, taus):
    """``sup_{ξ >= x} |d/dξ e^{−τψ(ξ)}|`` (len(x), T) for ``ψ = Σ_{j>=1} coef_j ξ^j``, coefficients >= 0:
    ``τ c₁ e^{−τ c₁ x}`` for degree 1, else ``(d/x) h(τ ψ(x))`` (inf at x = 0)."""
    x = np.asarray(x, dtype=np.float64)[:, None]
    if len(coef) <= 1:  # a constant φ: ψ = 0
        return np.zeros((len(x), len(taus)))
    if len(coef) == 2:
        return taus * coef[1] * np.exp(-taus * coef[1] * x)
    y = taus * np.polynomial.polynomial.polyval(x, np.r_[0.0, coef[1:]])
    with np.errstate(divide="ignore"):
        return (len(coef) - 1) / x * np.where(y >= 1.0, y * np.exp(-np.minimum(y, 700.0)), np.exp(-1.0))


def _divided(phi, lam, lam_lo, taus):
    """``Q_b(τ) >= |e^{−τψ(λ)} − e^{−τψ(λ̂_b)}| / |λ − λ̂_b|`` for every λ >= λ_- (k, T): the least of
    ``M(τ)`` (the slope's bound from ``λ_-``) and, for ``λ̂_b > λ_-`` with ``δ = (λ̂_b − λ_-)/2``, the
    larger of the slope's bound from ``λ̂_b − δ`` (λ within δ) and ``e^{−τψ(λ_-)}/δ`` (farther: the
    difference is at most ``e^{−τψ(λ_-)}``, ψ increasing). So the residual of a high eigenpair is
    damped with its own eigenvalue, and only ``1/gap`` of it with the smallest one."""
    coef = _psi(phi)
    M = _slope(coef, [lam_lo], taus)
    delta = 0.5 * (lam - lam_lo)
    psi_lo = float(np.polynomial.polynomial.polyval(lam_lo, np.r_[0.0, coef[1:]])) if len(coef) > 1 else 0.0
    with np.errstate(divide="ignore"):
        far = np.where(delta[:, None] > 0, np.exp(-taus * psi_lo) / np.where(delta > 0, delta, 1.0)[:, None], np.inf)
    return np.minimum(M, np.maximum(_slope(coef, lam - delta, taus), far))


def _first_order(acc, coef, decays, taus):
    """The first-order estimate of ``‖E x̂_b − e^{−τφ̂_b} x̂_b‖ e^{τφ(0)}`` (k, T) for Rayleigh–Ritz pairs:
    the residual's part outside the computed span moves ``x̂_b`` only towards the eigenvalues not
    computed, above ``λ̂_k − ρ_k``, so by ``ρ_b / (λ̂_k − ρ_k − λ̂_b)`` at most, each of them decaying
    faster than ``x̂_b`` (``e^{−τψ̂_b}``); its part in the span (``inspan``) mixes the computed pairs,
    by the divided differences of ``e^{−τψ}`` between their eigenvalues (the slope bound within a
    cluster). Infinite for the pairs of the top cluster (no gap to the rest)."""
    lam, res = acc.lam, acc.res
    top = lam[-1] - res[-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where((lam < top)[:, None], decays * (res / np.where(lam < top, top - lam, 1.0))[:, None], np.inf)
    if not np.any(acc.inspan):
        return out
    close = np.abs(np.subtract.outer(lam, lam)) <= 1e-9 * max(float(np.abs(lam).max()), 1e-300)
    for i, tau in enumerate(taus):
        g = decays[:, i]
        slope = _slope(coef, np.minimum.outer(lam, lam).ravel(), np.array([tau]))
        with np.errstate(divide="ignore", invalid="ignore"):
            dd = np.abs(np.subtract.outer(g, g)) / np.abs(np.subtract.outer(lam, lam))
        dd = np.where(close, slope.reshape(dd.shape), dd)
        out[:, i] += np.einsum("jb,jb->b", acc.inspan, dd)
    return out


@dataclass
class _Terms:
    """The time-dependent factors of the certificates at the times t (see :func:`_terms`)."""

    acc: Accuracy
    taus: np.ndarray  # (T,) τ = t/2
    D: np.ndarray  # (k, T) the filter factors e^{−τφ̂_b}
    decays: np.ndarray  # (k, T) e^{−τψ̂_b}
    pairs: np.ndarray  # (k, T) e_b(τ): the eigenpairs' terms of the module notes
    residual: np.ndarray  # (k, T) their residual parts only, e^{−τφ(0)} min(M(τ) ρ_b, 2‖x̂_b‖) (0: null)
    decay_k: np.ndarray  # (T,) the truncation's e^{−τφ(0)} e^{−τψ_k}
    sub: np.ndarray  # (2, T) e^{−τφ(0)} Σ_b e^{−τψ(λ̂_b − ρ_b)} (ρ_b/gap_b)^j, j = 1, 2
    null_factor: np.ndarray  # (T,) e^{−τφ(0)}


def _terms(kernel, t):
    """The :class:`_Terms` of a kernel at the times t."""
    top_rate(kernel)  # refuses a transfer function not known to increase
    acc = kernel._accuracy
    phi = transfer_function(kernel.transfer)
    taus = 0.5 * np.atleast_1d(checks.times(t)).astype(np.float64)
    rate = (lambda x: x) if phi is None else phi
    phi0 = float(rate(np.zeros(1))[0])
    psi = kernel.rates - phi0  # (k,)
    live = ~acc.null
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        null_factor = np.exp(-taus * phi0)
        D = np.exp(-np.multiply.outer(kernel.rates, taus))
        decays = np.exp(-np.multiply.outer(psi, taus))
        residual = np.minimum(acc.res[:, None] * _divided(phi, acc.lam, acc.lam_lo, taus), 2.0 * acc.wnorm[:, None])
        residual = np.where(np.isnan(residual), 2.0 * acc.wnorm[:, None], residual)  # 0 x inf: no bound
        residual = np.minimum(residual, _first_order(acc, _psi(phi), decays, taus))
        residual[~live] = 0.0
        pairs = np.multiply.outer(acc.dev, np.ones_like(taus))
        pairs[live] = np.minimum(acc.dev[live, None] * (1.0 - decays[live]) + residual[live], 2.0 * acc.wnorm[live, None])
        lam, res = acc.lam, acc.res
        top = len(lam) - 1
        psi_k = float(rate(np.array([max(lam[top] - res[top], 0.0)]))[0]) - phi0
        decay_k = null_factor * np.exp(-taus * psi_k)
        gap = lam[top] - lam
        below = live & (gap > res + res[top])
        sub = np.zeros((2, len(taus)))
        if below.any():
            psi_low = rate(np.maximum(lam[below] - res[below], 0.0)) - phi0
            ratio = (res[below] / gap[below])[None, :] ** np.array([[1.0], [2.0]])  # (2, b)
            sub = null_factor * (ratio @ np.exp(-np.multiply.outer(psi_low, taus)))
    return _Terms(acc, taus, D, decays, pairs * null_factor, residual * null_factor, decay_k, sub, null_factor)


def hks_bound(kernel, t, form, WX):
    """The bound of ``kernel.hks(t, form, return_bound=True)`` per vertex and time (``WX``: the
    mass times the eigenvectors).

    ``K_t(i, i) = ⟨δ_i, E e_i⟩_W`` ("paper") and ``⟨δ_i, E δ_i⟩_W`` ("density"), ``δ_i = W⁻¹ e_i``,
    split by the exact null space: ``E = e^{−τφ(0)} (Π + G)``, ``G = e^{−τψ(A)} (I − Π)``. The null
    part is compared vertex by vertex (``⟨δ_i, Π δ_i⟩ = 1/m_p``, ``⟨δ_i, Π e_i⟩ = (W 1)_i/m_p``, m_p
    the mass of the vertex's part, against the null eigenvectors' share of the sum). The rest, with
    ``y_b = (I − Π) x̂_b``, ``c_b = y_b(i)``, ``c'_b = (W y_b)(i)`` and ``δ_i⁺ = Y c + r``, ``e_i⁺ = Y c' +
    r'``: ``|⟨Y c, G Y c'⟩ − Σ_b e^{−τψ̂_b} c_b c'_b| <= ‖Y c‖ Σ_b |c'_b| M(τ) ρ_b``, the cross terms
    ``<= ‖r‖ Σ_b |c'_b| M ρ_b + ‖r'‖ Σ_b |c_b| M ρ_b``, ``|⟨r, G r'⟩| <= e^{−τψ_k} ‖r‖ ‖r'‖`` (the
    truncation, with the tails ``‖r‖² <= w_i − Σ_b x̂_b(i)²`` and ``‖r'‖² <= W_ii − Σ_b (W x̂_b)(i)²``)
    plus its second-order subspace part, and ``Σ_b e^{−τψ̂_b} |x̂_b(i) (W x̂_b)(i) − c_b c'_b|`` for the
    null-space components of the computed eigenvectors; ``‖Y c‖ <= ‖δ_i‖ <= sqrt(w_i)``. Rounding:
    ``(γ_{k+1} + (2 + 2τ|φ̂_b|) u)`` relative per term of the k-term sum, and ``γ_m |W||x̂_b|`` in
    ``W X̂`` for the paper form. The near-cancellations (the tails, the null part, whose ``m_p`` is
    a sum of n terms: ``γ_{n+m}``) are counted with their rounding. First order in u and in the
    residuals.
    """
    X = kernel.spectrum.eigenvectors
    w = kernel.spectrum.inverse_mass_bound
    if w is None:  # a Spectrum made by hand: bounded from its mass where that is possible
        w = inverse_mass_bound(kernel.spectrum.mass, kernel.spectrum.mass_kind)
    if w is None:
        raise MeshError("no truncation bound for this spectrum: its mass is not diagonal nor the consistent "
                        "FEM mass (the diagonal of its inverse is not bounded)")
    T = _terms(kernel, t)
    acc = T.acc
    n, k = X.shape
    live, null = ~acc.null, acc.null
    gk, gp = _gamma(k + 1), _gamma(int(null.sum()) + 2)
    factor_err = (2.0 + 2.0 * np.abs(np.multiply.outer(kernel.rates, T.taus))) * U  # (k, T)
    Dl, R, DR = T.decays[live], T.residual[live], T.D * (gk + factor_err)
    mass = sp.csr_matrix(kernel.spectrum.mass)
    d, diag = np.asarray(mass.sum(axis=1)).ravel(), mass.diagonal()
    absW = abs(mass) if form == "paper" else None

    def rows(z):  # the bound on the rows z (blocks of rows: no (n, k) temporary)
        Xz, WXz = X[z], WX[z]
        unref = acc.srow[z] == 0  # vertices outside the mesh: 0 in the kernel and in its truncation
        wf = np.where(unref, 0.0, w[z])
        on = acc.labels[z] >= 0
        part = np.maximum(acc.labels[z], 0)
        MU = np.where(on[:, None], acc.mu[part], 0.0) if len(acc.masses) else np.zeros_like(Xz)  # μ_{p(i), b}
        inv_m = np.where(on, 1.0 / acc.masses[part], 0.0) if len(acc.masses) else np.zeros(len(Xz))
        x2 = np.einsum("ij,ij->i", Xz, Xz)
        tail_x = np.maximum(wf - x2, 0.0) + gk * (wf + x2)
        C = (Xz - MU)[:, live]  # c_b = y_b(i)
        if form == "density":
            share = np.einsum("ij,ij->i", Xz[:, null], Xz[:, null])
            null_part = np.abs(inv_m - share) + gp * (inv_m + share) + acc.eta * inv_m  # m_p: a sum of n terms
            moved = (2.0 * np.abs(Xz * MU) + MU * MU)[:, live] @ Dl
            accuracy = (np.sqrt(wf) + 2.0 * np.sqrt(tail_x))[:, None] * (np.abs(C) @ R)
            tail = tail_x
            rounding = (Xz * Xz) @ DR
        else:
            dz = d[z]
            absX, absWX = np.abs(Xz), np.abs(WXz)
            share = np.einsum("ij,ij->i", Xz[:, null], WXz[:, null])
            null_part = (np.abs(inv_m * dz - share) + acc.eta * inv_m * dz
                         + gp * (inv_m * dz + np.einsum("ij,ij->i", absX[:, null], absWX[:, null])))
            Cw = (WXz - MU * dz[:, None])[:, live]  # c'_b = (W y_b)(i)
            moved = np.abs(Xz * WXz - (Xz - MU) * (WXz - MU * dz[:, None]))[:, live] @ Dl
            wx2 = np.einsum("ij,ij->i", WXz, WXz)
            tail_w = np.maximum(diag[z] - wx2, 0.0) + gk * (diag[z] + wx2)
            accuracy = ((np.sqrt(wf) + np.sqrt(tail_x))[:, None] * (np.abs(Cw) @ R)
                        + np.sqrt(tail_w)[:, None] * (np.abs(C) @ R))
            tail = np.sqrt(tail_x * tail_w)
            Wabs = absW[z] @ np.abs(X)  # fl(W X̂) is off by γ_m |W||X̂|
            rounding = (absX * absWX) @ DR + _gamma(acc.m) * ((absX * Wabs) @ T.D)
        with np.errstate(invalid="ignore", over="ignore"):
            b = (np.multiply.outer(null_part, T.null_factor) + moved * T.null_factor + accuracy
                 + np.multiply.outer(tail, T.decay_k + T.sub[1]) + 2.0 * rounding)
        b = np.where(np.isnan(b), 0.0, b)
        b[unref] = 0.0
        return b

    step = max(2**20 // max(k, 1), 1)
    bound = np.concatenate([rows(slice(a, a + step)) for a in range(0, n, step)]) if n else np.zeros((0, len(T.taus)))
    return bound if np.ndim(t) else bound[:, 0]


def truncation_bound(self, f: FieldLike, t: TimesLike) -> float | np.ndarray:  # noqa: D417 - HeatKernel's method
    """Upper bound of how far :meth:`smooth` is from the full kernel at time t, relative to ``‖f‖_W``.

    Three parts (the module notes of :mod:`o3dheat.spectral._truncation` derive them). The
    truncation: with ``P`` the W-orthogonal projection on the k eigenvectors (``W`` the spectrum's
    mass), the full-spectrum map satisfies ``‖Φ_t f − Φ_t^{(k)} f‖_W <= exp(−φ(λ_k) t / 2) ‖f − P
    f‖_W`` (every dropped eigenvalue is >= λ_k and φ increasing). The accuracy of the computed
    eigenpairs (their residuals, their distance to the exact null space) and the rounding of the
    sums (about ``(n + m) u`` times the field, ``m`` the entries of a row of W): what is left when
    the truncation has decayed, so the bound never underflows below the rounding of what is
    returned. Refused for a transfer function not known to increase (only polynomials with
    non-negative coefficients are).

    Parameters
    ----------
    f : (n,) or (n, c) array_like
        The field(s), one value per vertex.
    t : float or (T,) array_like
        Time(s) (paper convention, >= 0): one bound per time.

    Returns
    -------
    float, (T,), (c,) or (c, T) ndarray

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> K = o3dheat.heat_kernel(mesh, k=20)
    >>> b = K.truncation_bound(mesh.vertex.positions.numpy()[:, 0] ** 2, [0.0, 0.1, 1e3])
    >>> bool(b[1] < b[0] < 0.01)              # x² is nearly in the span of 20 eigenvectors
    True
    >>> bool(1e-14 < b[2] < 1e-10)            # late: the rounding of the sums, not exp(-10^4)
    True
    """
    f = self._field(f)
    f, _ = self._unit(f)  # relative: the scale of f does not matter (and its norms do not overflow)
    F = f[:, None] if f.ndim == 1 else f
    B = self.spectrum.mass
    X = self.spectrum.eigenvectors
    WF = B @ F
    C = X.T @ WF  # (k, c)
    R = F - X @ C
    nr = np.sqrt(np.maximum(np.einsum("ij,ij->j", R, B @ R), 0.0))
    nf = np.sqrt(np.maximum(np.einsum("ij,ij->j", F, WF), 0.0))
    T = _terms(self, t)
    acc, D = T.acc, T.D
    ns = np.sqrt(acc.srow @ (F * F))  # ‖f‖_S
    on = acc.labels >= 0
    sums = np.zeros((len(acc.masses), F.shape[1]))
    np.add.at(sums, acc.labels[on], (B @ R)[on])
    n_pr = np.sqrt(acc.masses @ (sums / acc.masses[:, None]) ** 2) if len(acc.masses) else np.zeros(F.shape[1])
    factor_err = (3.0 + 2.0 * np.abs(np.multiply.outer(self.rates, T.taus))) * U  # (k, T)
    absC = np.abs(C)  # (k, c)
    rounding = (acc.eta * (D * (acc.wnorm * acc.snorm)[:, None]).sum(axis=0)[None, :] * ns[:, None]
                + absC.T @ (D * (factor_err * acc.wnorm[:, None] + _gamma(len(acc.wnorm)) * acc.snorm[:, None])))
    bound = (np.multiply.outer(nr, T.decay_k + T.sub[0]) + np.multiply.outer(n_pr, T.null_factor) + absC.T @ T.pairs
             + 3.0 * rounding)  # (c, T)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(nf[:, None] > 0, bound / np.where(nf > 0, nf, 1.0)[:, None], 0.0)
    if f.ndim == 1:
        rel = rel[0]
        return rel if np.ndim(t) else float(rel[0])
    return rel if np.ndim(t) else rel[:, 0]


def suggest_k(self, t: float, tol: float = 1e-3) -> int:  # noqa: D417 - HeatKernel's method
    """Estimate how many eigenpairs make the truncation factor ``exp(−φ(λ_k) t/2)`` <= tol.

    Uses Weyl's law (``λ_j`` grows linearly with ``j`` on a surface), with the slope fitted to
    this spectrum's upper half of eigenvalues. An estimate, not a guarantee.

    Parameters
    ----------
    t : float
        Time (> 0).
    tol : float
        Target factor, in (0, 1).

    Returns
    -------
    int

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> K = o3dheat.heat_kernel(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16), k=20)
    >>> K.suggest_k(0.1) < K.suggest_k(0.01)  # small times need more eigenpairs
    True
    """
    t = float(checks.times(t))
    if t <= 0 or not (0 < tol < 1):
        raise MeshError("suggest_k needs t > 0 and 0 < tol < 1")
    need = 2 * np.log(1 / tol) / t  # the rate λ_k must reach
    k = len(self.rates)
    j = np.arange(1, k + 1)
    half = slice(k // 2, k)
    slope = float(np.sum(self.rates[half] * j[half]) / np.sum(j[half] ** 2))
    if slope <= 0:
        raise SolverError("cannot extrapolate from an all-zero spectrum")
    return int(np.ceil(need / slope))
