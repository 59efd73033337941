"""The triangular solves of a simplicial LLᵀ factor on many right-hand sides at once, row by row.

Entry points: :func:`solve_rows` (``x = A⁻¹ b`` for ``(n, c)`` C-ordered ``b``, from the factor's
CSC arrays and permutation) and its compiled loops :func:`forward`, :func:`backward`,
:func:`gather`, :func:`scatter`, run by :mod:`o3dheat.spectral._cholmod` on CHOLMOD's own arrays
(no copy of the factor).

Why: a solve reads the factor twice and, for each of its entries, one row of the right-hand
sides at a row index the factor gives. CHOLMOD's solve works on column-major blocks of four
right-hand sides: every entry then costs a scattered access per group of four, and its cost
per column stops falling at four columns (measured at 1M rows: 0.45-0.6 of a single column per
column from 4 to 32 columns). Here the right-hand sides are row-major ``(n, c)``: each entry of
the factor updates one contiguous row of ``c`` values (vectorized), so the cost per column keeps
falling with ``c`` (0.24 of a single column at 32 columns on one thread, 0.17 on two, 0.13 at 64;
see ``docs/details/heatflow.md``). Columns are independent: each thread takes a contiguous range
of them, and every value is computed by the same operations in the same order whatever the
number of columns or threads, so results are bit-identical for any split.
"""

from __future__ import annotations

import numpy as np

from o3dheat import parallel
from o3dheat._jit import compiled

__all__ = ["solve_rows", "forward", "backward", "gather", "scatter"]


def forward(Lp, Li, Lx, Y):
    """``Y = L⁻¹ Y`` in place: ``L`` lower triangular in CSC (``Lp``, ``Li``, ``Lx``), its diagonal
    the first entry of each column; ``Y`` C-ordered ``(n, c)``."""
    n, c = Y.shape
    for j in range(n):
        yj = Y[j]
        d = Lx[Lp[j]]
        for k in range(c):
            yj[k] /= d
        for p in range(Lp[j] + 1, Lp[j + 1]):
            yi = Y[Li[p]]
            v = Lx[p]
            for k in range(c):
                yi[k] -= v * yj[k]


def backward(Lp, Li, Lx, Y):
    """``Y = L⁻ᵀ Y`` in place (``L`` as for :func:`forward`)."""
    n, c = Y.shape
    acc = np.empty(c)
    for jj in range(n):
        j = n - 1 - jj
        yj = Y[j]
        for k in range(c):
            acc[k] = yj[k]
        for p in range(Lp[j] + 1, Lp[j + 1]):
            yi = Y[Li[p]]
            v = Lx[p]
            for k in range(c):
                acc[k] -= v * yi[k]
        d = Lx[Lp[j]]
        for k in range(c):
            yj[k] = acc[k] / d


def gather(B, perm, Y, first, a, z):
    """Rows ``a..z`` of ``Y[i] = B[perm[i], first:first + c]`` (``Y`` (n, c))."""
    c = Y.shape[1]
    for i in range(a, z):
        src = B[perm[i]]
        dst = Y[i]
        for k in range(c):
            dst[k] = src[first + k]


def scatter(Y, perm, X, first, a, z):
    """Rows ``a..z`` of ``X[perm[i], first:first + c] = Y[i]``."""
    c = Y.shape[1]
    for i in range(a, z):
        src = Y[i]
        dst = X[perm[i]]
        for k in range(c):
            dst[first + k] = src[k]


def solve_rows(Lp, Li, Lx, perm, B, out, work, threads=None):
    """``out = A⁻¹ B`` from the factor ``A[perm][:, perm] = L Lᵀ``.

    Parameters
    ----------
    Lp, Li, Lx : ndarray
        ``L`` in CSC (int32 or int64 indices), lower triangular, the diagonal first in each column.
    perm : (n,) int ndarray
        The fill-reducing permutation (row ``i`` of the factored matrix is row ``perm[i]`` of A).
    B : (n, c) float64 C-ordered ndarray
        Right-hand sides.
    out : (n, c) float64 C-ordered ndarray
        The solution (may not overlap ``B``).
    work : list
        Holds the workspaces between calls (filled here: an ``(n, width)`` array per thread).
    threads : int, optional
        Threads (default :func:`o3dheat.parallel.get_threads`); each solves a contiguous range of
        columns.

    Returns
    -------
    ndarray
        ``out``.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral._substitution import solve_rows
    >>> Lp, Li, Lx = np.array([0, 2, 3]), np.array([0, 1, 1]), np.array([2.0, 1.0, 1.0])
    >>> A = np.array([[4.0, 2.0], [2.0, 2.0]])          # L Lᵀ, L = [[2, 0], [1, 1]]
    >>> B = A @ np.arange(6.0).reshape(2, 3)
    >>> solve_rows(Lp, Li, Lx, np.arange(2), B, np.empty((2, 3)), []).tolist()
    [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]
    """
    n, c = B.shape
    # each thread its own contiguous (n, width) array (a thread that read rows shared with another
    # would be slower), of at least 16 columns (narrower ones gain nothing from a second thread:
    # each pass over the factor is bound by its scattered row accesses)
    t = max(1, min(parallel.get_threads() if threads is None else threads, c // 16))
    cuts = [round(j * c / t) for j in range(t + 1)]
    widths = [cuts[j + 1] - cuts[j] for j in range(t)]
    if [w.shape for w in work] != [(n, k) for k in widths]:
        work[:] = [np.empty((n, k)) for k in widths]
    fwd, bwd, gat, sca = compiled(forward), compiled(backward), compiled(gather), compiled(scatter)

    def part(j):
        Y = work[j]
        gat(B, perm, Y, cuts[j], 0, n)
        fwd(Lp, Li, Lx, Y)
        bwd(Lp, Li, Lx, Y)
        sca(Y, perm, out, cuts[j], 0, n)

    parallel.run(part, [(j,) for j in range(t)], threads=t)
    return out
