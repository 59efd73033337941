"""Shift-and-invert Lanczos for the heat semigroup ``exp(−τ W⁻¹L) F`` at many times at once: :func:`propagate`.

Entry points: :func:`propagate` (from one sparse factor of ``W + γL``), :class:`Propagation` (what
it reports), :data:`MIN_STEPS`, :data:`BREAKDOWN`. This is the restricted-denominator rational Krylov method (Moret & Novati, BIT 44, 2004; van den
Eshof & Hochbruck, SIAM J. Sci. Comput. 27, 2006; Güttel's survey, GAMM-Mitt. 36, 2013).

Notes
-----
``S = (W + γL)⁻¹ W`` is self-adjoint in the W inner product with eigenvalues ``s = 1/(1 + γλ)`` in
``(0, 1]`` (``λ >= 0`` those of ``L x = λ W x``). Lanczos in that inner product gives a W-orthonormal
basis ``V_m`` of ``span{f, S f, …, S^{m−1} f}`` and a tridiagonal ``T_m = V_mᵀ W S V_m``, and

    exp(−τ A) f ≈ f₀ + β₀ V_m g_τ(T_m) e₁,   g_τ(s) = exp(−τ φ((1/s − 1)/γ)),

``φ`` a transfer function (the identity by default), ``f₀`` the W-orthogonal projection of ``f`` on
the null space of ``L`` (the constants of each connected component, kept exactly: ``exp(−τA)`` is
the identity there) and ``β₀ = ‖f − f₀‖_W``. The null space is projected out of every Lanczos
vector (rounding would bring it back), so the basis spans only the part that decays.

The error is uniform in the mesh's largest eigenvalue: it is that of approximating ``g_τ`` by
polynomials in ``s`` on ``(0, 1]``, which depends on ``τ/γ`` only (van den Eshof & Hochbruck),
not on the mesh size. With ``τ`` spanning one decade about 22 solves reach 1e-8; four decades
about 85, with ``γ`` chosen for the range (``heatflow.shift``).

The Lanczos vectors are not re-orthogonalized: for functions of matrices the lost orthogonality
only delays convergence (Druskin, Greenbaum & Knizhnerman, SIAM J. Sci. Comput. 19, 1998; measured
here: full re-orthogonalization saved no step) and saves ``m`` passes over the basis per step.

Error estimate: for each column and time, the W-norm of the difference between the approximations
of steps ``m`` and ``m − max(2, ⌈m/8⌉)`` (the coefficient vectors are in a W-orthonormal basis),
relative to ``β₀``. A column stops when the estimate is below ``tol`` for every time at two consecutive steps,
after at least :data:`MIN_STEPS` steps (so that an approximation still near 0 at a large time,
before the smallest eigenvalues are found, is not taken for converged), or when its Krylov space
is invariant (then the result is exact).

For a transfer function, :mod:`o3dheat.spectral.heatflow` passes instead an a priori ``bound``
(:func:`o3dheat.spectral._flow_setup.chebyshev_bound`): twice the tail of the Chebyshev series of
``g_τ`` on an interval holding the spectrum of S, a rigorous bound of the error after m steps for
every field. It is the stopping rule and the estimate then: the difference of iterates assumes a
fast (geometric) convergence, and fell behind the error (up to 5x near tol, so that errors up to
3.7x tol were returned) where ``g_τ`` has a singularity near the spectrum, which makes the
convergence slow and uneven: √λ's branch point at λ = 0 (s = 1), the pole of λ/(1 + λ) and the
branch point of log(1 + λ) at λ = −1 (s = 1/(1 − γ)).

Many columns run in lockstep: one multi-column solve per step serves every column still running
(each has its own tridiagonal and stops on its own estimate); columns that lie in the null space
need no step.

Memory: the basis (one vector per step and column) is kept while it fits in ``basis_bytes``; past
it the rest of the vectors are regenerated after convergence (the same operations from the last
kept state, so the same vectors: about one more solve per step not kept) instead of stored.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike

from o3dheat.errors import MeshError, SolverError

from . import _krylov_loops as loops

__all__ = ["propagate", "Propagation", "MIN_STEPS", "BREAKDOWN"]

#: fewest Lanczos steps before a column may stop on its error estimate (unless its Krylov space is
#: invariant, the result then being exact)
MIN_STEPS = 8
#: ``β_m`` below this (``‖S‖_W <= 1``, so T's entries are at most 1): the Krylov space is invariant
BREAKDOWN = 1e-12
_CHUNK = 16  # basis vectors per stored block


@dataclass
class Propagation:
    """What :func:`propagate` did.

    Attributes
    ----------
    steps : (c,) int64 ndarray
        Lanczos steps (solves) per column; 0 for a column in the null space (constant per part).
    estimate : (c, T) float64 ndarray
        The error estimate of each column at each time, relative to ``‖f − f₀‖_W`` (0 where exact).
    converged : (c,) bool ndarray
        Whether each column's estimate reached ``tol`` (or its Krylov space was invariant).
    solves : int
        Right-hand sides solved, counting the regenerated vectors.
    replayed : int
        Steps whose vectors were regenerated instead of stored (``basis_bytes``).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from o3dheat.spectral.krylov import propagate
    >>> L = sp.diags([[1., 2, 2, 1], [-1., -1, -1], [-1., -1, -1]], [0, 1, -1], format="csr")
    >>> lu = sp.linalg.splu(sp.csc_matrix(sp.identity(4) + 0.5 * L))
    >>> U, info = propagate(lu.solve, None, np.eye(4)[:, :2], np.array([1.0]), 0.5,
    ...                     null=(np.zeros(4, int), np.ones(4)))
    >>> info.steps.tolist(), info.converged.tolist(), info.solves
    ([3, 3], [True, True], 6)
    """

    steps: np.ndarray
    estimate: np.ndarray
    converged: np.ndarray
    solves: int = 0
    replayed: int = 0


class _Null:
    """The null space of L: the constants of each part (labels; -1 for the rows of a part where
    L has none), ``d = W 1`` and each part's mass."""

    def __init__(self, null, n):
        labels, d = null
        self.labels = np.ascontiguousarray(labels, dtype=np.int64)
        self.d = np.ascontiguousarray(d, dtype=np.float64)
        if self.labels.shape != (n,) or self.d.shape != (n,):
            raise MeshError(f"the null space needs a label and a weight per row, got {self.labels.shape}, "
                            f"{self.d.shape}")
        self.parts = int(self.labels.max()) + 1 if n else 0
        on = self.labels >= 0
        self.mass = np.bincount(self.labels[on], weights=self.d[on], minlength=self.parts)

    def project_out(self, X, WX, sums=None):
        """In place: X and WX = W X lose their W-orthogonal projection on each part's constants
        (``sums``: WX's sums over each part, when known); returns ``Σ X ∘ WX`` afterwards, by column."""
        n = len(X)
        if sums is None:
            sums = loops.rows(loops.part_sums, n, WX, self.labels, self.parts)
        return loops.rows(loops.project, n, X, WX, self.d, self.labels, sums / self.mass[:, None])

    def times(self, W, X, WX):
        """``WX = W X`` (W in CSR), and WX's sums over each part."""
        return loops.rows(loops.spmm, len(X), W.indptr, W.indices, W.data, X, WX, self.labels, self.parts)


class _State:
    """The Lanczos recurrence of the columns still running (which of the caller's: ``cols``): the
    current and previous vectors, W times the current ones, the previous β, and the buffers of the
    next vectors (all (n, a), C-ordered, reused from step to step)."""

    def __init__(self, cols, V, WV, Vp=None, bp=None):
        self.cols, self.V, self.WV = cols, np.ascontiguousarray(V), np.ascontiguousarray(WV)
        self.Vp = np.zeros_like(self.V) if Vp is None else np.ascontiguousarray(Vp)
        self.bp = np.zeros(len(cols)) if bp is None else bp
        self.Z, self.WZ = np.empty_like(self.V), np.empty_like(self.V)

    def copy(self):
        return _State(self.cols.copy(), self.V.copy(), self.WV.copy(), self.Vp.copy(), self.bp.copy())

    def keep(self, mask):
        """Only the columns where ``mask`` (over the running ones) is True go on."""
        if not mask.all():
            self.cols, self.bp = self.cols[mask], self.bp[mask]
            for name in ("V", "WV", "Vp", "Z", "WZ"):
                setattr(self, name, np.ascontiguousarray(getattr(self, name)[:, mask]))


def _step(state, solve, W, null):
    """One Lanczos step of every running column, into ``state.Z`` (the next vectors times β) and
    ``state.WZ``; returns (α, β)."""
    n = len(state.V)
    solve(state.WV, state.Z)
    al = loops.rows(loops.update, n, state.Z, state.Vp, state.WV, state.bp)
    loops.rows(loops.subtract, n, state.Z, state.V, al)
    b2 = null.project_out(state.Z, state.WZ, null.times(W, state.Z, state.WZ))
    return al, np.sqrt(np.maximum(b2, 0.0))


def _advance(state, be):
    """The next vectors of the running columns (β > 0 for each), into the buffers of the previous
    ones (the current W V is no longer needed once α is known)."""
    V = state.Vp
    loops.rows(loops.scale, len(V), state.Z, state.WZ, 1.0 / be, V, state.WV)
    state.Vp, state.V, state.bp = state.V, V, be


def _result(f0, decay, blocks, coefficients, out):
    """(n, c, T), into ``out`` when given: the null-space part ``f0 ⊗ decay`` plus each column's
    stored vectors times its coefficients, summed row by row in one pass over the stored basis
    (:func:`o3dheat.spectral._krylov_loops.assemble`)."""
    from numba.typed import List

    n, c = f0.shape
    T = len(decay)
    U = np.empty((n, c, T)) if out is None else out
    M = max([len(Y) for Y in coefficients.values()], default=0)
    coef = np.zeros((c, max(M, 1), T))
    ncoef = np.zeros(c, dtype=np.int64)
    for j, Y in coefficients.items():
        coef[j, :len(Y)] = Y
        ncoef[j] = len(Y)
    # each block holds its vectors written so far (the last may be partly filled)
    stored = List([block for _, _, _, block in blocks] or [np.zeros((1, 1, n))])
    pos = np.full((max(len(blocks), 1), c), -1, dtype=np.int64)
    for b, (cols, _, _, _) in enumerate(blocks):
        pos[b, cols] = np.arange(len(cols))
    bfirst = np.array([first for _, first, _, _ in blocks] or [0], dtype=np.int64)
    bcount = np.array([count for _, _, count, _ in blocks] or [0], dtype=np.int64)
    loops.rows(loops.assemble, n, U, np.ascontiguousarray(f0.T), np.ascontiguousarray(decay), stored, pos, bfirst,
               bcount, coef, ncoef)
    return U


def _solver(solve):
    """``solve(B, out)`` from a solver with or without an ``out`` keyword."""
    try:
        takes_out = "out" in inspect.signature(solve).parameters
    except (TypeError, ValueError):
        takes_out = False
    if takes_out:
        return lambda B, out: solve(B, out=out)

    def into(B, out):
        out[...] = solve(B)

    return into


def _coefficients(al, be, b0, gamma, taus, rates):
    """``β₀ g_τ(T_m) e₁`` for every τ: (m, T)."""
    m = len(al)
    if m == 1:
        th, U = np.array(al, dtype=np.float64), np.ones((1, 1))
    else:
        th, U = sla.eigh_tridiagonal(np.asarray(al), np.asarray(be[:m - 1]))
    if th[-1] > 1.0 + 1e-8:  # s = 1/(1 + γλ) <= 1 for λ >= 0
        raise SolverError(f"L has a negative eigenvalue (about {(1.0 / th[-1] - 1.0) / gamma:.3g}): the heat "
                          "flow needs a positive semi-definite L (a Laplacian)")
    ok = th > 0
    lam = np.full(m, np.inf)
    lam[ok] = np.maximum((1.0 / th[ok] - 1.0) / gamma, 0.0)  # λ >= 0 (rounding near s = 1)
    finite = np.isfinite(lam)
    r = np.zeros(m)
    if rates is None:
        r[finite] = lam[finite]
    elif finite.any():
        r[finite] = rates(lam[finite])
    with np.errstate(over="ignore", invalid="ignore"):
        g = np.exp(-np.multiply.outer(r, taus))
    g[~finite] = 0.0
    if not np.all(np.isfinite(g)):
        raise SolverError("the filter factors exp(-τ φ(λ)) overflow: the transfer function is too negative "
                          "for these times (a negative φ amplifies without bound)")
    return b0 * (U @ (g * U[0][:, None]))


def _lag(m):
    """How many steps back the estimate of step m compares: ``max(2, ⌈m/8⌉)``. Lanczos converges
    in bursts at large times (a plateau while the next Ritz value settles): a lag of 2 stopped
    with errors up to 5x the tolerance on irregular meshes, m/8 never (dense references of
    three meshes, two masses, three fields, five time grids), for 5-15% more steps."""
    return max(2, -(-m // 8))


def _difference(Y, Yold):
    """Column norms of ``Y − [Yold; 0]``."""
    D = Y.copy()
    D[:len(Yold)] -= Yold
    return np.linalg.norm(D, axis=0)


def propagate(solve: Callable, W: sp.spmatrix | None, F: ArrayLike, taus: ArrayLike, gamma: float, *,
              null: tuple | None = None, tol: float = 1e-8, max_steps: int = 1000, rates: Callable | None = None,
              null_rate: float = 0.0, basis_bytes: float | None = None, min_steps: int = MIN_STEPS,
              out: np.ndarray | None = None, release: Callable | None = None,
              bound: np.ndarray | None = None) -> tuple[np.ndarray, Propagation]:
    """``exp(−τ W⁻¹L) F`` at every τ, from a solver of ``W + γL`` (see the module notes).

    Parameters
    ----------
    solve : callable
        ``B (n, a) -> (W + γL)⁻¹ B``, for example :meth:`o3dheat.spectral.linalg.Factor.solve`.
    W : (n, n) sparse matrix or None
        The mass (symmetric positive definite); None for the identity.
    F : (n, c) float64 ndarray
        The fields.
    taus : (T,) float64 ndarray
        Times ``τ > 0`` (the rate is ``exp(−τ λ)``: the paper's ``t`` is ``2τ``).
    gamma : float
        The shift (> 0) the factor was made with.
    null : (labels, d) or None
        The null space of ``L``: a part label per row (the constants of each part are in it; -1:
        that row's part has no null vector) and ``d = W 1``. None: ``L`` is positive definite.
    tol : float
        Relative error asked, in the W-norm, relative to ``‖f − f₀‖_W`` (f₀ the null-space part).
    max_steps : int
        Most steps per column; a column that does not converge by then is reported, not hidden
        (``converged`` False, its estimate in ``estimate``).
    rates : callable, optional
        ``φ``: decay rates of the eigenvalues (vectorised, finite), for transfer functions.
    null_rate : float
        ``φ(0)``, factored out exactly: the result is ``exp(−τ φ(0))`` times that of the rates
        ``φ − φ(0)`` (the null-space part's factor; 1 without ``rates``). The estimate is that of
        the second factor.
    basis_bytes : int, optional
        Memory for the stored basis (default: unbounded); vectors beyond it are regenerated.
    min_steps : int
        Fewest steps before the estimate may stop a column.
    out : (n, c, T) float64 ndarray, optional
        Where to write the result (a view of a larger array is fine).
    release : callable, optional
        Called once the steps are done, before the result's memory is taken (for example
        :meth:`o3dheat.spectral.linalg.Factor.release`: the solver's workspaces).
    bound : (T, M) float64 ndarray, optional
        A priori error bounds (relative to ``‖f − f₀‖_W``) after ``m = 0 .. M−1`` steps at each
        time, valid for every field (:func:`o3dheat.spectral._flow_setup.chebyshev_bound`): then a
        column stops at the first m whose bound is ``<= tol`` at every time (or at ``M − 1``, or when
        its Krylov space is invariant), and its estimate is that bound; ``min_steps`` is not used.

    Returns
    -------
    U : (n, c, T) float64 ndarray
        ``out`` when given.
    info : Propagation

    Examples
    --------
    A path graph of 4 vertices (W = I): heat spreads from the first vertex and keeps its total.

    >>> import numpy as np, scipy.sparse as sp, scipy.linalg as sla
    >>> from o3dheat.spectral.krylov import propagate
    >>> L = sp.diags([[1., 2, 2, 1], [-1., -1, -1], [-1., -1, -1]], [0, 1, -1], format="csr")
    >>> lu = sp.linalg.splu(sp.csc_matrix(sp.identity(4) + 0.5 * L))
    >>> U, info = propagate(lu.solve, None, np.eye(4)[:, :1], np.array([0.3, 3.0]), 0.5,
    ...                     null=(np.zeros(4, int), np.ones(4)))
    >>> exact = sla.expm(-3.0 * L.toarray())[:, 0]
    >>> bool(np.allclose(U[:, 0, 1], exact, atol=1e-12)), info.steps.tolist()
    (True, [3])
    """
    F, taus = _check_arguments(F, taus, gamma, tol, out)
    n, c = F.shape
    if bound is not None:
        bound = np.asarray(bound, dtype=np.float64)
        if bound.ndim != 2 or bound.shape[0] != len(taus) or bound.shape[1] < 2:
            raise MeshError(f"bound must have one row per time and a column per step count, got {bound.shape}")
    rates = _less_null_rate(rates, null_rate)
    W, null = _operator(W, null, n)
    solve = _solver(solve)
    F1, WF1, scale, b0 = _split_null(F, W, null)
    with np.errstate(over="ignore"):
        decay = np.exp(-taus * float(null_rate))
    if not np.all(np.isfinite(decay)):
        raise SolverError("exp(-τ φ(0)) overflows: the transfer function is too negative at 0 for these times")
    f0 = F - F1  # the null-space part, exact: exp(-τ φ(0)) f0 at every time
    # a column whose non-constant part is at rounding level of the field is constant per part
    live = b0 > 1e-14 * np.maximum(scale, 1e-300)
    track = _Columns(np.flatnonzero(live), c, b0, gamma, taus, rates, decay, tol, min_steps, max_steps, bound)
    if not live.any():
        return _result(f0, decay, [], {}, out), Propagation(track.steps, track.estimate, track.converged)
    state = _start_state(live, F1, WF1, b0)
    del F1, WF1
    basis = _Basis(n, np.inf if basis_bytes is None else float(basis_bytes))
    store = basis.store
    schedule = []  # per step: the running columns (for the replay)
    solves = 0
    done_coef = track.done_coef
    step = 0
    store(state, step)
    while len(state.cols):
        schedule.append(state.cols.copy())
        al, be = _step(state, solve, W, null)
        solves += len(state.cols)
        step += 1
        go = track.update(state.cols, al, be)
        be = be[go]
        state.keep(go)
        if len(state.cols):
            _advance(state, be)
            store(state, step)
    del state  # its buffers, before the result's memory is taken
    if release is not None:
        release()
    U = _result(f0, decay, basis.blocks, done_coef, out)
    basis.blocks.clear()
    replayed = 0
    if basis.saved is not None:  # the vectors not stored: regenerated from the last stored state
        more, replayed = _replay(basis.saved, schedule, done_coef, U, solve, W, null)
        solves += more
    return U, Propagation(track.steps, track.estimate, track.converged, solves, replayed)


def _less_null_rate(rates, null_rate):
    """The rates less φ(0): ``exp(-τ φ) = exp(-τ φ(0)) exp(-τ (φ - φ(0)))``, φ(0) applied exactly."""
    if rates is None or null_rate == 0.0:
        return rates
    phi = rates

    def less(lam):
        return phi(lam) - null_rate

    return less


def _start_state(live, F1, WF1, b0):
    """The first Lanczos state: the live columns of F1 and W F1, normalised."""
    cols = np.flatnonzero(live)
    if live.all():  # in place: no copies of (n, c) arrays (fresh memory is slow to touch)
        F1 /= b0
        WF1 /= b0
        return _State(cols, F1, WF1)
    return _State(cols, F1[:, cols] / b0[cols], WF1[:, cols] / b0[cols])


class _Columns:
    """Each column's tridiagonal coefficients, its last coefficient arrays, its estimate and when
    it stops (steps, converged, the final coefficients ``done_coef``)."""

    def __init__(self, cols, c, b0, gamma, taus, rates, decay, tol, min_steps, max_steps, bound=None):
        self.alphas = {j: [] for j in cols}
        self.betas = {j: [] for j in cols}
        self.history = {j: [] for j in cols}  # the last coefficient arrays, newest last
        self.under = {j: 0 for j in cols}  # consecutive steps with the estimate under tol
        self.steps = np.zeros(c, dtype=np.int64)
        self.estimate = np.zeros((c, len(taus)))
        self.converged = np.ones(c, dtype=bool)
        self.done_coef = {}
        self.settings = (b0, gamma, taus, rates, decay, tol, min_steps, max_steps)
        self.bound = bound

    def update(self, cols, al, be):
        """One step's coefficients of the running columns ``cols``: which of them go on."""
        if self.bound is not None:
            return self._update_bounded(cols, al, be)
        b0, gamma, taus, rates, decay, tol, min_steps, max_steps = self.settings
        alphas, betas, history, under = self.alphas, self.betas, self.history, self.under
        estimate, converged, done_coef, steps = self.estimate, self.converged, self.done_coef, self.steps
        go = np.ones(len(cols), dtype=bool)
        for k, j in enumerate(cols):
            alphas[j].append(al[k])
            betas[j].append(be[k])
            Y = _coefficients(alphas[j], betas[j], b0[j], gamma, taus, rates)
            m = len(alphas[j])
            lag = _lag(m)
            history[j] = (history[j] + [Y])[-(lag + 1):]
            exhausted = be[k] <= BREAKDOWN
            if m > lag:
                estimate[j] = _difference(Y, history[j][0]) / b0[j]
                under[j] = under[j] + 1 if estimate[j].max() <= tol else 0
            if exhausted:
                estimate[j] = 0.0
            if exhausted or (under[j] >= 2 and m >= min_steps) or m >= max_steps:
                go[k] = False
                converged[j] = exhausted or under[j] >= 2
                done_coef[j] = Y * decay  # exp(-τ φ(0)), 1 but for transfer functions
                steps[j] = m
        return go

    def _update_bounded(self, cols, al, be):
        """:meth:`update` with an a priori bound: the coefficients are needed only at the end."""
        b0, gamma, taus, rates, decay, tol, _, max_steps = self.settings
        bound = self.bound
        go = np.ones(len(cols), dtype=bool)
        for k, j in enumerate(cols):
            self.alphas[j].append(al[k])
            self.betas[j].append(be[k])
            m = len(self.alphas[j])
            est = bound[:, min(m, bound.shape[1] - 1)]
            exhausted = be[k] <= BREAKDOWN
            if exhausted or est.max() <= tol or m >= min(max_steps, bound.shape[1] - 1):
                go[k] = False
                self.converged[j] = exhausted or est.max() <= tol
                self.estimate[j] = 0.0 if exhausted else est
                self.done_coef[j] = _coefficients(self.alphas[j], self.betas[j], b0[j], gamma, taus, rates) * decay
                self.steps[j] = m
        return go


def _check_arguments(F, taus, gamma, tol, out):
    """``(F, taus)`` as float64 arrays, with the shift, the tolerance and ``out`` checked."""
    F = np.asarray(F, dtype=np.float64)
    if F.ndim != 2:
        raise MeshError(f"propagate takes fields of shape (n, c), got {F.shape}")
    n, c = F.shape
    taus = np.asarray(taus, dtype=np.float64)
    if taus.ndim != 1 or taus.size == 0 or not np.all(np.isfinite(taus)) or np.any(taus <= 0):
        raise MeshError("propagate needs a non-empty 1-D array of finite times > 0")
    if not (np.isfinite(gamma) and gamma > 0):
        raise MeshError(f"the shift must be a positive number, got {gamma}")
    if not (0 < tol < 1):
        raise MeshError(f"tol must lie in (0, 1), got {tol}")
    T = len(taus)
    if out is not None and (out.shape != (n, c, T) or out.dtype != np.float64):
        raise MeshError(f"out must be a float64 array of shape {(n, c, T)}, got {out.shape} {out.dtype}")
    return F, taus


def _operator(W, null, n):
    """``(W, null)``: the mass as sorted CSR (the identity for None) and the null space of L."""
    W = sp.identity(n, format="csr") if W is None else sp.csr_matrix(W)
    if not W.has_sorted_indices:
        W = W.sorted_indices()  # a copy: the caller's matrix is never changed
    d = np.asarray(W.sum(axis=1)).ravel()
    return W, _Null((np.full(n, -1, np.int64), d) if null is None else null, n)


def _split_null(F, W, null):
    """``(F1, W F1, scale, b0)``: the fields without their null-space part, W times them, the
    fields' W-norms and those of ``F1``."""
    F1 = np.ascontiguousarray(F, dtype=np.float64).copy()
    WF1 = np.empty_like(F1)
    sums = null.times(W, F1, WF1)
    scale = np.sqrt(np.maximum(np.einsum("ij,ij->j", F1, WF1), 0.0))
    b0 = np.sqrt(np.maximum(null.project_out(F1, WF1, sums), 0.0))
    return F1, WF1, scale, b0


class _Basis:
    """The Lanczos vectors stored for the result, in blocks ``[cols, first step, count, (a, _CHUNK,
    n) array]``, within ``budget`` bytes; past it, ``saved`` is the ``(step, state copy)`` where
    storing stopped (the replay starts there)."""

    def __init__(self, n, budget):
        self.n, self.budget, self.used = n, budget, 0.0
        self.blocks = []
        self.saved = None

    def store(self, state, step):
        if self.saved is not None:
            return
        blocks, n = self.blocks, self.n
        last = blocks[-1] if blocks else None
        if last is None or last[2] == _CHUNK or not np.array_equal(last[0], state.cols):
            need = 8.0 * n * _CHUNK * len(state.cols)
            if self.used + need > self.budget:
                self.saved = (step, state.copy())
                return
            last = [state.cols.copy(), step, 0, np.empty((len(state.cols), _CHUNK, n))]
            blocks.append(last)
            self.used += need
        loops.rows(loops.transpose_into, n, state.V, last[3][:, last[2], :])
        last[2] += 1


def _replay(saved, schedule, done_coef, U, solve, W, null):
    """Add to U the vectors that were not stored, regenerated from ``saved`` (the same operations,
    so the same vectors); returns ``(solves, steps)`` made for that."""
    start, state = saved
    n = U.shape[0]
    solves = replayed = 0
    for i in range(start, len(schedule) + 1):
        for k, j in enumerate(state.cols):  # vector i of column j
            if i < len(done_coef[j]):
                loops.rows(loops.add_outer, n, U[:, j, :], np.ascontiguousarray(state.V[:, k]),
                           np.ascontiguousarray(done_coef[j][i]))
        if i == len(schedule):
            break
        state.keep(np.isin(state.cols, schedule[i]))
        if not len(state.cols):
            break
        al, be = _step(state, solve, W, null)
        solves += len(state.cols)
        replayed += 1
        alive = np.array([i + 1 < len(done_coef[j]) for j in state.cols])
        if not alive.any():
            break
        be = be[alive]
        state.keep(alive)
        _advance(state, be)
    return solves, replayed
