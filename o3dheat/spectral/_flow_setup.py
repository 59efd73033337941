"""The set-up of the exact heat flow: a mesh's operators, the shifts ``γ`` and factors of ``W + γL``.

Entry points: :func:`shift_groups` and :func:`shift` (re-exported by
:mod:`o3dheat.spectral.heatflow`), :class:`Operators` (L, W, the parts, a spectral bound, the
symbolic analysis of the factors' pattern), :class:`Shifted` (a factor of ``W + γL``),
:func:`check_operators` (the operators of :meth:`o3dheat.HeatFlow.from_operators <o3dheat.spectral.heatflow.HeatFlow.from_operators>`),
:func:`unit_columns`, :func:`null_parts`, :func:`geometry_key`, and the steps around the
propagation of :meth:`o3dheat.HeatFlow.apply <o3dheat.spectral.heatflow.HeatFlow.apply>`: :func:`time_order`, :func:`check_converged`,
:func:`finish`; :class:`FlowReport` (re-exported by :mod:`o3dheat.spectral.heatflow`),
:func:`check_transfer` and, for transfer functions, :func:`transfer_plan` (the shift chosen for φ,
and the a priori error bound that certifies the result) with :func:`chebyshev_bound`.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.fft import dct
from scipy.sparse.csgraph import connected_components

from o3dheat import parallel
from o3dheat.errors import ConvergenceError, MeshError, SolverError
from o3dheat.geometry._loops import abs_row_sums, components

from . import fem
from .linalg import analyze, factorize

#: ratio τ_max/τ_min above which the times are split over two shifts (:func:`shift_groups`)
SPLIT_RANGE = 300.0
#: Chebyshev points of :func:`chebyshev_bound`: the first try, and the most (a kernel not resolved by
#: then is too rough to certify)
CHEBYSHEV_POINTS = (256, 2**14)
#: Chebyshev coefficients below this many ulps of ``max(1, max |g|)`` are rounding noise
#: (:func:`chebyshev_bound`): left out of the tail, and added back once as its floor
CHEBYSHEV_NOISE = 32.0




def shift_groups(taus: np.ndarray) -> list[np.ndarray]:
    """The times (sorted, > 0) cut into groups, each served by one shift: a range wider than
    :data:`SPLIT_RANGE` is cut at ``τ_min R^0.45`` (and each part again): measured on 200k-vertex
    scans, four decades take about 97 solves with one shift and 69 cut in two (30 + 39; the
    second factor is made on the other core during the first part's solves, its analysis
    shared), three decades 88 and 61; below about 300 one shift is cheaper.

    Returns
    -------
    list of (k,) int ndarray
        Indices into ``taus``, in order.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral.heatflow import shift_groups
    >>> [g.tolist() for g in shift_groups(np.geomspace(1.0, 1e4, 9))]
    [[0, 1, 2, 3], [4, 5, 6, 7, 8]]
    >>> [g.tolist() for g in shift_groups(np.geomspace(1.0, 10.0, 5))]
    [[0, 1, 2, 3, 4]]
    """
    taus = np.asarray(taus, dtype=np.float64)
    idx = np.arange(len(taus))
    if len(taus) == 0:
        return []
    span = np.log(taus[-1]) - np.log(taus[0]) if len(taus) > 1 else 0.0  # (logs: the ratio may overflow)
    if span <= np.log(SPLIT_RANGE):
        return [idx]
    cut = np.exp(np.log(taus[0]) + 0.45 * span)
    k = int(np.searchsorted(taus, cut))
    if k == 0 or k == len(taus):
        return [idx]
    return shift_groups(taus[:k]) + [g + k for g in shift_groups(taus[k:])]


def shift(tau_min: float, tau_max: float) -> float:
    """The shift ``γ`` of the factor ``W + γL`` for times ``τ`` (rate ``exp(−τλ)``) in
    ``[tau_min, tau_max]``.

    ``γ = τ_min · clip(0.3 (R/10)^0.45, 0.1, 8)``, ``R = τ_max/τ_min``, rounded to a quarter power
    of two (so that nearby ranges share a factor). Fitted to the steps needed for 1e-8 on
    irregular 20k-200k-vertex meshes, noisy and smooth fields: one time, best ``γ ≈ τ/10`` (17
    steps); the paper's ten scales (R = 10) ``γ ≈ 0.3 τ_min`` (22); R = 100, ``0.85 τ_min`` (41);
    four decades, ``6-8 τ_min`` (85); beyond, the largest times are past the decay of every mode
    and ``8 τ_min`` stays best.

    Examples
    --------
    >>> from o3dheat.spectral.heatflow import shift
    >>> round(shift(1.0, 10.0), 3), round(shift(1.0, 1e4), 3)
    (0.297, 6.727)
    """
    span = max(np.log(float(tau_max)) - np.log(float(tau_min)), 0.0)  # log R (R itself may overflow)
    factor = min(max(0.3 * np.exp(0.45 * (span - np.log(10.0))), 0.1), 8.0)
    return float(2.0 ** (np.round(4.0 * (np.log2(float(tau_min)) + np.log2(factor))) / 4.0))


def chebyshev_bound(rate, taus, gamma, lam_lo, lam_hi):
    """A priori bounds of the error of :func:`o3dheat.spectral.krylov.propagate` after each number of
    steps, for the kernel ``exp(−τ rate(λ))`` with the shift ``γ``: ``(bound, resolved)``.

    Why it holds: ``S = (W + γL)⁻¹ W`` is W-self-adjoint; on the part of a field outside the null
    space its eigenvalues ``s = 1/(1 + γλ)`` lie in ``I = [1/(1 + γ λ_hi), 1/(1 + γ λ_lo)]`` when
    ``λ_lo <= λ_2 <= λ_max <= λ_hi``, and so do the Ritz values of every Lanczos step. After m steps
    the approximation ``β₀ V_m g(T_m) e₁`` of ``g(S) f₁`` (``g(s) = exp(−τ rate((1/s − 1)/γ))``) is
    exact for every polynomial p of degree < m, so its W-norm error is at most
    ``β₀ (max_{spec S} |g − p| + max_{spec T_m} |g − p|) <= 2 β₀ max_I |g − p|``; with p the
    Chebyshev series of g on I cut after degree m − 1, ``max_I |g − p| <= Σ_{j >= m} |a_j|``. The
    bound holds for every field, uniformly in the mesh size, whatever the analyticity of the rate
    (a branch point at λ = 0 such as that of √λ only slows the decay of the ``a_j``).

    The ``a_j`` come from g at N Chebyshev points (a DCT), N doubled from 256 until the last eighth
    of them is rounding noise (below :data:`CHEBYSHEV_NOISE` ulps of ``max(1, max |g|)``; such
    coefficients are left out of the sums and the noise level is added once, for all of them).

    Parameters
    ----------
    rate : callable
        ``λ (N,) -> rate (N,)``, the rate less its value at 0 (``φ − φ(0)``).
    taus : (T,) float64 ndarray
        Times τ > 0.
    gamma, lam_lo, lam_hi : float
        The shift, a lower bound of the smallest non-zero eigenvalue of ``W⁻¹L``, an upper bound of
        the largest (``inf``: none known; then ``I`` reaches 0).

    Returns
    -------
    bound : (T, N) float64 ndarray
        ``bound[:, m]``: the bound of the relative error (to ``β₀ = ‖f − f₀‖_W``) after m steps.
    resolved : bool
        False when ``CHEBYSHEV_POINTS[1]`` points did not resolve g (the rate is too rough on the
        spectrum for any number of steps up to that), or g is not finite.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral._flow_setup import chebyshev_bound
    >>> b, ok = chebyshev_bound(np.sqrt, np.array([0.1, 1.0]), 0.01, 1.0, 1e4)
    >>> ok, [int(np.argmax(b[i] <= 1e-8)) for i in range(2)]   # steps for 1e-8 at each time
    (True, [64, 74])
    """
    a = 0.0 if not np.isfinite(lam_hi) else 1.0 / (1.0 + gamma * lam_hi)
    b = 1.0 / (1.0 + gamma * lam_lo)
    taus = np.asarray(taus, dtype=np.float64)
    n = CHEBYSHEV_POINTS[0]
    while True:
        x = np.cos(np.pi * (np.arange(n) + 0.5) / n)  # first kind: never s = 0
        s = 0.5 * (a + b) + 0.5 * (b - a) * x
        r = np.asarray(rate((1.0 / s - 1.0) / gamma), dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):
            g = np.exp(-np.multiply.outer(taus, r))
        if not np.all(np.isfinite(g)):
            return np.full((len(taus), 1), np.inf), False
        c = np.abs(dct(g, type=2, axis=1)) / n
        c[:, 0] /= 2
        noise = CHEBYSHEV_NOISE * np.finfo(np.float64).eps * np.maximum(g.max(axis=1), 1.0)
        c[c <= noise[:, None]] = 0.0
        resolved = not c[:, -(n // 8):].any()
        if resolved or n >= CHEBYSHEV_POINTS[1]:
            tail = np.cumsum(c[:, ::-1], axis=1)[:, ::-1]
            return 2.0 * (tail + noise[:, None]), resolved
        n *= 2


@dataclass
class Plan:
    """The propagation of a transfer function's kernel (:func:`transfer_plan`): the shift, the steps it
    needs for ``tol`` (None: not within ``max_steps``) and ``bound`` (T, m + 1), the a priori error
    bound after each number of steps (:func:`chebyshev_bound`); ``resolved`` False when the kernel
    is too rough to be bounded at all."""

    gamma: float
    steps: int | None
    bound: np.ndarray
    resolved: bool


def transfer_plan(rate, taus, lam_lo, lam_hi, tol, max_steps):
    """The shift for a transfer function's kernel at the times ``taus`` (sorted, > 0) and its certificate.

    The shift of :func:`shift` is fitted to ``exp(−τλ)``; other rates want others (``λ/(1 + λ)``
    converges in 3 to 7 steps with ``γ ≈ 1``, where the τ-fitted shift took 90 to 120; ``√λ``,
    whose branch point at 0 must stay away from the spectrum of ``S``, wants ``γλ_2`` of about
    0.02 at small times). So γ is the one of least steps by the a priori bound of
    :func:`chebyshev_bound`, over powers of two from ``0.01/λ_hi`` to ``100/λ_lo``, then refined
    to quarter powers (the grid of :func:`shift`, so that factors are shared). The bound is also
    the propagation's stopping rule and reported estimate: unlike the difference of iterates, it
    cannot lag behind the error when the convergence is slow.

    Parameters
    ----------
    rate : callable
        ``φ − φ(0)`` on the eigenvalues of ``W⁻¹L`` (vectorised).
    taus : (T,) float64 ndarray
        Times τ > 0, increasing.
    lam_lo, lam_hi : float
        Bounds of the non-zero spectrum of ``W⁻¹L`` (see :func:`chebyshev_bound`).
    tol : float
        The relative error asked.
    max_steps : int
        Most steps.

    Returns
    -------
    Plan

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral._flow_setup import transfer_plan
    >>> p = transfer_plan(lambda lam: lam / (1 + lam), np.array([0.1, 1.0]), 1.0, 1e4, 1e-8, 1000)
    >>> round(p.gamma, 3), p.steps          # γ = 2^(1/4): λ/(1 + λ) is nearly linear in s = 1/(1 + γλ)
    (1.189, 6)
    """
    taus = np.asarray(taus, dtype=np.float64)
    top = lam_hi if np.isfinite(lam_hi) else 1e6 * lam_lo

    def plan(q):
        gamma = float(2.0 ** (q / 4.0))
        bound, resolved = chebyshev_bound(rate, taus, gamma, lam_lo, lam_hi)
        bound = bound[:, :max_steps + 1]
        ok = np.flatnonzero(bound.max(axis=0) <= tol) if resolved else []
        steps = max(int(ok[0]), 1) if len(ok) else None
        return Plan(gamma, steps, bound[:, :steps + 1] if steps else bound, resolved)

    def cost(p):
        return (p.steps if p.steps is not None else np.inf, float(p.bound[:, -1].max()))

    lo, hi = np.floor(np.log2(0.01 / top)), np.ceil(np.log2(100.0 / lam_lo))
    best = min((plan(4 * q) for q in np.arange(lo, max(hi, lo) + 1)), key=cost)
    q0 = int(np.round(4 * np.log2(best.gamma)))
    return min((plan(q) for q in range(q0 - 3, q0 + 4)), key=cost)


def check_plan(plan, tol, max_steps, times, bounded=True):
    """Raise :class:`~o3dheat.errors.ConvergenceError` when a transfer function's :class:`Plan` does
    not reach ``tol`` (its times ``times``, paper convention; ``bounded``: whether the operator's
    largest eigenvalue was bounded, else the plan's interval reached λ = ∞)."""
    if plan.steps is not None:
        return
    span = f"times {times.min():.4g}..{times.max():.4g}"
    if not bounded:
        raise ConvergenceError(f"the heat flow with this transfer function cannot be certified at {span}: no bound "
                               "of the operator's largest eigenvalue is known (the mass is neither diagonal nor "
                               "diagonally dominant), and the kernel is too rough up to λ = ∞; use the spectral "
                               "kernel (o3dheat.HeatKernel)")
    if not plan.resolved:
        raise ConvergenceError(
            f"the heat flow did not reach tol={tol:g}: the transfer function makes the kernel exp(-(t/2) φ(λ)) "
            f"too rough on this mesh's spectrum at {span} to be certified (not resolved by "
            f"{CHEBYSHEV_POINTS[1]} Chebyshev points): use the spectral kernel (o3dheat.HeatKernel)")
    reached = float(plan.bound[:, -1].max())
    floor = 2.0 * CHEBYSHEV_NOISE * np.finfo(np.float64).eps
    if reached <= 1.5 * floor:
        raise ConvergenceError(f"the heat flow did not reach tol={tol:g} at {span}: with a transfer function the "
                               f"result is certified to its rounding floor, about {reached:.1g}: ask tol >= {2 * floor:.0e}")
    raise ConvergenceError(
        f"the heat flow did not reach tol={tol:g} in {max_steps} steps at {span}: with this transfer function "
        f"the a priori bound gets to {reached:.2g}; raise max_steps, or split the times")


class Operators:
    """A mesh's operators for the flow: L, the mass W (None for the identity), the parts (the null
    space of L), a bound of the largest eigenvalue, the symbolic analysis of the factors' pattern
    (started in the background as soon as the pattern is known) and timings. Shared through the
    cache."""

    def __init__(self, L, W, mass, seconds=0.0, analysis=None, parts=None, symmetric=False):
        t0 = time.perf_counter()
        self.L, self.W = _csr(L, symmetric), None if W is None else _csr(W, symmetric)
        self.mass = mass
        self.parts, self.labels = connected_components(self.L, directed=False) if parts is None else parts
        self.d = np.ones(self.L.shape[0]) if self.W is None else np.asarray(self.W.sum(axis=1)).ravel()
        # Gershgorin on D⁻¹L, D the lumped mass (W itself when diagonal): the consistent mass is
        # >= D/4 element by element (each element's mass has eigenvalues |t|/12 x {1, 1, 4})
        rows = abs_row_sums(self.L.indptr, self.L.data)
        diagonal = self.W is None or self.W.nnz == np.count_nonzero(self.W.diagonal())
        if mass == "given" and not diagonal:  # a mass built elsewhere: λ_max(L) / λ_min(W), both by
            # Gershgorin (None when W is not diagonally dominant: no bound known)
            low = float(np.min(2.0 * self.W.diagonal() - abs_row_sums(self.W.indptr, self.W.data)))
            self.lam_max = float(np.max(rows)) / low if low > 0 else None
        else:
            self.lam_max = float(np.max(rows / np.maximum(self.d, 1e-300))) * (4.0 if mass == "consistent" else 1.0)
        self._analysis = analysis
        self.seconds = seconds + time.perf_counter() - t0

    @classmethod
    def of_mesh(cls, prep, mass):
        """The operators of a prepared mesh for a mass kind (the analysis made meanwhile on another core)."""
        t0 = time.perf_counter()
        n = len(prep.V)
        pattern = fem.adjacency_pattern(prep.F, n)
        # the factors' ordering needs the pattern only: analysed on another core meanwhile
        analysis = parallel.background(analyze, sp.csc_matrix((np.ones(len(pattern[1])), pattern[1], pattern[0]),
                                                              shape=(n, n)))
        L, W, _ = fem.operators(prep.V, prep.F, mass, pattern=pattern)
        ops = cls(L, None if mass == "identity" else W, mass, time.perf_counter() - t0, None,
                  components(prep.F, n), symmetric=True)
        # waited for here: no job of this process's threads is left in the cache (a forked child
        # would wait for it forever)
        ops._analysis = analysis.result()
        ops.seconds = time.perf_counter() - t0
        return ops

    def shifted(self, gamma):
        """``W + γL`` (CSC: symmetric), on L's pattern when W's is the same or diagonal."""
        L, W = self.L, self.W
        n = L.shape[0]
        if W is not None and W.nnz == L.nnz and np.array_equal(W.indptr, L.indptr) and np.array_equal(W.indices, L.indices):
            data = W.data + gamma * L.data
        elif W is None or W.nnz == sp.csr_matrix(sp.diags(W.diagonal())).nnz:
            rows = np.repeat(np.arange(n), np.diff(L.indptr))
            diagonal = np.flatnonzero(L.indices == rows)
            if len(diagonal) != n:  # a vertex without a diagonal entry in L: the general sum
                return sp.csc_matrix((sp.identity(n) if W is None else W) + gamma * L)
            data = gamma * L.data
            data[diagonal] += 1.0 if W is None else W.diagonal()
        else:
            return sp.csc_matrix(W + gamma * L)
        return sp.csc_matrix((data, L.indices, L.indptr), shape=(n, n))

    @property
    def analysis(self):
        """The symbolic analysis of the factors' pattern (None: each factorization analyses)."""
        return self._analysis

    @property
    def nbytes(self):
        """Bytes held (for the cache)."""
        total = self.d.nbytes + self.labels.nbytes
        for M in (self.L, self.W):
            if M is not None:
                total += M.data.nbytes + M.indices.nbytes + M.indptr.nbytes
        return total


def unit_columns(F):
    """``(F / p, p)``: each column divided by a power of two ``p`` that brings its largest value
    near 1 when it lies outside [2^-500, 2^500] (exact; ``p = 1`` for ordinary fields), so that
    W-norms neither overflow nor underflow."""
    top = np.max(np.abs(F), axis=0) if F.size else np.zeros(F.shape[1])
    p = np.ones(F.shape[1])
    far = (top > 0) & ((top < 2.0**-500) | (top > 2.0**500))
    p[far] = 2.0 ** np.round(np.log2(top[far]))
    return (F / p if far.any() else F), p


def null_parts(L):
    """``(parts, labels)``: the connected parts of L's graph on which the constants are in L's
    null space (``L 1_p = 0`` to rounding), numbered; -1 for the vertices of the other parts (a
    Dirichlet boundary, a shifted operator: no null vector there)."""
    count, labels = connected_components(L, directed=False)
    rows = np.asarray(abs(L).sum(axis=1)).ravel()
    residual = np.abs(np.bincount(labels, weights=np.asarray(L.sum(axis=1)).ravel(), minlength=count))
    scale = np.bincount(labels, weights=rows, minlength=count)
    null = residual <= 1e-12 * np.maximum(scale, 1e-300)
    number = np.full(count, -1, np.int64)
    number[null] = np.arange(int(null.sum()))
    return int(null.sum()), number[labels]


def _csr(M, symmetric=False):
    """M as a float64 CSR matrix; a CSC one known to be symmetric (the operators of
    :mod:`o3dheat.spectral.fem`) reuses its arrays (they are those of its transpose)."""
    if symmetric and sp.isspmatrix_csc(M) and M.dtype == np.float64:
        return sp.csr_matrix((M.data, M.indices, M.indptr), shape=M.shape)
    return sp.csr_matrix(M, dtype=np.float64)


def geometry_key(prep, mass):
    """The key of a prepared mesh's operators for a mass kind in the cache."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(prep.V, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(prep.F, dtype=np.int64).tobytes())
    h.update(f"{prep.V.shape}{prep.F.shape}|{mass}".encode())
    return h.hexdigest()[:32]


class Shifted:
    """A factor of ``W + γL`` with its size, for the cache."""

    def __init__(self, ops, gamma, backend):
        t0 = time.perf_counter()
        analysis = ops.analysis if backend in ("auto", "cholmod") else None
        self.factor = factorize(ops.shifted(gamma), backend=backend, analysis=analysis)
        self.seconds = time.perf_counter() - t0

    @property
    def nbytes(self):
        """Bytes held by the factor (for the cache)."""
        return int(getattr(self.factor, "nbytes", 0))


def check_operators(L, W):
    """``(L, W)`` as float64 CSR matrices, checked: square, of one size, finite, symmetric, with a
    non-negative diagonal (a positive one for W); W may be None (the identity)."""
    try:
        L = sp.csr_matrix(L, dtype=np.float64)
        W = None if W is None else sp.csr_matrix(W, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise MeshError(f"L and W must be sparse (or dense) matrices of numbers: {e}") from None
    n = L.shape[0]
    if L.shape != (n, n) or (W is not None and W.shape != (n, n)):
        raise MeshError(f"L and W must be square and of one size, got {L.shape} and {getattr(W, 'shape', None)}")
    for name, M in (("L", L), ("W", W)):
        if M is None:
            continue
        if not np.all(np.isfinite(M.data)):
            raise MeshError(f"{name} has NaN or infinite entries")
        if M.nnz and abs(M - M.T).max() > 1e-10 * abs(M).max():
            raise MeshError(f"{name} must be symmetric")
    if np.any(L.diagonal() < 0) or (W is not None and np.any(W.diagonal() <= 0)):
        raise MeshError("L must be positive semi-definite and W positive definite (a negative diagonal entry)")
    return L, W


def time_order(taus):
    """``(zero, order, in_order)``: the indices of the zero times, those of the others by increasing
    time, and whether that is the given order (then the result is written in place, no copy)."""
    zero = np.flatnonzero(taus == 0)
    order = np.flatnonzero(taus > 0)
    order = order[np.argsort(taus[order], kind="stable")]
    return zero, order, len(zero) == 0 and np.array_equal(order, np.arange(len(taus)))


def check_converged(info, tol, max_steps, times, transfer):
    """Raise :class:`~o3dheat.errors.ConvergenceError` when a column of a propagation (``info``, its
    times ``times``) did not reach ``tol``; ``transfer``: whether a transfer function is used."""
    if not info.converged.all():
        bad = int(np.flatnonzero(~info.converged)[0])
        worst = float(info.estimate[bad].max())
        raise ConvergenceError(
            f"the heat flow did not reach tol={tol:g} in {max_steps} steps (column {bad}: estimated "
            f"relative error {worst:.2g} at times {times.min():.4g}..{times.max():.4g})"
            + ("; the transfer function may make the kernel too rough to approximate"
               if transfer else "; raise max_steps, or split the times"))


def finish(U, F, units, order, zero, in_order):
    """The propagated ``U`` (times in increasing order) scaled back by the columns' ``units`` and put
    in the order of the given times (``F`` itself at the zero times)."""
    if np.any(units != 1.0):
        with np.errstate(over="ignore", invalid="ignore"):
            U *= units[None, :, None]
        if not np.all(np.isfinite(U)):
            raise SolverError("Φ_t f exceeds the float64 range (|values| > 1.8e308): rescale the field")
    if not in_order:
        r, c = F.shape
        ordered, U = U, np.empty((r, c, len(order) + len(zero)))
        U[:, :, order] = ordered
        U[:, :, zero] = (F * units)[:, :, None]
        del ordered
    return U


def check_transfer(phi, lam_max, unit):
    """Refuse a transfer function whose full kernel does not exist: φ decreasing without bound
    at high frequencies (exp(−(t/2) φ) would amplify them more, the finer the mesh). ``phi``: from
    :func:`o3dheat.spectral.variants.transfer_function <o3dheat.spectral.variants.transfer_function>`; ``lam_max``: a bound of the operator's largest
    eigenvalue (None: none known); ``unit``: the operator's factor (1, or 1/λ_2)."""
    coef = phi.coefficients
    if coef is not None:
        nz = np.flatnonzero(coef)
        if len(nz) and nz[-1] > 0 and coef[nz[-1]] < 0:
            raise MeshError(f"the transfer polynomial's leading coefficient is negative ({coef[nz[-1]]:g}): "
                            "exp(-(t/2) φ(λ)) grows without bound as λ grows, so the full kernel does not "
                            "exist; use the spectral kernel (o3dheat.HeatKernel), which truncates it")
        return
    if lam_max is None:  # a non-diagonal mass built elsewhere: no bound to sample up to
        return
    top = lam_max * unit  # above every (normalised) eigenvalue
    lam = np.concatenate([[0.0], np.geomspace(max(top * 1e-12, 1e-300), top, 400)])
    phi = phi(lam)
    low = phi[lam <= 0.1 * top]
    if phi[-1] < phi[-40] and phi[-1] < low.min() - 1e-12 * max(np.abs(phi).max(), 1e-300):
        raise MeshError(f"the transfer function decreases to {phi[-1]:.3g} at λ = {top:.3g} (the top of this "
                        "mesh's spectrum), below its values at low frequencies: exp(-(t/2) φ(λ)) amplifies "
                        "the finest details more, the finer the mesh, so the full kernel does not converge; "
                        "use the spectral kernel (o3dheat.HeatKernel), which truncates it")


@dataclass
class FlowReport:
    """How :meth:`o3dheat.HeatFlow.apply <o3dheat.spectral.heatflow.HeatFlow.apply>` computed its result.

    Attributes
    ----------
    tol : float
        The tolerance asked (relative, W-norm, of the non-constant part).
    times : (T,) float64 ndarray
        The times (paper convention).
    estimate : (c, T) float64 ndarray
        A posteriori error estimate per column and time, relative to ``‖f − f₀‖_W``; every
        entry is ``<= tol`` (0 at ``t = 0`` and for fields constant on each part). With a
        transfer function φ: an a priori bound of the error, relative to ``exp(−(t/2) φ(0))
        ‖f − f₀‖_W`` (:func:`chebyshev_bound`; the same for every column).
    steps : (c,) int64 ndarray
        Solves (Lanczos steps) per column, over all shifts.
    shifts : list of (float, (k,) int ndarray)
        Each shift ``γ`` (times τ units) and the indices of the times it served.
    solves : int
        Right-hand sides solved in all (regenerated vectors included).
    timings : dict
        Seconds: "assemble" (0 when the operators were cached), "factorize", "solve".
    backend : str
        The factorization backend.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat
    >>> mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    >>> z = mesh.vertex.positions.numpy()[:, 2]
    >>> F, rep = o3dheat.heat_flow(mesh, z, [0.1, 1.0], return_report=True)
    >>> bool(rep.estimate.max() <= rep.tol), len(rep.shifts), rep.steps.tolist() == [rep.solves]
    (True, 1, True)
    """

    tol: float
    times: np.ndarray
    estimate: np.ndarray
    steps: np.ndarray
    shifts: list
    solves: int
    timings: dict = field(default_factory=dict)
    backend: str = ""

    def __repr__(self):
        return (f"FlowReport(tol={self.tol:g}, times={len(self.times)}, columns={len(self.steps)}, "
                f"solves={self.solves}, shifts={[round(g, 6) for g, _ in self.shifts]}, "
                f"estimate<={float(self.estimate.max(initial=0.0)):.2g}, backend={self.backend!r})")
