"""Sparse Cholesky factorizations behind one interface: CHOLMOD (scikit-sparse) -> cholespy -> SuperLU.

Entry points: :func:`factorize` (a :class:`Factor`), :func:`analyze` (an :class:`Analysis` shared
by the factorizations of one pattern), :func:`available_backends`. The CHOLMOD binding is
:mod:`o3dheat.spectral._cholmod`; the memory checks made before factorizing are
:mod:`o3dheat.memory`.

Notes
-----
``factorize(A)`` returns a :class:`Factor` whose ``solve`` accepts one right-hand side ``(n,)`` or
many ``(n, c)``. With ``backend="auto"`` the first backend that is installed and succeeds is used;
each fallback is logged as a warning naming the reason, and the factor says which backend it is.

* ``"cholmod"``: CHOLMOD of the system SuiteSparse, the library scikit-sparse is built against.
  scikit-sparse's ``solve_A`` holds Python's GIL, so the columns of a block cannot be solved
  concurrently through it; o3dheat therefore calls the very library scikit-sparse loaded through
  ``ctypes`` (which releases the GIL) and solves the columns of a block on several threads
  (1.8-2x faster block solves on 2 cores, bit-identical results: each group of columns is solved
  alone). The factorization is supernodal from :data:`SUPERNODAL_MIN_N` rows (BLAS-3 on dense
  blocks: 2x faster at 1M rows even on the reference BLAS, 3.5x with OpenBLAS, which
  ``scripts/setup.sh`` installs), run with the BLAS on one thread so that the factor does not
  depend on the machine's core count, then converted to a simplicial LLᵀ for the threaded solves
  (faster per column than the supernodal solve); smaller matrices get a simplicial LDLᵀ directly.
  When the binding is not possible, or fails at any point but for a matrix that is not positive
  definite or a lack of memory (no ``libcholmod`` found, an unexpected struct layout, a failed
  self-check or ``cholmod_start``, a failed solve), scikit-sparse's own ``cholesky`` takes over,
  single-threaded, with a warning naming the reason.
* ``"cholespy"``: the pip wheel of cholespy (CHOLMOD bundled), for machines without
  ``libsuitesparse-dev``.
* ``"superlu"``: scipy's SuperLU (always there; an LU, slower and more memory).

The number of threads that solve the columns of a block is :func:`o3dheat.parallel.get_threads`.
"""

from __future__ import annotations

import contextlib
import logging

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import ArrayLike

from o3dheat import parallel
from o3dheat.errors import MeshError, OutOfMemory, SolverError
from o3dheat.memory import check_memory

from ._cholmod import ORDERINGS, Analysis, CholmodFactor, NotPositiveDefinite, TooLarge, library

__all__ = ["BACKENDS", "Factor", "available_backends", "factorize", "analyze", "Analysis"]

log = logging.getLogger("o3dheat")

#: the factorization backends, in the order ``backend="auto"`` tries them
BACKENDS = ("cholmod", "cholespy", "superlu")
_WARNED = set()
ORDERING = "amd"  # as the binding (o3dheat.spectral._cholmod): METIS costs more than it saves on meshes
MODES = ("auto", "simplicial", "supernodal")
SUPERNODAL_MIN_N = 100_000  # "auto": supernodal from here (measured in scripts/bench_spectrum.py)


def available_backends() -> list[str]:
    """Names of the factorization backends importable here, in order of preference.

    Returns
    -------
    list of str

    Examples
    --------
    >>> import o3dheat.spectral.linalg as la
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
    nbytes : int
        Memory held by the factor (an estimate; 0 where the backend does not tell).

    Examples
    --------
    Made by :func:`factorize`:

    >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> A = sp.diags([2.0, 3.0, 4.0]).tocsc()
    >>> f = la.factorize(A, backend="superlu")
    >>> f.backend, f.shape
    ('superlu', (3, 3))
    """

    def __init__(self, backend, solve, shape):
        self.backend = backend
        self._solve = solve
        self.shape = shape
        #: bytes the factor holds (an estimate; 0 where the backend does not tell)
        self.nbytes = int(getattr(solve, "nbytes", 0))

    def solve(self, b: ArrayLike, out: np.ndarray | None = None) -> np.ndarray:
        """Solve ``A x = b``.

        Parameters
        ----------
        b : (n,) or (n, c) float64 array_like
            Right-hand side(s), one row per row of ``A``.
        out : ndarray, optional
            A C-ordered float64 array of the shape of ``b`` (not overlapping it) to hold ``x``:
            repeated solves then reuse its memory.

        Returns
        -------
        x : ndarray of the same shape as ``b`` (``out`` when given)

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
        >>> f = la.factorize(sp.diags([2.0, 4.0, 8.0]).tocsc())
        >>> f.solve([2.0, 4.0, 8.0]).round(12).tolist()
        [1.0, 1.0, 1.0]
        >>> out = np.empty((3, 2))                       # several right-hand sides, into out
        >>> f.solve(np.ones((3, 2)), out=out) is out, out[:, 0].round(12).tolist()
        (True, [0.5, 0.25, 0.125])
        """
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.shape[0]:
            raise MeshError(f"right-hand side has {b.shape[0]} rows, the matrix {self.shape[0]}")
        if out is None:
            x = self._solve(b)
        else:
            if out.shape != b.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
                raise MeshError(f"out must be a C-ordered float64 array of shape {b.shape}")
            into = getattr(self._solve, "into", None)
            x = into(b, out) if into is not None else out
            if into is None:
                np.copyto(out, self._solve(b))
        if not np.all(np.isfinite(x)):
            raise SolverError(f"the {self.backend} solve produced non-finite values: the matrix is "
                              "singular or badly conditioned")
        return x

    __call__ = solve

    def release(self) -> None:
        """Give back the memory of the last solve's workspaces (they are made again by the next
        solve): CHOLMOD keeps about three ``(n, columns)`` arrays per thread between solves.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
        >>> f = la.factorize(sp.diags([4.0, 16.0]).tocsc())
        >>> f.release(); f.solve([4.0, 16.0]).tolist()
        [1.0, 1.0]
        """
        release = getattr(self._solve, "release", None)
        if release is not None:
            release()


def analyze(A: sp.spmatrix, mode: str = "auto", ordering: str = "auto") -> Analysis | None:
    """The symbolic analysis of ``A``'s pattern, for :func:`factorize` (``analysis=``) of any
    matrix with that pattern, with the factor's size, flops and memory counted before any numeric
    work; None where CHOLMOD's binding is not available (each factorization then analyses its own
    matrix). Runs without Python's GIL: it can overlap other work.

    A factor too large for CHOLMOD's 32-bit indices (more than 2³¹ entries) is analysed with its
    64-bit ones (``wide``); "too large" is never reported as "out of memory".

    Parameters
    ----------
    A : (n, n) scipy.sparse matrix
        Only its pattern is read.
    mode : {"auto", "simplicial", "supernodal"}
        As for :func:`factorize` (the factorizations must use the same).
    ordering : {"auto", "amd", "metis", "nesdis", "natural"}
        The fill-reducing ordering. "auto" (what :func:`factorize` uses): AMD, then METIS where
        AMD's own flop count says that METIS's longer ordering pays for itself (uniform meshes of
        about 1M vertices and more; not curvature-adaptive ones: ``docs/details/large.md``), the
        one of fewer flops kept; "natural" keeps the given order (for tests and measurements).

    Returns
    -------
    Analysis or None
        ``.lnz`` (factor entries), ``.flops``, ``.nbytes`` (the factorization's peak memory),
        ``.ordering`` (the one used), ``.wide``.

    Raises
    ------
    MeshError
        An unknown mode or ordering.
    OutOfMemory
        CHOLMOD ran out of memory analysing.
    SolverError
        The factor is too large even for CHOLMOD's 64-bit indices (``TooLarge``).

    Examples
    --------
    >>> import scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> a = la.analyze(sp.identity(3, format="csc"))
    >>> a is None or (a.n, a.lnz, a.wide)
    (3, 3, False)
    """
    mode = _auto_mode(mode, A.shape[0])
    if ordering not in ORDERINGS:
        raise MeshError(f"unknown ordering {ordering!r}: use one of {', '.join(map(repr, ORDERINGS))}")
    lib = library()
    if lib is None:
        return None
    try:
        return Analysis(lib, A, mode, ordering)
    except (OutOfMemory, TooLarge):
        raise
    except Exception as e:  # noqa: BLE001 - the binding failed: each factorization analyses itself
        log.info("CHOLMOD analysis unavailable (%s): each factorization analyses its own matrix", e)
        return None


def _auto_mode(mode, n):
    if mode not in MODES:
        raise MeshError(f"unknown mode {mode!r}: use one of {MODES}")
    if mode == "auto":
        return "supernodal" if n >= SUPERNODAL_MIN_N else "simplicial"
    return mode


def _cholmod(A, mode, analysis=None):
    lib = library()
    if lib is not None:
        try:
            return _BindingSolve(CholmodFactor(lib, A, mode, analysis), A, mode)
        except (OutOfMemory, NotPositiveDefinite, TooLarge):
            raise  # a property of the matrix or of the machine: scikit-sparse would fail alike
        except Exception as e:  # noqa: BLE001 - too big for the int32 interface, another layout...
            _warn_binding(e)
    return _sksparse(A, mode)


def _warn_binding(e):
    reason = f"{type(e).__name__}: {e}"
    level = logging.INFO if ("binding", reason) in _WARNED else logging.WARNING
    _WARNED.add(("binding", reason))
    log.log(level, "CHOLMOD through ctypes failed (%s): scikit-sparse's own solver instead (one thread)", reason)


class _BindingSolve:
    """``factor.solve`` through the binding, replaced for good by scikit-sparse's solver when a
    solve fails in it (the matrix is kept for that: about a tenth of the factor's memory). An
    object without reference cycles: the factor's memory goes back as soon as the last reference
    to it does (a closure that referred to itself kept every factor of a flow until Python's cycle
    collector ran: the first factor of a 4M-vertex flow stayed while the second was made)."""

    def __init__(self, factor, A, mode):
        self.factor, self.A, self.mode, self.fallback = factor, A, mode, None
        self.nbytes = getattr(factor, "nbytes", 0)

    def __call__(self, b, out=None):
        if self.fallback is None:
            try:
                return self.factor.solve(b, out=out)
            except (OutOfMemory, MemoryError):
                raise
            except Exception as e:  # noqa: BLE001 - any failure of the binding
                _warn_binding(e)
                self.fallback = _sksparse(self.A, self.mode)
        x = self.fallback(b)
        if out is None:
            return x
        np.copyto(out, x)
        return out

    def into(self, b, out):
        return self(b, out)

    def release(self):
        self.factor.release()


def _sksparse(A, mode):
    from sksparse.cholmod import CholmodOutOfMemoryError, CholmodTooLargeError, cholesky

    A = sp.csc_matrix(A)
    try:
        with parallel.blas_one_thread() if mode == "supernodal" else contextlib.nullcontext():
            try:
                f = cholesky(A, mode=mode, ordering_method=ORDERING)
            except (CholmodOutOfMemoryError, CholmodTooLargeError):
                raise
            except Exception:  # a CHOLMOD built without METIS
                f = cholesky(A, mode=mode)
    except CholmodTooLargeError as e:
        raise TooLarge(f"the factor of the {A.shape[0]} x {A.shape[0]} matrix is too large for CHOLMOD ({e}): "
                       "use a smaller mesh") from e
    except CholmodOutOfMemoryError as e:
        raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {A.shape[0]} x {A.shape[0]} matrix ({e}): "
                          "use a smaller mesh") from e
    return f.solve_A


def cholespy_bytes(A: sp.spmatrix) -> int:
    """Bytes cholespy is expected to need to factorize ``A`` (it does not report running out of
    memory: it crashes the process, so this is checked before it starts). With CHOLMOD's binding
    the factor's size is counted by a symbolic analysis (``40 nnz(L) + 64 n``, as for CHOLMOD's
    supernodal factor); without it, a bound for mesh Laplacians, ``80 n log2 n`` bytes (measured:
    38-60 bytes per ``n log2 n`` from 20k to 1M vertices; matrices of other graphs may need more).

    Examples
    --------
    >>> import scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> la.cholespy_bytes(sp.identity(1024, format="csc")) > 0
    True
    """
    n = A.shape[0]
    lib = library()
    if lib is not None:
        try:
            return 40 * Analysis(lib, sp.csc_matrix(A), "supernodal").lnz + 64 * n
        except (OutOfMemory, TooLarge):
            raise
        except Exception:  # noqa: BLE001 - the binding failed: the bound below
            pass
    return int(80 * n * max(np.log2(max(n, 2)), 1.0) + 64 * n)


def _cholespy(A):
    from cholespy import CholeskySolverD, MatrixType

    A = sp.csr_matrix(A)  # cholespy wants CSR (its CSC path mis-reads indices)
    n = A.shape[0]
    check_memory(cholespy_bytes(A), f"cholespy's factorization of the {n} x {n} matrix",
                 "use a smaller mesh (decimate it) or a machine with more memory")
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

    def solve(b):
        return lu.solve(b)

    solve.nbytes = 12 * (lu.L.nnz + lu.U.nnz)
    return solve


def factorize(A: sp.spmatrix, backend: str = "auto", mode: str = "auto", analysis: Analysis | None = None) -> Factor:
    """Factorize a sparse symmetric positive definite matrix once, for many solves.

    Parameters
    ----------
    A : (n, n) scipy.sparse matrix
        Symmetric positive definite (for example ``L - sigma B`` with ``sigma < 0``).
    backend : {"auto", "cholmod", "cholespy", "superlu"}
        "auto" tries them in that order and logs a warning at each fallback.
    mode : {"auto", "simplicial", "supernodal"}
        CHOLMOD's factorization (ignored by the other backends): "auto" is supernodal from
        :data:`SUPERNODAL_MIN_N` rows, simplicial below. Supernodal factors are made with the BLAS
        on one thread (reproducible whatever the core count; when another Python thread holds
        o3dheat's BLAS limit at that moment, the BLAS keeps its threads and the last bits may
        differ) and solved as simplicial LLᵀ (see the module docstring).
    analysis : Analysis, optional
        :func:`analyze` of a matrix with ``A``'s pattern: CHOLMOD skips its own analysis (ignored
        by the other backends, and when the pattern or mode differ).

    Returns
    -------
    Factor

    Raises
    ------
    MeshError
        ``A`` is not square or has non-finite entries, or an unknown backend or mode.
    OutOfMemory
        The factor would not fit in the memory left (estimated from CHOLMOD's symbolic analysis
        before any numeric work), or a backend ran out of it; no other backend is tried.
    SolverError
        The requested backend is missing, or every backend failed, or the factor is too large
        even for CHOLMOD's 64-bit indices.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> A = sp.diags([2.0, 3.0, 4.0]).tocsc()
    >>> la.factorize(A).solve(np.array([2.0, 3.0, 4.0])).round(12).tolist()
    [1.0, 1.0, 1.0]
    """
    if backend == "auto":
        order = list(BACKENDS)
    elif backend in BACKENDS:
        order = [backend]
    else:
        raise MeshError(f"unknown backend {backend!r}: use 'auto' or one of {BACKENDS}")
    A = sp.csc_matrix(A, dtype=np.float64)
    if A.shape[0] != A.shape[1]:
        raise MeshError(f"the matrix to factorize must be square, got shape {A.shape}")
    mode = _auto_mode(mode, A.shape[0])
    if not np.all(np.isfinite(A.data)):
        raise MeshError("the matrix to factorize has NaN or infinite entries: check the mesh "
                          "coordinates and the shift")
    errors = []
    for name in order:
        try:
            if name == "cholmod":
                solve = _cholmod(A, mode, analysis)
            elif name == "cholespy":
                solve = _cholespy(A)
            else:
                solve = _superlu(A)
        except (OutOfMemory, TooLarge):
            raise  # another backend would need as much, and may crash the process (cholespy does)
        except MemoryError as e:
            raise OutOfMemory(f"{name} ran out of memory factorizing the {A.shape[0]} x {A.shape[0]} "
                              "matrix: use a smaller mesh") from e
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
