"""The eigensolvers behind :func:`o3dheat.spectral.spectrum.eigensolve`: :func:`solve_eigenproblem`.

Entry points: :func:`solve_eigenproblem` (the method chosen by size, its fallbacks, the memory
checked first; eigenpairs sorted, B-orthonormal, with fixed signs and canonical bases of multiple
eigenvalues), :func:`residuals` (normwise backward errors), :func:`weyl_gap`. The methods: block
shift-invert Lanczos (:mod:`o3dheat.spectral.lanczos`), ARPACK on the same factor, dense LAPACK.
"""

from __future__ import annotations

import contextlib
import logging
import time

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from o3dheat import parallel
from o3dheat.errors import ConvergenceError, MeshError, SolverError
from o3dheat.memory import available_memory, check_memory, peak_memory

from .lanczos import block_lanczos, rayleigh_ritz
from .linalg import analyze, factorize

log = logging.getLogger("o3dheat")

DENSE_MAX_N = 1200
DENSE_LIMIT_N = 12_000  # above this a dense solve needs several GiB: never chosen automatically
# Measured (scripts/bench_spectrum.py, 2 cores): the block Lanczos wins from about 10k vertices,
# and from 3k when k >= 64 (1.1-2x at 3k-8k, k = 70-100); below, ARPACK's single-vector Lanczos on
# the same CHOLMOD factor needs fewer solves and less work (10-20% faster for k = 10-50).
LANCZOS_MIN_N = 10_000
LANCZOS_MANY_K = (64, 3_000)  # (k, n): from k eigenpairs on n vertices up, Lanczos as well


#: magnitudes within this fraction of an eigenvector's largest one tie for its sign (:func:`_fix_signs`)
SIGN_TIE = 1e-6


def _fix_signs(X, chunk=16, tie=SIGN_TIE):
    """In place: the entry of largest magnitude of each column becomes positive; entries whose
    magnitudes are within ``tie`` of the largest (relative) tie, and the first of them decides.

    On a symmetric mesh an eigenvector's largest magnitudes are equal, at symmetric vertices,
    often with opposite signs: which one is largest is then decided by rounding, and a solve whose
    rounding differed (BLAS on another thread count, another method) flipped the whole vector (a
    difference of twice its largest entry). The first of the tied entries is the same in every
    solve. By column chunks shared out among threads: no n x k temporary."""

    def fix(a, z):
        Xc = X[:, a:z]
        A = np.abs(Xc)
        first = np.argmax(A >= (1.0 - tie) * A.max(axis=0), axis=0)
        s = np.sign(Xc[first, np.arange(Xc.shape[1])])
        s[s == 0] = 1.0
        Xc *= s

    parallel.run(fix, parallel.row_parts(X.shape[1], chunk))  # ranges of columns
    return X


def residuals(L, B, lam, X, chunk=16, b_norms=False):
    """Normwise backward errors, computed in column chunks (no n x k temporaries), the chunks
    shared out among threads (each column is computed whole by one thread); with ``b_norms``, also
    the columns' B-norms squared ``xᵀ B x`` (from the same products)."""
    nL = abs(L).sum(axis=0).max()
    nB = abs(B).sum(axis=0).max()
    L, B = sp.csr_matrix(L), sp.csr_matrix(B)

    def backward_errors(a, z):
        Xc = np.ascontiguousarray(X[:, a:z])
        BXc = B @ Xc
        R = L @ Xc - BXc * lam[a:z]
        res = np.linalg.norm(R, axis=0) / ((nL + np.abs(lam[a:z]) * nB) * np.linalg.norm(Xc, axis=0) + 1e-300)
        return res, np.einsum("ij,ij->j", Xc, BXc)

    parts = parallel.run(backward_errors, parallel.row_parts(X.shape[1], chunk))
    res = np.concatenate([p[0] for p in parts])
    return (res, np.concatenate([p[1] for p in parts])) if b_norms else res


def _b_orthonormalize(X, B):
    """Make Xᵀ B X = I exactly (to rounding) with one Cholesky of the k x k Gram matrix."""
    G = X.T @ (B @ X)
    G = (G + G.T) / 2
    try:
        C = np.linalg.cholesky(G)
    except np.linalg.LinAlgError as e:
        raise SolverError("the eigenvectors are not linearly independent (eigensolver failure)") from e
    return sla.solve_triangular(C, X.T, lower=True).T


def weyl_gap(B):
    """Weyl's law: λ_j ≈ 4π j / area, so 4π / area is the expected gap between eigenvalues."""
    return 4 * np.pi / float(B.sum())


def _shift(B):
    # a hundredth of the first gap below 0
    return -0.01 * weyl_gap(B)


def _choose_method(method, r, k):
    """"dense", "arpack" or "lanczos" for r vertices and k eigenpairs (see eigensolve)."""
    many_k = k >= LANCZOS_MANY_K[0] and r >= LANCZOS_MANY_K[1]
    iterative = "lanczos" if r >= LANCZOS_MIN_N or many_k else "arpack"
    if method == "auto":
        method = "dense" if (r <= DENSE_MAX_N or k > r // 2) and r <= DENSE_LIMIT_N else iterative
    if k >= r - 1:
        method = "dense"  # ARPACK and the block Lanczos need k < n - 1
    if method == "dense" and r > DENSE_LIMIT_N:
        raise MeshError(f"a dense eigensolve of {r} vertices would need about "
                        f"{2 * 8 * r * r / 2**30:.0f} GiB: ask for k < {r - 1} eigenpairs with "
                        "method='auto' (iterative), or use a smaller mesh")
    return method


def _solve_arpack(L, B, k, sigma, backend, seed, analysis=None):
    # machine precision: a looser ARPACK tolerance was seen to miss copies of multiple eigenvalues
    t0 = time.perf_counter()
    fac = factorize(L - sigma * B, backend=backend, analysis=analysis)
    t1 = time.perf_counter()
    n = L.shape[0]
    op = spla.LinearOperator((n, n), matvec=fac.solve, dtype=np.float64)
    ncv = min(n - 1, max(2 * k + 1, 20))
    try:
        lam, X = spla.eigsh(L, k=k, M=B, sigma=sigma, which="LM", OPinv=op, ncv=ncv, tol=0.0,
                            v0=np.random.default_rng(seed).standard_normal(n), maxiter=max(1000, 20 * k))
    except spla.ArpackNoConvergence as e:
        raise ConvergenceError(f"the eigensolver did not converge for k={k}: {e}") from e
    except spla.ArpackError as e:  # e.g. a shift so far from the spectrum that L - sigma B is sigma B to rounding
        raise ConvergenceError(f"ARPACK failed for k={k} with the shift sigma={sigma:.3g}: {e} (choose a shift "
                               "near 0, below the smallest eigenvalue, or method='lanczos')") from e
    return lam, X, fac.backend, t1 - t0, time.perf_counter() - t1


def _solve_lanczos(L, B, k, sigma, backend, seed, tol, block, analysis=None):
    # L, B come renumbered in CSR (_permuted): the format of fast products with blocks of vectors
    t0 = time.perf_counter()
    fac = factorize(L - sigma * B, backend=backend, analysis=analysis)
    t1 = time.perf_counter()
    used = fac.backend
    buf = {}  # block_lanczos keeps no solution past the next solve: one buffer per shape serves all

    # F821 silenced in solve: ruff sees the `del buf, fac` below, after solve's last call
    def solve(Y):
        if Y.shape not in buf:  # noqa: F821 - deleted after the last call
            buf[Y.shape] = np.empty(Y.shape)  # noqa: F821 - deleted after the last call
        return fac.solve(Y, out=buf[Y.shape])  # noqa: F821 - deleted after the last call

    _, Xv, info = block_lanczos(L, B, solve, k, sigma, block=block, tol=max(tol, 1e-14), seed=seed,
                                refine=False)
    del buf, solve
    del fac  # free the factorization before the Rayleigh-Ritz (peak memory)
    lam, X = rayleigh_ritz(L, B, Xv, overwrite=True)  # in the memory of the basis
    log.info("block Lanczos: %s", info)
    return lam, X, used, t1 - t0, time.perf_counter() - t1


def _permuted(A, perm):
    """``A[perm][:, perm]`` as CSR (the format of the products with blocks of vectors)."""
    return sp.csr_matrix(sp.csr_matrix(A)[perm][:, perm])


def _unpermuted(X, perm, chunk=32):
    """Rows of X back to the original numbering: ``out[perm] = X``, by column chunks (no n x k
    temporary beyond the result) shared out among threads."""
    out = np.empty(X.shape, order="F")
    parallel.run(lambda a, z: out.__setitem__((perm, slice(a, z)), X[:, a:z]),
                 parallel.row_parts(X.shape[1], chunk))  # ranges of columns
    return out


def _solve_dense(L, B, k):
    t0 = time.perf_counter()
    # up to DENSE_MAX_N the BLAS gains nothing from threads (measured), and when another process
    # keeps a core busy OpenBLAS' spinning threads made a 1152-vertex solve 90x slower: one thread
    small = L.shape[0] <= DENSE_MAX_N
    with parallel.blas_one_thread() if small else contextlib.nullcontext():
        lam, X = sla.eigh(L.toarray(), B.toarray(), subset_by_index=[0, k - 1])
    return lam, X, "dense", 0.0, time.perf_counter() - t0


def solve_eigenproblem(L, B, k, method, sigma, backend, seed, tol, block):
    """Smallest k eigenpairs of L x = λ B x: (λ, X B-orthonormal with fixed signs, backend, σ,
    residuals, timings).

    The chosen method falls back when it fails to converge (the block Lanczos on tiny meshes,
    whose Krylov space is nearly exhausted by a 2k-vector basis; ARPACK on hard clusters):
    "lanczos" -> "arpack" -> "dense", the last only where a dense solve fits in memory."""
    r = L.shape[0]
    method = _choose_method(method, r, k)
    chain = {"lanczos": ["lanczos", "arpack", "dense"], "arpack": ["arpack", "dense"]}.get(method, [method])
    chain = [m for m in chain if m != "dense" or r <= DENSE_LIMIT_N]
    if chain[0] == "dense":
        check_memory(3 * 8 * r * r, f"a dense eigensolve of {r} vertices", "ask for fewer eigenpairs (iterative)")
    else:  # the iterative solves check their memory once the factor's size is known (_solve_by)
        free = available_memory()
        if free is not None and 3 * 8 * r * r > free:
            chain = [m for m in chain if m != "dense"]
    for i, m in enumerate(chain):
        try:
            return _solve_by(L, B, k, m, sigma, backend, seed, tol, block)
        except ConvergenceError as e:
            if i + 1 == len(chain):
                raise
            log.warning("eigensolver %r failed (%s): falling back to %r", m, e, chain[i + 1])


def _canonical_bases(lam, X, B, scale, rel=1e-9):
    """In place: the basis of each cluster of equal eigenvalues (to ``rel`` of ``scale``, the
    eigensolver's accuracy: numerically one eigenspace) made independent of how the solver chose
    it: ``X_c P`` with ``P`` the orthogonal polar factor of ``X_cᵀ B G``, ``G`` a fixed
    pseudo-random block. Any B-orthonormal basis ``X_c Q`` of the same space gives the same result
    (to rounding): ``polar(Qᵀ M) = Qᵀ polar(M)``. Four concurrent dense eigensolves (threads
    change the BLAS's rounding) rotated the sphere's multiple eigenvectors arbitrarily before."""
    lam = np.asarray(lam)
    tied = np.diff(lam) <= rel * np.maximum(np.abs(lam[1:]), scale)  # tied[i]: λ_i and λ_{i+1} one cluster
    if not tied.any():  # simple eigenvalues only: nothing to do (no copy, no conversion)
        return X
    B = sp.csr_matrix(B)
    starts = np.flatnonzero(np.r_[True, ~tied])
    for i, j in zip(starts, np.r_[starts[1:], len(lam)], strict=True):
        if j - i > 1:
            G = np.random.default_rng(20261201 + j - i).standard_normal((X.shape[0], j - i))
            U, _, Vt = np.linalg.svd(X[:, i:j].T @ (B @ G))
            X[:, i:j] = X[:, i:j] @ (U @ Vt)
    return X


def _solve_by(L, B, k, method, sigma, backend, seed, tol, block):
    B_in = B
    use_dense = method == "dense"
    s = float("nan") if use_dense else (_shift(B) if sigma is None else float(sigma))
    perm, t_perm = None, 0.0
    if use_dense:
        lam, X, used, t_fac, t_sol = _solve_dense(L, B, k)
    else:
        # renumber the vertices for memory locality (reverse Cuthill-McKee): the products with L and
        # B, which read rows of blocks of vectors at the neighbours' indices, are 2x faster on meshes
        # stored in a scattered order (decimated, remeshed); the results are numbered back
        what = f"the eigensolve of {k} eigenpairs on {L.shape[0]:,} vertices"
        advice = ("ask for fewer eigenpairs, decimate the mesh, or smooth with o3dheat.heat_flow (the full "
                  "heat kernel, without eigenpairs: a fraction of this memory)")
        # what is known without the factor first: at 10M vertices the basis alone does not fit, and the
        # ordering would take minutes before the refusal
        check_memory(peak_memory(L.shape[0], k, block, 0), f"{what}, its factor aside,", advice)
        t0 = time.perf_counter()
        perm = reverse_cuthill_mckee(sp.csr_matrix(L), symmetric_mode=True)
        L, B = _permuted(L, perm), _permuted(B, perm)
        # the factor's size from its symbolic analysis (shared with the factorization): then the memory check
        analysis = analyze(L - s * B) if backend in ("auto", "cholmod") else None
        check_memory(peak_memory(L.shape[0], k, block, None if analysis is None else analysis.nbytes), what, advice)
        t_perm = time.perf_counter() - t0
        # BLAS on one thread from the factorization to the end (as in a small dense solve): BLAS
        # sums (ARPACK's dot products, a factorization's blocks) depend on its thread count, and
        # while another thread is inside parallel.blas_one_thread that count is one; the same
        # count in every call gives the same results, serial or concurrent, bit for bit
        with parallel.blas_one_thread():
            if method == "arpack":
                lam, X, used, t_fac, t_sol = _solve_arpack(L, B, k, s, backend, seed, analysis)
            else:
                lam, X, used, t_fac, t_sol = _solve_lanczos(L, B, k, s, backend, seed, tol, block, analysis)
    t0 = time.perf_counter()
    with parallel.blas_one_thread():
        lam, X, res = _finish(lam, X, L, B, B_in, perm, method)
    t_sol += t_perm + time.perf_counter() - t0
    return lam, X, used, s, res, {"factorize": t_fac, "solve": t_sol, "cache": False}


def _finish(lam, X, L, B, B_in, perm, method):
    """Eigenpairs of a solver (in the numbering of ``L``, ``B``: ``perm`` of ``B_in``'s) sorted,
    checked, B-orthonormal, numbered back, with fixed signs and canonical bases: ``(λ, X, residuals)``."""
    order = np.argsort(lam, kind="stable")
    if np.any(order != np.arange(len(lam))):
        lam, X = lam[order], X[:, order]
    if not (np.all(np.isfinite(lam)) and np.all(np.isfinite(X))):
        raise SolverError("the eigensolver returned non-finite values")
    if method != "lanczos":  # its Rayleigh-Ritz already made X B-orthonormal
        X = _b_orthonormalize(X, B)
    lam = np.maximum(lam, 0.0)
    res = residuals(L, B, lam, X)
    if perm is not None:
        X = _unpermuted(X, perm)
    X = _fix_signs(X)  # in the caller's numbering: "first entry on ties" is well defined there
    # after the signs: a multiple eigenvalue's canonical basis has its own signs (the polar factor
    # is unique), where "largest entry" ties to rounding on a symmetric mesh
    X = _canonical_bases(lam, X, B_in, weyl_gap(B_in))
    return lam, X, res
