"""CHOLMOD through ``ctypes`` (the GIL released during each call): :class:`CholmodFactor`, :class:`Analysis`.

Entry points: :func:`library` (the libcholmod scikit-sparse loaded, bound and self-checked, or
None), :class:`CholmodFactor` (a factor whose block solves run on several threads),
:class:`Analysis` (a symbolic analysis shared by factorizations of one pattern),
:func:`factor_nnz`. The struct fields the binding touches are in the commented ``_OFFSETS``
table, each checked against a known value before it is trusted; :mod:`o3dheat.spectral.linalg`
is the public interface (it falls back to scikit-sparse's own solver when this binding fails).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import threading
import weakref

import numpy as np
import scipy.sparse as sp

from o3dheat import parallel
from o3dheat.errors import OutOfMemory, SolverError

from .memory import check_memory

log = logging.getLogger("o3dheat")


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
_MODES = {"simplicial": 0, "supernodal": 2}  # Common->supernodal: CHOLMOD_SIMPLICIAL, CHOLMOD_SUPERNODAL

# The fields of CHOLMOD's structs that the binding reads or writes, by byte offset, for the CHOLMOD
# that the scikit-sparse pin of pyproject.toml (0.4.16) builds against: SuiteSparse 5.x (CHOLMOD 3)
# on LP64; the same offsets hold in CHOLMOD 2 to 5. Each is checked against a known value before it
# is trusted (the last column); a mismatch means another layout: scikit-sparse's own solver is used.
#
#   struct.field                     type     offset  checked against
#   cholmod_common.supernodal_switch double      40   40.0, its default after cholmod_start
#   cholmod_common.supernodal        int         48   1 (CHOLMOD_AUTO), its default; then written
#   cholmod_common.print             int        144   3, its default; then written 0 (silent)
#   cholmod_factor.n                 size_t       0   the order of the matrix, after the analysis
#   cholmod_factor.minor             size_t       8   n after a successful factorization
#   cholmod_factor.ColCount          int32 *     24   read only when .n checked out (memory estimate)
_OFFSETS = {
    "common.supernodal_switch": (40, ctypes.c_double, 40.0),
    "common.supernodal": (48, ctypes.c_int, 1),
    "common.print": (144, ctypes.c_int, 3),
    "factor.n": (0, ctypes.c_size_t, None),
    "factor.minor": (8, ctypes.c_size_t, None),
    "factor.ColCount": (24, ctypes.c_void_p, None),
}
_COMMON_BYTES = 1 << 14  # cholmod_common: 2664 bytes in CHOLMOD 3 (SuiteSparse 5.12); room to spare
_LIB = None  # the bound library, or False when binding is not possible


class _BindingError(OSError):
    """The ctypes binding cannot be used (another layout, a failed start or self-check or solve)."""


class NotPositiveDefinite(SolverError):
    """A property of the matrix: no other CHOLMOD call would factorize it."""


def _field(address, name):
    """The ctypes object of a struct field of the table above, at a struct's address."""
    offset, ctype, _ = _OFFSETS[name]
    return ctype.from_address(address + offset)


def library():
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
        raise _BindingError("libcholmod not found")
    lib = ctypes.CDLL(path)  # CDLL (not PyDLL): the GIL is released during every call
    vp, ci = ctypes.c_void_p, ctypes.c_int
    lib.cholmod_start.argtypes = lib.cholmod_finish.argtypes = [vp]
    lib.cholmod_analyze.argtypes = [ctypes.POINTER(_Sparse), vp]
    lib.cholmod_analyze.restype = vp
    lib.cholmod_copy_factor.argtypes = [vp, vp]
    lib.cholmod_copy_factor.restype = vp
    lib.cholmod_factorize.argtypes = [ctypes.POINTER(_Sparse), vp, vp]
    lib.cholmod_change_factor.argtypes = [ci, ci, ci, ci, ci, vp, vp]
    lib.cholmod_solve2.argtypes = [ci, vp, ctypes.POINTER(_Dense), vp, ctypes.POINTER(_DENSE_P),
                                   vp, ctypes.POINTER(_DENSE_P), ctypes.POINTER(_DENSE_P), vp]
    lib.cholmod_resymbol.argtypes = [ctypes.POINTER(_Sparse), vp, ctypes.c_size_t, ci, vp, vp]
    lib.cholmod_free_factor.argtypes = [ctypes.POINTER(vp), vp]
    lib.cholmod_free_dense.argtypes = [ctypes.POINTER(_DENSE_P), vp]
    _self_check(lib)
    return lib


def _self_check(lib):
    """Factor small matrices both ways, solve on two threads, detect a zero pivot; raises
    :class:`_BindingError` when anything is off."""
    A = sp.diags([np.full(6, -1.0), np.arange(2.0, 9.0), np.full(6, -1.0)], [-1, 0, 1], format="csc")
    x = np.arange(14.0).reshape(7, 2)
    for mode in _MODES:
        if not np.allclose(CholmodFactor(lib, A, mode).solve(A @ x, 2), x, rtol=1e-12, atol=1e-12):
            raise _BindingError(f"self-check failed ({mode})")
    try:
        CholmodFactor(lib, sp.diags([1.0, 0.0, 2.0], format="csc"), "simplicial")
    except NotPositiveDefinite:
        return
    raise _BindingError("self-check failed: a singular matrix was not detected")


def _common(lib, mode):
    """A started cholmod_common (a buffer) in the given factorization mode, messages off."""
    c = ctypes.create_string_buffer(_COMMON_BYTES)
    if not lib.cholmod_start(c):
        raise _BindingError("cholmod_start failed")
    address = ctypes.addressof(c)
    for name in ("common.supernodal_switch", "common.supernodal", "common.print"):
        if _field(address, name).value != _OFFSETS[name][2]:
            lib.cholmod_finish(c)
            raise _BindingError(f"unexpected cholmod_common layout ({name})")
    _field(address, "common.supernodal").value = _MODES[mode]
    _field(address, "common.print").value = 0  # failures are reported as SolverError, not printed
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


class CholmodFactor:
    """A CHOLMOD factor held through ctypes. ``solve(b, threads)`` splits the columns of ``b``
    into contiguous groups solved concurrently, each thread with its own cholmod_common and
    workspace (the factor is only read); the result does not depend on the number of threads.
    A supernodal factor is made with the BLAS on one thread (its rounding would otherwise depend
    on the thread count), then converted to a simplicial LLᵀ. Freed with the object."""

    def __init__(self, lib, A, mode, analysis=None):
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
        self._fbuf = None
        c = self._contexts[0][0]
        if analysis is not None and analysis._fits(A, mode):  # the ordering and symbolic factor, made once
            self._handle.value = lib.cholmod_copy_factor(analysis.handle, c)  # own common: no shared state
        else:
            self._handle.value = lib.cholmod_analyze(ctypes.byref(S), c)
        if not self._handle.value:
            raise OutOfMemory(f"CHOLMOD could not analyze the {n} x {n} matrix (out of memory)")
        # after the analysis ColCount holds the column counts of L: the factor's size is known
        # before it is made (a supernodal factor stores up to about twice as many entries, and is
        # converted to a simplicial one while it exists: three times, counted once more for safety)
        if _field(self._handle.value, "factor.n").value != n:
            raise _BindingError("unexpected cholmod_factor layout (n)")
        lnz = factor_nnz(self._handle.value, n)
        counts = lnz is not None
        if counts:
            check_memory((12 if mode == "simplicial" else 40) * lnz + 64 * n,
                         f"the Cholesky factor of {n} x {n} ({lnz} nonzeros)",
                         "use a smaller mesh (decimate it) or a machine with more memory")
        if mode == "supernodal":
            with parallel.blas_one_thread():
                ok = lib.cholmod_factorize(ctypes.byref(S), self._handle, c)
        else:
            ok = lib.cholmod_factorize(ctypes.byref(S), self._handle, c)
        minor = _field(self._handle.value, "factor.minor").value
        if not ok and minor >= n:  # no failed pivot: CHOLMOD ran out of memory
            raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {n} x {n} matrix: use a smaller mesh")
        if not ok or minor < n:
            raise NotPositiveDefinite(f"CHOLMOD: the matrix is not positive definite (column {minor} of {n})")
        # supernodal -> simplicial LLᵀ (packed, monotonic): CHOLMOD_REAL, to_ll, to_super, packed, monotonic
        if mode == "supernodal" and not lib.cholmod_change_factor(_REAL, 1, 0, 1, 1, self._handle, c):
            raise OutOfMemory(f"CHOLMOD ran out of memory converting the factor of the {n} x {n} matrix")
        # the relaxed supernodes' explicit zeros (about 30% of the entries on meshes) are dropped:
        # every solve reads the factor twice, so it gets that much faster (about 17% at 1M rows);
        # a solve then only skips products with zeros (its results agree to rounding)
        if mode == "supernodal" and not lib.cholmod_resymbol(ctypes.byref(S), None, 0, 1, self._handle, c):
            raise OutOfMemory(f"CHOLMOD ran out of memory pruning the factor of the {n} x {n} matrix")
        self.nbytes = 12 * lnz + 16 * n if counts else 0

    def release(self):
        """Free the solve workspaces of every context and the column-major buffer."""
        with self._lock:
            for c, X, Y, E in self._contexts:
                for h in (X, Y, E):
                    if h:
                        self._lib.cholmod_free_dense(ctypes.byref(h), c)
            self._fbuf = None

    def _solve_columns(self, j, b, out):
        c, X, Y, E = self._contexts[j]
        b = np.asfortranarray(b, dtype=np.float64)
        rows, cols = b.shape
        D = _Dense(rows, cols, rows * cols, rows, b.ctypes.data, None, _REAL, _DOUBLE)
        if not self._lib.cholmod_solve2(_SYS_A, self._handle, ctypes.byref(D), None, ctypes.byref(X),
                                        None, ctypes.byref(Y), ctypes.byref(E), c):
            raise _BindingError("CHOLMOD solve failed")
        d = X.contents.d
        out[...] = np.ctypeslib.as_array(ctypes.cast(X.contents.x, ctypes.POINTER(ctypes.c_double)),
                                         shape=(cols, d)).T[:rows]

    def solve(self, b, threads=None, out=None):
        b = np.asarray(b, dtype=np.float64)
        out = np.empty(b.shape) if out is None else out
        if b.size == 0:
            return out
        b2, out2 = b.reshape(self.n, -1), out.reshape(self.n, -1)
        # CHOLMOD's simplicial solve works on groups of 4 columns (1-, 2-, 3- and 4-column kernels
        # round differently): the threads get whole groups, so results do not depend on their count
        groups = -(-b2.shape[1] // 4)
        t = min(parallel.get_threads() if threads is None else threads, groups)
        cuts = [min(4 * round(j * groups / t), b2.shape[1]) for j in range(t + 1)]
        with self._lock:
            # column-major once (CHOLMOD's layout), into a buffer kept for the next solve of the
            # same shape (a fresh (n, b) array faults its pages in anew): each group is a slice
            if not b2.flags.f_contiguous:
                if self._fbuf is None or self._fbuf.shape != b2.shape:
                    self._fbuf = np.empty(b2.shape, order="F")
                np.copyto(self._fbuf, b2)
                b2 = self._fbuf
            while len(self._contexts) < t:
                self._contexts.append((_common(self._lib, self._mode), _DENSE_P(), _DENSE_P(), _DENSE_P()))
            parallel.run(lambda j: self._solve_columns(j, b2[:, cuts[j]:cuts[j + 1]], out2[:, cuts[j]:cuts[j + 1]]),
                         [(j,) for j in range(t)], threads=t)
        return out

class Analysis:
    """CHOLMOD's symbolic analysis of a sparse symmetric pattern (the fill-reducing ordering, the
    elimination tree, the supernodes: about a third of a factorization's time at 1M rows), made
    once by :func:`o3dheat.spectral.linalg.analyze` and shared by factorizations of matrices with
    that very pattern (``factorize(A, analysis=...)``), for example ``W + γL`` for several ``γ``.
    Freed with the object.

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> A = sp.diags([[-1.0] * 4, [3.0] * 5, [-1.0] * 4], [-1, 0, 1], format="csc")
    >>> a = la.analyze(A)
    >>> f1, f2 = la.factorize(A, analysis=a), la.factorize(2 * A, analysis=a)
    >>> bool(np.allclose(f1.solve(np.ones(5)), 2 * f2.solve(np.ones(5))))
    True
    """

    def __init__(self, lib, A, mode):
        A = sp.csc_matrix(A)
        n = A.shape[0]
        if A.nnz >= 2**31 - 1:
            raise OverflowError("more than 2^31 nonzeros")
        if not A.has_sorted_indices:
            A = A.sorted_indices()
        self._indptr = np.asarray(A.indptr, dtype=np.int32)
        self._indices = np.asarray(A.indices, dtype=np.int32)
        S = _Sparse(n, n, len(self._indices), self._indptr.ctypes.data, self._indices.ctypes.data, None, None, None,
                    _LOWER, _INT, 0, _DOUBLE, 1, 1)  # CHOLMOD_PATTERN: the values do not matter
        self._lib, self.n, self.mode = lib, n, mode
        self.common = _common(lib, mode)
        self.handle = lib.cholmod_analyze(ctypes.byref(S), self.common)
        if not self.handle:
            lib.cholmod_finish(self.common)
            raise OutOfMemory(f"CHOLMOD could not analyze the {n} x {n} pattern (out of memory)")
        self._finalizer = weakref.finalize(self, _free, lib, ctypes.c_void_p(self.handle),
                                           [(self.common, None, None, None)])

    def _fits(self, A, mode):
        """Whether ``A`` (CSC, sorted) has the analysed pattern and mode."""
        return (mode == self.mode and A.shape[0] == self.n and len(A.indices) == len(self._indices)
                and np.array_equal(A.indptr, self._indptr) and np.array_equal(A.indices, self._indices))

def factor_nnz(handle, n):
    """Nonzeros of the Cholesky factor an analysis (``cholmod_analyze``) predicts, from its column
    counts; None when the factor holds none."""
    counts = _field(handle, "factor.ColCount").value
    if not counts:
        return None
    return int(np.ctypeslib.as_array(ctypes.cast(counts, ctypes.POINTER(ctypes.c_int32)), shape=(n,))
               .astype(np.int64).sum())

