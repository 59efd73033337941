"""Block shift-invert Lanczos for the smallest eigenpairs of a symmetric definite pencil (L, B): :func:`block_lanczos`.

Entry points: :func:`block_lanczos` (from a solver of ``L − σ B``), :func:`rayleigh_ritz`.

Notes
-----
The Krylov space is built for ``S = (L − σ B)^{-1} B``, which is self-adjoint in the B-inner
product and maps the smallest eigenvalues λ of ``L x = λ B x`` to the largest ``ν = 1/(λ − σ)``.
Design choices, each measured on 200k-vertex meshes (see ``scripts/bench_spectrum.py``):

* blocks of ``b`` vectors are solved together (one multi-right-hand-side solve on the factor),
  and orthogonalized with BLAS-3 products instead of ARPACK's vector-by-vector BLAS-2 work;
* semi-orthogonality (Simon 1984): each new block is orthogonalized against the last two blocks,
  then its coefficients against the whole basis are measured in one pass; only when one exceeds
  ``sqrt(eps)`` are they subtracted, and then only those above ``eps^(3/4)`` (partial
  re-orthogonalization: about half the basis; small coefficients need no second pass).
  The products with B of the last two blocks are kept, so a step costs one solve, one sparse
  product with B and one pass over the basis (two of each when re-orthogonalizing);
* a thick restart on the best Ritz vectors bounds the basis at ``max(2k, k + 4b)`` vectors; the
  leading converged Ritz vectors are locked there (out of T and of later rotations: 40-80% of
  the restart's GEMM saved), still orthogonalized against;
* convergence per Ritz pair from the Lanczos residual ``ρ = ‖R_m z_last‖_B <= tol |ν|`` (free:
  no operator application), which needs no gap and so holds for multiple eigenvalues too;
* final eigenvalues are exact Rayleigh quotients: a Rayleigh-Ritz of (L, B) in the span of the
  Ritz vectors, which also makes them B-orthonormal to rounding;
* the passes over the basis, the sparse products and the restarts run on o3dheat's threads by
  blocks of rows (:mod:`o3dheat.parallel`), BLAS pinned to one thread meanwhile; sums over the
  rows are taken block by block in a fixed order, so results do not depend on the thread count.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.typing import ArrayLike

from o3dheat import parallel
from o3dheat.errors import ConvergenceError, MeshError

__all__ = ["block_lanczos", "rayleigh_ritz"]

_SEMI = np.sqrt(np.finfo(float).eps)
_ETA = np.finfo(float).eps ** 0.75


def _runs(idx, gap=8):
    """Sorted indices as half-open ranges ``(a, z)``, merging runs less than ``gap`` apart (one
    BLAS call per range; the few columns in between get a harmless tiny correction)."""
    if len(idx) == 0:
        return []
    cut = np.flatnonzero(np.diff(idx) > gap) + 1
    starts = np.concatenate([[idx[0]], idx[cut]])
    ends = np.concatenate([idx[cut - 1], [idx[-1]]]) + 1
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def _b_orthonormalize_block(W, rows, rng, BW=None, out=None):
    """B-orthonormalize the columns of W (n, b): returns Q, R, BQ with W = Q R, Qᵀ B Q = I.

    ``rows`` is a :class:`_Rows` of B. ``BW`` (= B W), when given, saves the sparse product;
    dependent columns are replaced by fresh random ones (their R rows are then 0). ``out``, a
    pair of (n, b) arrays other than W and BW, receives Q and BQ (no fresh memory to fault in)."""
    for _ in range(3):
        if BW is None:
            BW = rows.spmul(0, W)
        G = rows.inner(W, BW)
        G = (G + G.T) / 2
        try:
            R = np.linalg.cholesky(G).T  # upper triangular
            if np.min(np.diag(R)) > 1e-10 * np.max(np.diag(R)):
                Rinv = sla.lapack.dtrtri(R)[0]  # b x b: LAPACK directly (solve_triangular costs ms)
                q, bq = out if out is not None else (None, None)
                return rows.dot(W, Rinv, out=q), R, rows.dot(BW, Rinv, out=bq)
        except np.linalg.LinAlgError:
            pass
        w, U = np.linalg.eigh(G)
        keep = w > 1e-12 * max(w.max(), 1e-300)
        W = np.concatenate([W @ (U[:, keep] / np.sqrt(w[keep])),
                            rng.standard_normal((W.shape[0], int((~keep).sum())))], 1)
        BW = None
    raise ConvergenceError("could not build a B-orthonormal block (breakdown of the Lanczos basis)")


def _rotate(V, m, Z, p, rows=None):
    """In place, ``V[:, :p] = V[:, :m] @ Z[:, :p]``, by row chunks (no n x p temporary), the
    chunks shared out among threads. The default chunk keeps each thread's temporary near 2 MB
    (16384-row chunks made 20 MB ones: on a 20k-vertex mesh, 30% of the eigensolve's peak)."""
    rows = rows or max(256, (1 << 18) // max(p, 1))
    Zp = np.ascontiguousarray(Z[:, :p])
    parallel.run(lambda a, z: V.__setitem__((slice(a, z), slice(0, p)), V[a:z, :m] @ Zp),
                 parallel.row_parts(V.shape[0], rows))


def _sub_bv(BY, BV, C, rows):
    """In place, ``BY -= [B V_older, B V_newer] @ C`` for the last ``len(C)`` (b or 2b) basis
    vectors (two products: no copy of the cached blocks into one array)."""
    b = BV[1].shape[1]
    if len(C) > b:
        rows.sub(BY, BV[0], C[:b])
    rows.sub(BY, BV[1], C[len(C) - b:])


def _row_block(M, a, z):
    """Rows ``a:z`` of the CSR matrix M as a CSR matrix whose data and indices are views of M's."""
    p = M.indptr[a:z + 1]
    block = sp.csr_matrix((z - a, M.shape[1]), dtype=M.dtype)
    # set, not passed to the constructor: scipy copies a view smaller than half of its base
    block.data, block.indices, block.indptr = M.data[p[0]:p[-1]], M.indices[p[0]:p[-1]], p - p[0]
    return block


class _Rows:
    """Row-parallel kernels over the n rows of the basis (:func:`o3dheat.parallel.run` on fixed
    parts of at most ``CHUNK`` rows, which depend on n only; the reductions add the parts in order: thread-count independent)."""

    def __init__(self, *mats):
        self.n = mats[0].shape[0]
        self.parts = parallel.row_parts(self.n)
        # row blocks of the sparse matrices (CSR), one per part, sharing the matrix's arrays (no
        # copy: at a million vertices a copy of B is 84 MB): the products with them are then
        # shared out like the dense passes
        self.blocks = [[_row_block(M, a, z) for a, z in self.parts] if len(self.parts) > 1 else [M]
                       for M in mats]

    def inner(self, X, Y):
        """``X.T @ Y``."""
        if len(self.parts) == 1:
            return X.T @ Y
        out = parallel.run(lambda a, z: X[a:z].T @ Y[a:z], self.parts)
        for part in out[1:]:
            out[0] += part
        return out[0]

    def sub(self, Y, X, C):
        """In place, ``Y -= X @ C``."""
        if len(self.parts) == 1:
            Y -= X @ C
            return
        parallel.run(lambda a, z: np.subtract(Y[a:z], X[a:z] @ C, out=Y[a:z]), self.parts)

    def dot(self, X, C, out=None):
        """``X @ C`` (into ``out``, a C-ordered array not overlapping X, or a new one)."""
        if out is None:
            out = np.empty((X.shape[0], C.shape[1]))
        if len(self.parts) == 1:
            return np.matmul(X, C, out=out)
        parallel.run(lambda a, z: np.matmul(X[a:z], C, out=out[a:z]), self.parts)
        return out

    def spmul(self, i, Y, out=None):
        """``M_i @ Y`` for the i-th sparse matrix given at construction (into ``out``, an array
        not overlapping Y, or a new one)."""
        blocks = self.blocks[i]
        if len(blocks) == 1:
            if out is None:
                return blocks[0] @ Y
            out[...] = blocks[0] @ Y
            return out
        if out is None:
            out = np.empty((self.n, Y.shape[1]))
        parallel.run(lambda j, a, z: out.__setitem__(slice(a, z), blocks[j] @ Y),
                     [(j, a, z) for j, (a, z) in enumerate(self.parts)])
        return out

    def copy(self, dst, src):
        """``dst[...] = src`` (first touches of fresh memory are slow: share them out)."""
        if len(self.parts) == 1:
            dst[...] = src
            return
        parallel.run(lambda a, z: dst.__setitem__(slice(a, z), src[a:z]), self.parts)


def block_lanczos(L: sp.spmatrix, B: sp.spmatrix, solve: Callable, k: int, sigma: float, block: int = 8,
                  tol: float = 1e-8, max_basis: int | None = None, max_restarts: int = 100, seed: int = 0,
                  refine: bool = True, start: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Smallest k eigenpairs of ``L x = λ B x`` by block shift-invert Lanczos.

    Parameters
    ----------
    L, B : (n, n) scipy.sparse matrices
        Symmetric; ``B`` positive definite, ``L − σ B`` positive definite.
    solve : callable
        ``solve(Y)`` returns ``(L − σ B)^{-1} Y`` for ``Y`` of shape ``(n, b)``. It may return
        the same array every time (no solution is used after the next call).
    k : int
        Number of eigenpairs, ``k < n``.
    sigma : float
        The shift, below the smallest eigenvalue.
    block : int
        Block size ``b``.
    tol : float
        Convergence when every wanted Ritz pair has ``‖S y − ν y‖_B <= tol |ν|`` (the Lanczos
        residual). Eigenvectors are then accurate to about ``tol`` over the relative gap, and
        eigenvalues to about ``tol²`` relative (they are Rayleigh quotients).
    max_basis : int, optional
        Basis size before a thick restart; default ``max(2k, k + 4b)`` (capped at n).
    max_restarts : int
        Thick restarts allowed before a ConvergenceError.
    seed : int
        Seed of the random start block.
    refine : bool
        Finish with :func:`rayleigh_ritz` (exact Rayleigh quotients, B-orthonormal vectors).
        False returns the Lanczos Ritz values and the Ritz vectors in the basis' own memory, shrunk
        to k columns without a copy, so that a caller can free the factorization and then refine
        in place (``rayleigh_ritz(..., overwrite=True)``): the peak memory stays that of the basis.
    start : (n, b) array_like, optional
        The start block instead of a random one (``b`` columns, the block size), for example
        random combinations of approximate eigenvectors (a warm start: a resampled mesh's
        spectrum from its reference's eigenvectors transferred onto it). Measured on 20k-vertex
        resamplings, k = 100: 7-10% fewer solves, less than the transfer costs
        (``scripts/bench_warm_start.py``).

    Returns
    -------
    lam : (k,) ndarray
        Ascending eigenvalues (Rayleigh quotients).
    X : (n, k) ndarray
        B-orthonormal eigenvectors.
    info : dict
        ``solves`` (right-hand sides solved), ``restarts``, ``basis`` (largest basis size),
        ``block``, ``full_reorth`` (steps that re-orthogonalized against older blocks), ``steps``
        and ``locked`` (Ritz pairs locked at restarts).

    Raises
    ------
    ConvergenceError
        No convergence within ``max_restarts`` restarts, or a breakdown.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> from o3dheat.spectral.linalg import factorize
    >>> L = sp.diags(np.arange(200.0)).tocsc(); B = sp.identity(200, format="csc")
    >>> lam, X, info = block_lanczos(L, B, factorize(L + 0.5 * B).solve, 5, -0.5)
    >>> lam.round(8).tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0]
    """
    with parallel.blas_one_thread():  # our own threads share out the big loops
        return _block_lanczos(L, B, solve, k, sigma, block, tol, max_basis, max_restarts, seed, refine, start)


def _block_lanczos(L, B, solve, k, sigma, block, tol, max_basis, max_restarts, seed, refine, start=None):
    n = L.shape[0]
    b, m_max = _basis_size(n, k, block, max_basis)
    rng = np.random.default_rng(seed)
    VT, T, rows, W, BW = _setup(B, n, b, m_max, start, rng)
    V = VT.T
    BV = [None, BW]  # B times the last two blocks (older, newer): saves sparse products
    # the (n, b) arrays of every step live in buffers made once: at a million vertices a fresh
    # 64 MB array is a fresh mmap whose pages fault in one by one (seconds of system time). B W
    # rotates through three (the newest and the two kept in BV), B Y and W through one each.
    by_buf, w_buf = np.empty((n, b)), np.empty((n, b))
    bw_ring = [np.empty((n, b)) for _ in range(3)]
    m, turn, after_restart = 0, 0, False
    solves = restarts = biggest = steps = full = 0
    c, locked_nu = 0, np.zeros(0)  # locked (converged) Ritz vectors: V[:, :c], values locked_nu
    while True:
        rows.copy(V[:, m:m + b], W)
        m += b
        steps += 1
        biggest = max(biggest, m)
        Y = solve(BW)
        solves += b
        BY = rows.spmul(0, Y, out=by_buf)
        # local orthogonalization: the last two blocks (all of the kept part right after a restart)
        lo = 0 if after_restart else max(0, m - 2 * b)
        Vl = V[:, lo:m]
        Cl = rows.inner(Vl, BY)
        rows.sub(Y, Vl, Cl)
        if after_restart:
            BY = rows.spmul(0, Y, out=by_buf)
        else:
            BV = [BV[1], BW]
            _sub_bv(BY, BV, Cl, rows)
        # measure the loss of orthogonality against the whole basis (one pass); restore it with
        # one update when it exceeds sqrt(eps) (the coefficients are then small: no second pass)
        C = rows.inner(V[:, :m], BY)
        ynorm = np.sqrt(np.maximum(np.einsum("ij,ij->j", Y, BY), 1e-300))
        rel = np.max(np.abs(C[:lo]) / ynorm, axis=1, initial=0.0)
        if after_restart or np.max(rel, initial=0.0) > _SEMI:
            full += 1
            BY = _reorthogonalize(Y, V, Vl, C, rel, lo, m, rows, by_buf)
        else:
            rows.sub(Y, Vl, C[lo:m])
            _sub_bv(BY, BV, C[lo:m], rows)
        if after_restart:  # the new block is not a neighbour of the kept part: refill the cache
            BV = [None, BW]
        after_restart = False
        T[lo:m, m - b:m] = Cl + C[lo:m]
        turn = (turn + 1) % 3
        W, R, BW = _b_orthonormalize_block(Y, rows, rng, BY, out=(w_buf, bw_ring[turn]))
        done_filling = m + b > m_max
        if m < k + b and not done_filling:
            continue
        nu, Z, rho = _ritz_pairs(T, R, c, m, b)
        if m >= k and bool(np.all(rho[:k - c] <= tol * np.abs(nu[:k - c]))):
            break
        if done_filling:
            if restarts >= max_restarts:
                raise ConvergenceError(f"block Lanczos did not converge after {restarts} restarts")
            restarts += 1
            c, m, locked_nu = _restart(V, T, Z, nu, rho, c, m, b, k, m_max, tol, locked_nu)
            after_restart = True
    del Vl, BV, V, W, BW, Y, BY, by_buf, w_buf, bw_ring  # before the refinement: peak memory
    info = {"solves": solves, "restarts": restarts, "basis": biggest, "block": b,
            "full_reorth": full, "steps": steps, "locked": c}
    return _ritz_vectors(L, B, VT, Z, np.concatenate([locked_nu, nu[:k - c]]), c, m, k, sigma, refine, info)


def _basis_size(n, k, block, max_basis):
    """``(b, m_max)``: the block size and the largest basis (before a restart) for k eigenpairs of n."""
    b = int(max(1, min(block, n // 4 if n >= 8 else 1)))
    m_max = int(min(n - b, max_basis or max(2 * k, k + 4 * b)))
    m_max = max(m_max, min(n - b, k + max(2 * b, 8, k // 4)))
    if m_max < k:
        raise ConvergenceError(f"the problem is too small for Lanczos (n={n}, k={k}): use the dense solver")
    return b, m_max


def _setup(B, n, b, m_max, start, rng):
    """``(VT, T, rows, W, B W)``: the basis (transposed: its first k rows can be kept in place), the
    projected matrix, B's rows, and the B-orthonormal start block."""
    VT = np.empty((m_max + b, n))
    T = np.zeros((m_max + b, m_max + b))
    rows = _Rows(sp.csr_matrix(B))
    W, _, BW = _b_orthonormalize_block(_start_block(start, n, b, rng), rows, rng)
    return VT, T, rows, W, BW


def _start_block(start, n, b, rng):
    """The start block: ``start``, checked, or ``b`` random vectors."""
    if start is not None:
        start = np.array(start, dtype=np.float64, order="C", ndmin=2)
        if start.shape != (n, b) or not np.all(np.isfinite(start)):
            raise MeshError(f"the start block must be a finite ({n}, {b}) array, got shape {start.shape}")
    return rng.standard_normal((n, b)) if start is None else start


def _reorthogonalize(Y, V, Vl, C, rel, lo, m, rows, by_buf):
    """Partial re-orthogonalization (Simon 1984) of Y: only against the basis vectors whose
    coefficient exceeds eps^(3/4), in contiguous runs, plus the local blocks; returns B Y."""
    for a, z in _runs(np.flatnonzero(rel > _ETA)):
        rows.sub(Y, V[:, a:z], C[a:z])
    rows.sub(Y, Vl, C[lo:m])
    return rows.spmul(0, Y, out=by_buf)


def _ritz_pairs(T, R, c, m, b):
    """``(ν, Z, ρ)``: the Ritz pairs of the active part of T (the first c basis vectors are locked
    Ritz vectors), largest ν first (smallest λ), and their residual norms."""
    Ts = np.triu(T[c:m, c:m]) + np.triu(T[c:m, c:m], 1).T
    nu, Z = np.linalg.eigh(Ts)
    nu, Z = nu[::-1], Z[:, ::-1]  # largest ν first = smallest λ
    rho = np.linalg.norm(R @ Z[m - b - c:m - c, :], axis=0)
    return nu, Z, rho


def _restart(V, T, Z, nu, rho, c, m, b, k, m_max, tol, locked_nu):
    """A thick restart in place: the basis rotated to its leading Ritz vectors, T made diagonal;
    returns ``(c, m, locked_nu)``, the locked count, the kept basis size and the locked values."""
    p = min(m - b, max(k + (m_max - k) // 2, k + b), m_max - b)
    # lock the leading converged Ritz pairs: they leave T and the rotations (their
    # coupling to later blocks is below tol |ν|, the final Rayleigh-Ritz sees them all)
    # (only pairs 100x below the tolerance: they stay more accurate than the rest needs)
    firm = rho <= 0.01 * tol * np.abs(nu)
    lock = min(int(np.argmin(firm)) if not firm.all() else len(firm), k - 1 - c)
    _rotate(V[:, c:], m - c, Z, p - c)
    T[:] = 0
    locked_nu = np.concatenate([locked_nu, nu[:lock]])
    T[:p, :p] = np.diag(np.concatenate([locked_nu, nu[lock:p - c]]))
    return c + lock, p, locked_nu


def _ritz_vectors(L, B, VT, Z, nu, c, m, k, sigma, refine, info):
    """The result: the Ritz vectors rotated into the first k rows of the basis (the rest freed),
    refined by Rayleigh-Ritz when asked."""
    _rotate(VT.T[:, c:], m - c, Z, k - c)  # the Ritz vectors, in the first k columns
    VT.resize((k, VT.shape[1]), refcheck=False)  # the Ritz vectors stay, the rest of the basis is freed
    V = VT.T
    if not refine:
        return sigma + 1.0 / nu[:k], V[:, :k], info
    lam, X = rayleigh_ritz(L, B, V, overwrite=True)
    return lam, X, info


def rayleigh_ritz(L: sp.spmatrix, B: sp.spmatrix, X: np.ndarray, chunk: int = 32, overwrite: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Rayleigh-Ritz of the pencil (L, B) in the span of the columns of X.

    Parameters
    ----------
    L, B : (n, n) scipy.sparse matrices
        The pencil: symmetric, ``B`` positive definite.
    X : (n, k) ndarray
        A basis of the subspace (need not be B-orthonormal).
    chunk : int
        Columns per sparse product (bounds the temporaries to n x chunk).
    overwrite : bool
        Write the Ritz vectors into X (by row chunks: no second n x k array) and return it.

    Returns
    -------
    lam : (k,) ndarray
        Ascending Ritz values (Rayleigh quotients).
    Y : (n, k) ndarray
        B-orthonormal Ritz vectors (a new array, or X itself with ``overwrite``).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp
    >>> L = sp.diags([1.0, 2.0, 3.0]); B = sp.identity(3)
    >>> rayleigh_ritz(L, B, np.eye(3)[:, :2])[0].tolist()
    [1.0, 2.0]
    """
    k = X.shape[1]
    A = np.empty((k, k))
    M = np.empty((k, k))
    rows = _Rows(sp.csr_matrix(L), sp.csr_matrix(B))
    with parallel.blas_one_thread():
        for c in range(0, k, chunk):
            Xc = np.ascontiguousarray(X[:, c:c + chunk])  # sparse products are 2-3x faster on C order
            A[:, c:c + chunk] = rows.inner(X, rows.spmul(0, Xc))
            M[:, c:c + chunk] = rows.inner(X, rows.spmul(1, Xc))
        lam, U = sla.eigh((A + A.T) / 2, (M + M.T) / 2)
        if overwrite:
            _rotate(X, k, U, k)
            return lam, X
        return lam, rows.dot(X, U)
