"""Sparse Cholesky factorizations behind one interface: CHOLMOD (scikit-sparse) -> cholespy -> SuperLU.

``factorize(A)`` returns a :class:`Factor` whose ``solve`` accepts one right-hand side ``(n,)`` or
many ``(n, c)``. With ``backend="auto"`` the first backend that is installed and succeeds is used;
each fallback is logged as a warning naming the reason, and the factor says which backend it is.

* ``"cholmod"``: scikit-sparse's CHOLMOD (system SuiteSparse). Simplicial LDLᵀ by default, which
  on Debian's reference-BLAS build solves 1.6-2.5x faster than supernodal.
* ``"cholespy"``: the pip wheel of cholespy (CHOLMOD bundled), for machines without
  ``libsuitesparse-dev``.
* ``"superlu"``: scipy's SuperLU (always there; an LU, slower and more memory).
"""

from __future__ import annotations

import logging

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .errors import SolverError

__all__ = ["factorize", "Factor", "available_backends", "BACKENDS"]

log = logging.getLogger("o3dheat")

BACKENDS = ("cholmod", "cholespy", "superlu")
_WARNED = set()
ORDERING = "default"  # CHOLMOD tries AMD, then METIS when the fill is high: best or near-best on meshes


def available_backends():
    """Names of the factorization backends importable here, in order of preference.

    Returns
    -------
    list of str

    Examples
    --------
    >>> import o3dheat.linalg as la
    >>> "superlu" in la.available_backends()
    True
    """
    out = []
    try:
        import sksparse.cholmod  # noqa: F401
        out.append("cholmod")
    except Exception:  # ImportError, or a broken shared library
        pass
    try:
        import cholespy  # noqa: F401
        out.append("cholespy")
    except Exception:
        pass
    out.append("superlu")
    return out


class Factor:
    """A factorization of a sparse symmetric positive definite matrix ``A``.

    Attributes
    ----------
    backend : str
        "cholmod", "cholespy" or "superlu".
    shape : tuple
    """

    def __init__(self, backend, solve, shape):
        self.backend = backend
        self._solve = solve
        self.shape = shape

    def solve(self, b):
        """Solve ``A x = b``.

        Parameters
        ----------
        b : (n,) or (n, c) float64 array_like

        Returns
        -------
        x : ndarray of the same shape as ``b``
        """
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.shape[0]:
            raise SolverError(f"right-hand side has {b.shape[0]} rows, the matrix {self.shape[0]}")
        x = self._solve(b)
        if not np.all(np.isfinite(x)):
            raise SolverError(f"the {self.backend} solve produced non-finite values: the matrix is "
                              "singular or badly conditioned")
        return x

    __call__ = solve


def _cholmod(A, mode):
    from sksparse.cholmod import cholesky

    A = sp.csc_matrix(A)
    try:
        f = cholesky(A, mode=mode, ordering_method=ORDERING)
    except Exception:  # a CHOLMOD built without METIS
        f = cholesky(A, mode=mode)
    return f.solve_A


def _cholespy(A):
    from cholespy import CholeskySolverD, MatrixType

    A = sp.csr_matrix(A)  # cholespy wants CSR (its CSC path mis-reads indices)
    n = A.shape[0]
    s = CholeskySolverD(n, A.indptr.astype(np.int32), A.indices.astype(np.int32),
                        np.ascontiguousarray(A.data, dtype=np.float64), MatrixType.CSR)

    def solve(b):
        b = np.ascontiguousarray(b)
        x = np.zeros_like(b)
        s.solve(b, x)
        return x

    # cholespy does not report a failed factorization: probe it once
    probe = solve(np.ones(n))
    if not np.all(np.isfinite(probe)) or not np.allclose(A @ probe, 1.0, rtol=1e-6, atol=1e-6 * abs(A).max()):
        raise SolverError("cholespy factorization failed (matrix not positive definite?)")
    return solve


def _superlu(A):
    lu = spla.splu(sp.csc_matrix(A))
    return lu.solve


def factorize(A, backend="auto", mode="simplicial"):
    """Factorize a sparse symmetric positive definite matrix once, for many solves.

    Parameters
    ----------
    A : (n, n) scipy.sparse matrix
        Symmetric positive definite (for example ``L - sigma B`` with ``sigma < 0``).
    backend : {"auto", "cholmod", "cholespy", "superlu"}
        "auto" tries them in that order and logs a warning at each fallback.
    mode : {"simplicial", "supernodal", "auto"}
        CHOLMOD's factorization mode (ignored by the other backends).

    Returns
    -------
    Factor

    Raises
    ------
    SolverError
        The requested backend is missing or every backend failed.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, o3dheat.linalg as la
    >>> A = sp.diags([2.0, 3.0, 4.0]).tocsc()
    >>> la.factorize(A).solve(np.array([2.0, 3.0, 4.0])).round(12).tolist()
    [1.0, 1.0, 1.0]
    """
    if backend == "auto":
        order = list(BACKENDS)
    elif backend in BACKENDS:
        order = [backend]
    else:
        raise SolverError(f"unknown backend {backend!r}: use 'auto' or one of {BACKENDS}")
    A = sp.csc_matrix(A, dtype=np.float64)
    errors = []
    for name in order:
        try:
            if name == "cholmod":
                solve = _cholmod(A, mode)
            elif name == "cholespy":
                solve = _cholespy(A)
            else:
                solve = _superlu(A)
        except Exception as e:  # ImportError or a failed factorization
            errors.append(f"{name}: {type(e).__name__}: {e}")
            if backend == "auto" and name != order[-1]:
                reason = f"{type(e).__name__}: {e}"
                # each distinct reason is a warning once per process, then logged at INFO
                level = logging.INFO if (name, reason) in _WARNED else logging.WARNING
                _WARNED.add((name, reason))
                log.log(level, "factorization backend %s unavailable or failed (%s); falling back", name, reason)
            continue
        return Factor(name, solve, A.shape)
    raise SolverError("could not factorize the matrix: " + "; ".join(errors))
