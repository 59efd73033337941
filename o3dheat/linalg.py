"""Sparse Cholesky factorizations behind one interface: CHOLMOD (scikit-sparse) -> cholespy -> SuperLU.

``factorize(A)`` returns a :class:`Factor` whose ``solve`` accepts one right-hand side ``(n,)`` or
many ``(n, c)``. With ``backend="auto"`` the first backend that is installed and succeeds is used;
each fallback is logged as a warning naming the reason, and the factor says which backend it is.

* ``"cholmod"``: CHOLMOD of the system SuiteSparse, the library scikit-sparse is built against.
  Simplicial LDLᵀ by default, which on Debian's reference-BLAS build solves 1.6-2.5x faster than
  supernodal. scikit-sparse's ``solve_A`` holds Python's GIL, so the columns of a block cannot be
  solved concurrently through it; o3dheat therefore calls the very library scikit-sparse loaded
  through ``ctypes`` (which releases the GIL) and solves the columns of a block on several threads
  (1.8-2x faster block solves on 2 cores, bit-identical results: each column is solved alone).
  When that binding is not possible (no ``libcholmod`` found, an unexpected ``cholmod_common``
  layout, a failed self-check) scikit-sparse's own ``cholesky`` is used, single-threaded.
* ``"cholespy"``: the pip wheel of cholespy (CHOLMOD bundled), for machines without
  ``libsuitesparse-dev``.
* ``"superlu"``: scipy's SuperLU (always there; an LU, slower and more memory).

The number of threads that solve the columns of a block is :func:`o3dheat.parallel.get_threads`.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import threading
import weakref

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from . import parallel
from .errors import SolverError

__all__ = ["BACKENDS", "Factor", "available_backends", "factorize", "available_memory", "OutOfMemory"]

log = logging.getLogger("o3dheat")

BACKENDS = ("cholmod", "cholespy", "superlu")
_WARNED = set()
ORDERING = "default"  # CHOLMOD tries AMD, then METIS when the fill is high: best or near-best on meshes


class OutOfMemory(SolverError):
    """The work does not fit in the memory this process may use (estimated before, or reported by
    CHOLMOD): no other backend is tried, since it would need as much and may crash the process."""


def available_memory():
    """Bytes this process may still allocate: the smaller of the system's available memory
    (``MemAvailable`` of /proc/meminfo) and what an address-space limit (``ulimit -v``) leaves;
    None when neither is known.

    Examples
    --------
    >>> import o3dheat.linalg as la
    >>> m = la.available_memory(); m is None or m > 0
    True
    """
    limits = []
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    limits.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm") as fh:
                used = int(fh.read().split()[0]) * resource.getpagesize()
            limits.append(max(soft - used, 0))
    except (ImportError, OSError, ValueError):
        pass
    return min(limits) if limits else None


def check_memory(needed, what, advice):
    """Raise :class:`OutOfMemory` when ``needed`` bytes exceed what this process may allocate."""
    have = available_memory()
    if have is not None and needed > have:
        raise OutOfMemory(f"{what} needs about {needed / 2**30:.2f} GiB, but only {have / 2**30:.2f} GiB "
                          f"are available: {advice}")


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


# ---- CHOLMOD through ctypes (the GIL is released during each call) --------------------------

class _Sparse(ctypes.Structure):  # cholmod_sparse, unchanged from CHOLMOD 1 to 5
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t), ("nzmax", ctypes.c_size_t),
                ("p", ctypes.c_void_p), ("i", ctypes.c_void_p), ("nz", ctypes.c_void_p),
                ("x", ctypes.c_void_p), ("z", ctypes.c_void_p), ("stype", ctypes.c_int),
                ("itype", ctypes.c_int), ("xtype", ctypes.c_int), ("dtype", ctypes.c_int),
                ("sorted", ctypes.c_int), ("packed", ctypes.c_int)]


class _Dense(ctypes.Structure):  # cholmod_dense, column-major with leading dimension d
    _fields_ = [("nrow", ctypes.c_size_t), ("ncol", ctypes.c_size_t), ("nzmax", ctypes.c_size_t),
                ("d", ctypes.c_size_t), ("x", ctypes.c_void_p), ("z", ctypes.c_void_p),
                ("xtype", ctypes.c_int), ("dtype", ctypes.c_int)]


_DENSE_P = ctypes.POINTER(_Dense)
_REAL, _DOUBLE, _INT, _LOWER, _SYS_A = 1, 0, 0, -1, 0  # CHOLMOD_REAL, _DOUBLE, _INT, stype, CHOLMOD_A
_MODES = {"simplicial": 0, "auto": 1, "supernodal": 2}  # Common->supernodal
_COMMON_BYTES = 1 << 14  # cholmod_common: 2664 bytes in CHOLMOD 3 (SuiteSparse 5.12); room to spare
_LIB = None  # the bound library, or False when binding is not possible


def _library():
    """The CHOLMOD library scikit-sparse is linked to, bound with ctypes and self-checked; None
    when that is not possible (then scikit-sparse's own solver is used)."""
    global _LIB
    if _LIB is None:
        try:
            _LIB = _bind()
        except Exception as e:  # noqa: BLE001 - no library, another layout, a failed self-check
            log.info("CHOLMOD through ctypes unavailable (%s): scikit-sparse solves, one thread", e)
            _LIB = False
    return _LIB or None


def _bind():
    import sksparse.cholmod  # noqa: F401 - loads the libcholmod scikit-sparse is built against

    path = None
    try:  # the very library now mapped into this process
        with open("/proc/self/maps") as fh:
            path = next((line.split(None, 5)[5].strip() for line in fh
                         if "libcholmod" in line and len(line.split(None, 5)) == 6), None)
    except OSError:
        pass
    path = path or ctypes.util.find_library("cholmod")
    if not path:
        raise OSError("libcholmod not found")
    lib = ctypes.CDLL(path)  # CDLL (not PyDLL): the GIL is released during every call
    vp = ctypes.c_void_p
    lib.cholmod_start.argtypes = lib.cholmod_finish.argtypes = [vp]
    lib.cholmod_analyze.argtypes = [ctypes.POINTER(_Sparse), vp]
    lib.cholmod_analyze.restype = vp
    lib.cholmod_factorize.argtypes = [ctypes.POINTER(_Sparse), vp, vp]
    lib.cholmod_solve2.argtypes = [ctypes.c_int, vp, ctypes.POINTER(_Dense), vp, ctypes.POINTER(_DENSE_P),
                                   vp, ctypes.POINTER(_DENSE_P), ctypes.POINTER(_DENSE_P), vp]
    lib.cholmod_free_factor.argtypes = [ctypes.POINTER(vp), vp]
    lib.cholmod_free_dense.argtypes = [ctypes.POINTER(_DENSE_P), vp]
    # self-check on small matrices: factor, a two-thread solve, a detected zero pivot
    A = sp.diags([np.full(6, -1.0), np.arange(2.0, 9.0), np.full(6, -1.0)], [-1, 0, 1], format="csc")
    x = np.arange(14.0).reshape(7, 2)
    if not np.allclose(_CholmodFactor(lib, A, "simplicial").solve(A @ x, 2), x, rtol=1e-12, atol=1e-12):
        raise OSError("self-check failed")
    try:
        _CholmodFactor(lib, sp.diags([1.0, 0.0, 2.0], format="csc"), "simplicial")
    except SolverError:
        return lib
    raise OSError("self-check failed: a singular matrix was not detected")


def _common(lib, mode):
    """A started cholmod_common (a buffer) in the given factorization mode, messages off."""
    c = ctypes.create_string_buffer(_COMMON_BYTES)
    if not lib.cholmod_start(c):
        raise SolverError("cholmod_start failed")
    # the first fields are dbound, grow0, grow1, grow2, maxrank, supernodal_switch (default 40),
    # supernodal (default CHOLMOD_AUTO = 1), ... print (default 3) at byte 144 in CHOLMOD 2-5
    switch, flag = ctypes.c_double.from_buffer(c, 40).value, ctypes.c_int.from_buffer(c, 48)
    if switch != 40.0 or flag.value != 1:
        lib.cholmod_finish(c)
        raise OSError("unexpected cholmod_common layout")
    flag.value = _MODES[mode]
    verbosity = ctypes.c_int.from_buffer(c, 144)
    if verbosity.value == 3:
        verbosity.value = 0  # failures are reported as SolverError, not printed
    return c


def _free(lib, handle, contexts):
    for c, X, Y, E in contexts:
        for h in (X, Y, E):
            if h:
                lib.cholmod_free_dense(ctypes.byref(h), c)
    if handle.value and contexts:
        lib.cholmod_free_factor(ctypes.byref(handle), contexts[0][0])
    for c, *_ in contexts:
        lib.cholmod_finish(c)


class _CholmodFactor:
    """A CHOLMOD factor held through ctypes. ``solve(b, threads)`` splits the columns of ``b``
    into contiguous groups solved concurrently, each thread with its own cholmod_common and
    workspace (the factor is only read); the result does not depend on the number of threads.
    Freed with the object."""

    def __init__(self, lib, A, mode):
        A = sp.csc_matrix(A)
        n = A.shape[0]
        if A.nnz >= 2**31 - 1:
            raise OverflowError("more than 2^31 nonzeros")
        if not A.has_sorted_indices:
            A = A.sorted_indices()  # a copy: the caller's arrays are never reordered
        p, i = np.asarray(A.indptr, dtype=np.int32), np.asarray(A.indices, dtype=np.int32)
        x = np.ascontiguousarray(A.data, dtype=np.float64)
        S = _Sparse(n, n, len(i), p.ctypes.data, i.ctypes.data, None, x.ctypes.data, None,
                    _LOWER, _INT, _REAL, _DOUBLE, 1, 1)
        self._lib, self.n, self._mode = lib, n, mode
        self._handle = ctypes.c_void_p()
        self._contexts = [(_common(lib, mode), _DENSE_P(), _DENSE_P(), _DENSE_P())]
        self._finalizer = weakref.finalize(self, _free, lib, self._handle, self._contexts)
        self._lock = threading.Lock()
        c = self._contexts[0][0]
        self._handle.value = lib.cholmod_analyze(ctypes.byref(S), c)
        if not self._handle.value:
            raise OutOfMemory(f"CHOLMOD could not analyze the {n} x {n} matrix (out of memory)")
        # cholmod_factor begins with n, minor, Perm, ColCount (CHOLMOD 1-5): after the analysis
        # ColCount holds the column counts of L, so the factor's size is known before it is made
        size = ctypes.c_size_t.from_address(self._handle.value).value
        if size != n:
            raise OSError("unexpected cholmod_factor layout")
        counts = ctypes.c_void_p.from_address(self._handle.value + 24).value
        if counts:
            lnz = int(np.ctypeslib.as_array(ctypes.cast(counts, ctypes.POINTER(ctypes.c_int32)), shape=(n,))
                      .astype(np.int64).sum())
            check_memory(12 * lnz + 64 * n, f"the Cholesky factor of {n} x {n} ({lnz} nonzeros)",
                         "use a smaller mesh (decimate it) or a machine with more memory")
        ok = lib.cholmod_factorize(ctypes.byref(S), self._handle, c)
        minor = ctypes.c_size_t.from_address(self._handle.value + 8).value
        if not ok and minor >= n:  # no failed pivot: CHOLMOD ran out of memory
            raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {n} x {n} matrix: use a smaller mesh")
        if not ok or minor < n:
            raise SolverError(f"CHOLMOD: the matrix is not positive definite (column {minor} of {n})")

    def _solve_columns(self, j, b, out):
        c, X, Y, E = self._contexts[j]
        b = np.asfortranarray(b, dtype=np.float64)
        rows, cols = b.shape
        D = _Dense(rows, cols, rows * cols, rows, b.ctypes.data, None, _REAL, _DOUBLE)
        if not self._lib.cholmod_solve2(_SYS_A, self._handle, ctypes.byref(D), None, ctypes.byref(X),
                                        None, ctypes.byref(Y), ctypes.byref(E), c):
            raise SolverError("CHOLMOD solve failed (out of memory?)")
        d = X.contents.d
        out[...] = np.ctypeslib.as_array(ctypes.cast(X.contents.x, ctypes.POINTER(ctypes.c_double)),
                                         shape=(cols, d)).T[:rows]

    def solve(self, b, threads=None):
        b = np.asarray(b, dtype=np.float64)
        out = np.empty(b.shape)
        if b.size == 0:
            return out
        b2, out2 = b.reshape(self.n, -1), out.reshape(self.n, -1)
        # CHOLMOD's simplicial solve works on groups of 4 columns (1-, 2-, 3- and 4-column kernels
        # round differently): the threads get whole groups, so results do not depend on their count
        groups = -(-b2.shape[1] // 4)
        t = min(parallel.get_threads() if threads is None else threads, groups)
        cuts = [min(4 * round(j * groups / t), b2.shape[1]) for j in range(t + 1)]
        with self._lock:
            while len(self._contexts) < t:
                self._contexts.append((_common(self._lib, self._mode), _DENSE_P(), _DENSE_P(), _DENSE_P()))
            parallel.run(lambda j: self._solve_columns(j, b2[:, cuts[j]:cuts[j + 1]], out2[:, cuts[j]:cuts[j + 1]]),
                         [(j,) for j in range(t)], threads=t)
        return out


def _cholmod(A, mode):
    lib = _library()
    if lib is not None:
        try:
            return _CholmodFactor(lib, A, mode).solve
        except (OverflowError, OSError) as e:  # too big for the int32 interface, another layout
            log.info("CHOLMOD through ctypes not used (%s): scikit-sparse instead", e)
    from sksparse.cholmod import CholmodOutOfMemoryError, CholmodTooLargeError, cholesky

    A = sp.csc_matrix(A)
    try:
        try:
            f = cholesky(A, mode=mode, ordering_method=ORDERING)
        except (CholmodOutOfMemoryError, CholmodTooLargeError):
            raise
        except Exception:  # a CHOLMOD built without METIS
            f = cholesky(A, mode=mode)
    except (CholmodOutOfMemoryError, CholmodTooLargeError) as e:
        raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {A.shape[0]} x {A.shape[0]} matrix ({e}): "
                          "use a smaller mesh") from e
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
        ``A`` is not square or has non-finite entries, the requested backend is missing, or
        every backend failed.

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
    if A.shape[0] != A.shape[1]:
        raise SolverError(f"the matrix to factorize must be square, got shape {A.shape}")
    if not np.all(np.isfinite(A.data)):
        raise SolverError("the matrix to factorize has NaN or infinite entries: check the mesh "
                          "coordinates and the shift")
    errors = []
    for name in order:
        try:
            if name == "cholmod":
                solve = _cholmod(A, mode)
            elif name == "cholespy":
                solve = _cholespy(A)
            else:
                solve = _superlu(A)
        except OutOfMemory:
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
