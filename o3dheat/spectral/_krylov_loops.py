"""The compiled loops of one Lanczos step of :mod:`o3dheat.spectral.krylov`: :func:`rows` runs them.

Each is compiled by :func:`o3dheat._jit.compiled` and runs over a range of rows ``[a, z)`` of
C-ordered ``(n, c)`` arrays, updating in place (no fresh memory per step: on virtual machines a
first touch of fresh pages costs about 1 s per GB).

Sums over the rows come back per range: :func:`rows` adds them in the order of
:func:`o3dheat.parallel.row_parts`, which depends on ``n`` only, so results do not depend on the
number of threads.
"""

from __future__ import annotations

import numpy as np

from o3dheat import parallel
from o3dheat._jit import compiled

__all__ = ["rows", "update", "subtract", "spmm", "part_sums", "project", "scale", "add_outer", "transpose_into", "assemble"]


def rows(fn, n, *args):
    """``fn(*args, a, z)`` over the row ranges of ``n`` rows on o3dheat's threads; the partial
    results (arrays or None) added in order.

    Examples
    --------
    >>> import numpy as np
    >>> from o3dheat.spectral._krylov_loops import rows, part_sums
    >>> X = np.ones((5, 2))
    >>> rows(part_sums, 5, X, np.zeros(5, np.int64), 1).tolist()
    [[5.0, 5.0]]
    """
    k = compiled(fn)
    parts = parallel.run(lambda a, z: k(*args, a, z), parallel.row_parts(n))
    if parts[0] is None:
        return None
    total = parts[0].copy()
    for p in parts[1:]:
        total += p
    return total


def update(Z, Vp, WV, bp, a, z):
    """``Z −= bp Vp`` by column; returns the partial ``Σ WV ∘ Z`` (the Lanczos α)."""
    c = Z.shape[1]
    acc = np.zeros(c)
    for i in range(a, z):
        for k in range(c):
            v = Z[i, k] - bp[k] * Vp[i, k]
            Z[i, k] = v
            acc[k] += WV[i, k] * v
    return acc


def subtract(Z, V, alpha, a, z):
    """``Z −= alpha V`` by column."""
    c = Z.shape[1]
    for i in range(a, z):
        for k in range(c):
            Z[i, k] -= alpha[k] * V[i, k]


def spmm(indptr, indices, data, Z, out, labels, parts, a, z):
    """Rows ``a..z`` of ``out = M Z``, ``M`` in CSR (each row's sum in the order of its entries);
    returns the partial sums of ``out`` over each part (parts, c), as :func:`part_sums`."""
    c = Z.shape[1]
    sums = np.zeros((parts, c))
    if c == 1:
        for i in range(a, z):
            s = 0.0
            for p in range(indptr[i], indptr[i + 1]):
                s += data[p] * Z[indices[p], 0]
            out[i, 0] = s
            if labels[i] >= 0:
                sums[labels[i], 0] += s
        return sums
    acc = np.zeros(c)
    for i in range(a, z):
        for k in range(c):
            acc[k] = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            w = data[p]
            for k in range(c):
                acc[k] += w * Z[j, k]
        g = labels[i]
        for k in range(c):
            out[i, k] = acc[k]
            if g >= 0:
                sums[g, k] += acc[k]
    return sums


def part_sums(X, labels, parts, a, z):
    """The partial sums of the rows of ``X`` over each part (parts, c); rows labelled -1 (in no
    part with a null vector) are left out."""
    c = X.shape[1]
    acc = np.zeros((parts, c))
    for i in range(a, z):
        p = labels[i]
        if p >= 0:
            for k in range(c):
                acc[p, k] += X[i, k]
    return acc


def project(Z, WZ, d, labels, mu, a, z):
    """``Z −= mu[part]`` and ``WZ −= d mu[part]`` (the W-projection on each part's constants out);
    returns the partial ``Σ Z ∘ WZ`` (β², after the projection)."""
    c = Z.shape[1]
    acc = np.zeros(c)
    for i in range(a, z):
        p = labels[i]
        for k in range(c):
            x, y = Z[i, k], WZ[i, k]
            if p >= 0:
                x -= mu[p, k]
                y -= d[i] * mu[p, k]
                Z[i, k] = x
                WZ[i, k] = y
            acc[k] += x * y
    return acc


def scale(Z, WZ, inv, V, WV, a, z):
    """``V = Z inv`` and ``WV = WZ inv`` by column."""
    c = Z.shape[1]
    for i in range(a, z):
        for k in range(c):
            V[i, k] = Z[i, k] * inv[k]
            WV[i, k] = WZ[i, k] * inv[k]


def add_outer(U, v, y, a, z):
    """Rows ``a..z`` of ``U += v yᵀ`` (U (n, T), any strides)."""
    T = y.shape[0]
    for i in range(a, z):
        vi = v[i]
        for t in range(T):
            U[i, t] += vi * y[t]


def transpose_into(V, out, a, z):
    """Rows ``a..z`` of ``out[k, i] = V[i, k]`` (out (c, n), any strides): one pass over V."""
    c = V.shape[1]
    for i in range(a, z):
        for k in range(c):
            out[k, i] = V[i, k]


def assemble(U, f0T, decay, blocks, pos, bfirst, bcount, coef, ncoef, a, z):
    """Rows ``a..z`` of the result ``U[i, j] = f0[i, j] decay + Σ_s v_s[i, j] coef[j, s]``: the
    stored Lanczos vectors ``v_s`` of each column ``j`` times its first ``ncoef[j]`` coefficients,
    vector ``bfirst[b] + s`` (``s < bcount[b]``) of column ``j`` being ``blocks[b][pos[b, j], s]``
    (``pos`` -1: not in that block). Summed over rows in runs of 2048 (contiguous, vectorized), each value in the
    order of the steps, whatever the threads."""
    c, T = U.shape[1], U.shape[2]
    R = 2048
    acc = np.empty((T, R))
    for r0 in range(a, z, R):
        m = min(R, z - r0)
        for j in range(c):
            fj = f0T[j, r0:r0 + m]
            for t in range(T):
                d = decay[t]
                at = acc[t]
                for i in range(m):
                    at[i] = fj[i] * d
            for b in range(len(blocks)):
                k = pos[b, j]
                if k < 0:
                    continue
                block = blocks[b]
                first = bfirst[b]
                for s in range(min(bcount[b], ncoef[j] - first)):
                    v = block[k, s, r0:r0 + m]
                    cs = coef[j, first + s]
                    for t in range(T):
                        ct = cs[t]
                        at = acc[t]
                        for i in range(m):
                            at[i] += ct * v[i]
            for i in range(m):
                ui = U[r0 + i, j]
                for t in range(T):
                    ui[t] = acc[t, i]
