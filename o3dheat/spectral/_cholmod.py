"""CHOLMOD through ``ctypes`` (the GIL released during each call): :class:`CholmodFactor`, :class:`Analysis`.

Entry points: :func:`library` (the libcholmod scikit-sparse loaded, bound and self-checked, or
None), :class:`CholmodFactor` (a factor whose block solves run on several threads),
:class:`Analysis` (a symbolic analysis shared by factorizations of one pattern, with its fill,
flops and memory), :func:`factor_bytes`. The struct fields the binding touches are in the
commented ``_OFFSETS`` table, each checked against a known value before it is trusted;
:mod:`o3dheat.spectral.linalg` is the public interface (it falls back to scikit-sparse's own
solver when this binding fails).

Index width: CHOLMOD comes in two flavours, ``cholmod_*`` with 32-bit indices and ``cholmod_l_*``
with 64-bit ones. The 32-bit one is used while it can hold the factor (its indices take 4 bytes
per entry instead of 8: a smaller factor and faster solves); when CHOLMOD's symbolic analysis says
the factor is too large for 32-bit indices (a supernodal factor of more than 2³¹ entries: meshes
of roughly 27-56M vertices), the analysis is made again with 64-bit indices, before any numeric
work. "Too large" and "out of memory" are told apart by CHOLMOD's status, never confused.

Ordering ("auto"): AMD, then METIS only when AMD's own flop count says that METIS pays, that is
when the factorization with AMD's ordering would take more than :data:`METIS_FLOPS_PER_ROW` flops
per row; the ordering with fewer flops is kept. Why (measured, ``docs/details/large.md``): METIS
orders about 7 µs per row (7.2 s at 1M rows, AMD 0.8 s). On curvature-adaptive meshes (the bunny:
17k-42k flops per row with AMD from 250k to 4M rows) it saves 35-50% of the flops, less than it
costs; CHOLMOD's own default, which tries METIS whenever AMD's flops per factor entry exceed 500,
spent 34 s ordering the 4M bunny to save 4 s. On a uniform torus (160k flops per row with AMD at
1M) METIS saves 77% of the flops and 41% of the fill: 12.3 s of factorization become 4.0 s, for
4.9 s more of ordering, and every solve reads 41% less.
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
from o3dheat.memory import check_memory, give_back

from . import _substitution

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
_PATTERN, _REAL, _DOUBLE, _LOWER, _SYS_A = 0, 1, 0, -1, 0  # CHOLMOD_PATTERN, _REAL, _DOUBLE, stype, CHOLMOD_A
_INT, _LONG = 0, 2  # CHOLMOD_INT, CHOLMOD_LONG: Common->itype of cholmod_start, cholmod_l_start
_OK, _OUT_OF_MEMORY, _TOO_LARGE = 0, -2, -3  # Common->status
_MODES = {"simplicial": 0, "supernodal": 2}  # Common->supernodal: CHOLMOD_SIMPLICIAL, CHOLMOD_SUPERNODAL
#: Common->method[0].ordering: CHOLMOD_NATURAL, CHOLMOD_AMD, CHOLMOD_METIS, CHOLMOD_NESDIS; "auto": AMD,
#: then METIS where it pays (module notes)
ORDERINGS = {"auto": None, "amd": 2, "metis": 3, "nesdis": 4, "natural": 0}
#: "auto" orders with METIS too when AMD's ordering would take more flops than this per row to
#: factorize: METIS's extra time (about 7 µs per row) is then below the half of the
#: factorization (at 10-13 GFlop/s on one core) that it saves (module notes)
METIS_FLOPS_PER_ROW = 1.2e5
#: right-hand sides from which a solve runs row by row (:mod:`o3dheat.spectral._substitution`)
#: rather than through CHOLMOD's solve, 4 columns per thread (measured per column, relative to one
#: column, at 20k / 41k / 1M rows: 8 columns 0.45 / 0.69 / 0.46 row by row against CHOLMOD's
#: 0.44 / 0.42 / 0.33; 16 columns 0.28 / 0.48 / 0.27 against 0.32 / 0.39 / 0.35; 32 columns
#: 0.16 / 0.34 / 0.19 against 0.34 / 0.40 / 0.33)
ROW_SOLVE_MIN = 16

# The fields of CHOLMOD's structs that the binding reads or writes, by byte offset, for the CHOLMOD
# that the scikit-sparse pin of pyproject.toml (0.4.16) builds against: SuiteSparse 5.x (CHOLMOD 3)
# on LP64; the same offsets hold in CHOLMOD 2 to 5 (cholmod_l_* uses the same structs). Each is
# checked against a known value before it is trusted (the last column); a mismatch means another
# layout: scikit-sparse's own solver is used.
#
#   struct.field                     type     offset  checked against
#   cholmod_common.supernodal_switch double      40   40.0, its default after cholmod_start
#   cholmod_common.supernodal        int         48   1 (CHOLMOD_AUTO), its default; then written
#   cholmod_common.print             int        144   3, its default; then written 0 (silent)
#   cholmod_common.nmethods          int        168   0 (the default strategy); then written 1
#   cholmod_common.method0_ordering  int        316   1 (CHOLMOD_GIVEN), method[0]'s default; then written
#   cholmod_common.itype             int       1960   0 after cholmod_start, 2 after cholmod_l_start
#   cholmod_common.status            int       1972   0 after a start; -3 after an impossible allocation (self-check)
#   cholmod_common.fl                double    1976   read after an analysis (its flop count)
#   cholmod_common.lnz               double    1984   read after an analysis (nnz(L)); checked against ColCount
#   cholmod_common.memory_usage      size_t    2016   read after a factorization (CHOLMOD's peak bytes); checked in (0, 1 MiB) by the self-check
#   cholmod_factor.n                 size_t       0   the order of the matrix, after the analysis
#   cholmod_factor.minor             size_t       8   n after a successful factorization
#   cholmod_factor.Perm              int *       16   read when the simplicial LLᵀ checks out (is_ll ...)
#   cholmod_factor.ColCount          int *       24   summed: equal to common.lnz
#   cholmod_factor.p                 int *       48   read when the simplicial LLᵀ checks out
#   cholmod_factor.i                 int *       56   likewise; each column's first row is its own
#   cholmod_factor.x                 double *    64   likewise
#   cholmod_factor.xsize             size_t     120   a supernodal analysis' entries, >= lnz
#   cholmod_factor.is_ll             int        180   1 after the conversion to a simplicial LLᵀ
#   cholmod_factor.is_super          int        184   0 after it
#   cholmod_factor.is_monotonic      int        188   1 after it
_OFFSETS = {
    "common.supernodal_switch": (40, ctypes.c_double, 40.0),
    "common.supernodal": (48, ctypes.c_int, 1),
    "common.print": (144, ctypes.c_int, 3),
    "common.nmethods": (168, ctypes.c_int, 0),
    "common.method0_ordering": (316, ctypes.c_int, 1),
    "common.itype": (1960, ctypes.c_int, None),
    "common.status": (1972, ctypes.c_int, 0),
    "common.fl": (1976, ctypes.c_double, None),
    "common.lnz": (1984, ctypes.c_double, None),
    "common.memory_usage": (2016, ctypes.c_size_t, None),
    "factor.n": (0, ctypes.c_size_t, None),
    "factor.minor": (8, ctypes.c_size_t, None),
    "factor.Perm": (16, ctypes.c_void_p, None),
    "factor.ColCount": (24, ctypes.c_void_p, None),
    "factor.p": (48, ctypes.c_void_p, None),
    "factor.i": (56, ctypes.c_void_p, None),
    "factor.x": (64, ctypes.c_void_p, None),
    "factor.xsize": (120, ctypes.c_size_t, None),
    "factor.is_ll": (180, ctypes.c_int, None),
    "factor.is_super": (184, ctypes.c_int, None),
    "factor.is_monotonic": (188, ctypes.c_int, None),
}
_COMMON_BYTES = 1 << 14  # cholmod_common: 2664 bytes in CHOLMOD 3 (SuiteSparse 5.12); room to spare
_LIB = None  # the bound 32-bit API, or False when binding is not possible


class _BindingError(OSError):
    """The ctypes binding cannot be used (another layout, a failed start or self-check or solve)."""


class _TooLarge(OverflowError):
    """CHOLMOD's status CHOLMOD_TOO_LARGE: the problem does not fit this index width."""


class NotPositiveDefinite(SolverError):
    """A property of the matrix: no other CHOLMOD call would factorize it."""


class TooLarge(SolverError):
    """The factor does not fit CHOLMOD's widest indices (or the 64-bit interface is missing): no
    other backend would do better."""


def _field(address, name):
    """The ctypes object of a struct field of the table above, at a struct's address."""
    offset, ctype, _ = _OFFSETS[name]
    return ctype.from_address(address + offset)


class _Api:
    """CHOLMOD's functions of one index width, under the names of the 32-bit ones
    (``api.cholmod_analyze`` is ``cholmod_l_analyze`` when ``wide``), with the integer type of
    its index arrays (``index``) and its ``itype``."""

    _SIGNATURES = {
        "start": (["vp"], "int"), "finish": (["vp"], "int"),
        "analyze": (["sparse", "vp"], "vp"), "copy_factor": (["vp", "vp"], "vp"),
        "factorize": (["sparse", "vp", "vp"], "int"),
        "change_factor": (["int", "int", "int", "int", "int", "vp", "vp"], "int"),
        "solve2": (["int", "vp", "dense", "vp", "dense_pp", "vp", "dense_pp", "dense_pp", "vp"], "int"),
        "resymbol": (["sparse", "vp", "size", "int", "vp", "vp"], "int"),
        "free_factor": (["vp_p", "vp"], "int"), "free_dense": (["dense_pp", "vp"], "int"),
        "allocate_dense": (["size", "size", "size", "int", "vp"], "vp"),
    }
    _TYPES = {"vp": ctypes.c_void_p, "int": ctypes.c_int, "size": ctypes.c_size_t, "sparse": ctypes.POINTER(_Sparse),
              "dense": ctypes.POINTER(_Dense), "dense_pp": ctypes.POINTER(_DENSE_P),
              "vp_p": ctypes.POINTER(ctypes.c_void_p)}

    def __init__(self, cdll, wide):
        self.wide = wide
        self.itype = _LONG if wide else _INT
        self.index = np.int64 if wide else np.int32
        self.cdll = cdll
        self._wide = None
        for name, (args, result) in self._SIGNATURES.items():
            fn = getattr(cdll, ("cholmod_l_" if wide else "cholmod_") + name)
            fn.argtypes = [self._TYPES[a] for a in args]
            fn.restype = self._TYPES[result]
            setattr(self, "cholmod_" + name, fn)

    def wide_api(self):
        """The 64-bit API of the same library, bound and self-checked once (None when it fails)."""
        if self.wide:
            return self
        if self._wide is None:
            try:
                api = _Api(self.cdll, True)
                _self_check(api)
                self._wide = api
            except Exception as e:  # noqa: BLE001 - a library without cholmod_l_*, a failed check
                log.info("CHOLMOD's 64-bit interface unavailable (%s)", e)
                self._wide = False
        return self._wide or None


def library():
    """CHOLMOD's 32-bit API in the library scikit-sparse is linked to, bound with ctypes and
    self-checked (its 64-bit twin: ``.wide_api()``); None when that is not possible (then
    scikit-sparse's own solver is used)."""
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
    api = _Api(ctypes.CDLL(path), False)  # CDLL (not PyDLL): the GIL is released during every call
    _self_check(api)
    return api


def _self_check(api):
    """Factor small matrices both ways, solve on two threads and row by row, detect a zero pivot
    and a problem too large; raises :class:`_BindingError` when anything is off."""
    A = sp.diags([np.full(6, -1.0), np.arange(2.0, 9.0), np.full(6, -1.0)], [-1, 0, 1], format="csc")
    x = np.arange(14.0 * ROW_SOLVE_MIN).reshape(7, 2 * ROW_SOLVE_MIN)
    for mode in _MODES:
        f = CholmodFactor(api, A, mode)
        if not 0 < f.peak_bytes < 2**20:
            raise _BindingError("self-check failed: CHOLMOD's memory count not where expected")
        if not (np.allclose(f.solve(A @ x[:, :2], 2), x[:, :2], rtol=1e-12, atol=1e-12)
                and np.allclose(f.solve(A @ x, 2), x, rtol=1e-12, atol=1e-12)):
            raise _BindingError(f"self-check failed ({mode})")
    c = _common(api, "simplicial")
    try:
        if api.cholmod_allocate_dense(2**40, 2**40, 2**40, _REAL, c) or _status(c) != _TOO_LARGE:
            raise _BindingError("self-check failed: CHOLMOD's status (too large) not where expected")
    finally:
        api.cholmod_finish(c)
    try:
        CholmodFactor(api, sp.diags([1.0, 0.0, 2.0], format="csc"), "simplicial")
    except NotPositiveDefinite:
        return
    raise _BindingError("self-check failed: a singular matrix was not detected")


def _common(api, mode, ordering="amd"):
    """A started cholmod_common (a buffer) of ``api``'s width, in the given factorization mode and
    ordering (AMD for "auto": :func:`_analyze` tries METIS after it), messages off."""
    c = ctypes.create_string_buffer(_COMMON_BYTES)
    if not api.cholmod_start(c):
        raise _BindingError("cholmod_start failed")
    address = ctypes.addressof(c)
    names = ("common.supernodal_switch", "common.supernodal", "common.print", "common.nmethods",
             "common.method0_ordering", "common.status")
    bad = [name for name in names if _field(address, name).value != _OFFSETS[name][2]]
    if bad or _field(address, "common.itype").value != api.itype:
        api.cholmod_finish(c)
        raise _BindingError(f"unexpected cholmod_common layout ({(bad or ['common.itype'])[0]})")
    _field(address, "common.supernodal").value = _MODES[mode]
    _field(address, "common.print").value = 0  # failures are reported as SolverError, not printed
    _field(address, "common.nmethods").value = 1  # one ordering at a time (module notes)
    _field(address, "common.method0_ordering").value = ORDERINGS[ordering] if ordering != "auto" else ORDERINGS["amd"]
    return c


def _status(common):
    return _field(ctypes.addressof(common), "common.status").value


def _sparse(api, A, values=True):
    """``(cholmod_sparse, arrays)`` for the lower triangle's pattern of CSC ``A`` (sorted), with
    ``api``'s index type; the arrays must outlive the struct's use."""
    n = A.shape[0]
    p, i = np.asarray(A.indptr, dtype=api.index), np.asarray(A.indices, dtype=api.index)
    x = np.ascontiguousarray(A.data, dtype=np.float64) if values else None
    S = _Sparse(n, n, len(i), p.ctypes.data, i.ctypes.data, None, None if x is None else x.ctypes.data, None,
                _LOWER, api.itype, _REAL if values else _PATTERN, _DOUBLE, 1, 1)
    return S, (p, i, x)


def _analyze(api, S, common, n, ordering="amd"):
    """``(handle, ordering)``: ``cholmod_analyze`` in ``common``'s ordering, or :class:`_TooLarge` /
    :class:`OutOfMemory` by CHOLMOD's status; with ``ordering="auto"``, then with METIS where AMD's
    flop count says it pays (:data:`METIS_FLOPS_PER_ROW`), the analysis of fewer flops kept."""
    handle = api.cholmod_analyze(ctypes.byref(S), common)
    if not handle:
        if _status(common) == _TOO_LARGE:
            raise _TooLarge(f"the factor of the {n} x {n} matrix is too large for CHOLMOD's "
                            f"{64 if api.wide else 32}-bit indices")
        raise OutOfMemory(f"CHOLMOD could not analyze the {n} x {n} matrix (out of memory)")
    address = ctypes.addressof(common)
    flops, lnz = _field(address, "common.fl").value, _field(address, "common.lnz").value
    if ordering != "auto" or flops <= METIS_FLOPS_PER_ROW * n:
        return handle, "amd" if ordering == "auto" else ordering
    _field(address, "common.method0_ordering").value = ORDERINGS["metis"]
    other = api.cholmod_analyze(ctypes.byref(S), common)
    better = bool(other) and _field(address, "common.fl").value < flops
    _free(api, ctypes.c_void_p(other if not better else handle), [(common, None, None, None)], finish=False)
    _field(address, "common.method0_ordering").value = ORDERINGS["amd"]
    _field(address, "common.status").value = _OK  # a failed METIS analysis leaves AMD's, kept
    if not better:  # the common's counts back to the analysis kept
        _field(address, "common.fl").value, _field(address, "common.lnz").value = flops, lnz
    return (other, "metis") if better else (handle, "amd")


def _wide_or_refuse(api, e):
    """The 64-bit API after a :class:`_TooLarge` of ``api``'s width ``e``, or a refusal."""
    wide = None if api.wide else api.wide_api()
    if wide is None:
        raise TooLarge(f"{e}{'' if api.wide else ', and CHOLMOD 64-bit interface is unavailable'}: use a "
                       "smaller mesh (decimate it)") from e
    log.info("%s: analysing again with 64-bit indices", e)
    return wide


def factor_bytes(handle, api, mode, n):
    """Peak bytes of the factorization that an analysis (``cholmod_analyze``) prepared, the
    conversion to a simplicial LLᵀ included, by CHOLMOD's own count of its allocations.

    Supernodal: the numeric factor (8 bytes per entry of its ``xsize``, the relaxed supernodes'
    zeros included), then the simplicial copy's row indices (at most one per entry; the values are
    moved in place), and 16 indices per row of work space and permutations. Simplicial: ``nnz(L)``
    values and row indices grown as CHOLMOD grows them (1.2 nnz(L) + 5 per column), and 13
    indices per row. Both 0-12% above CHOLMOD's peak count on meshes of 1.2k to 1M vertices, with
    32- and 64-bit indices (tested; the table is in ``docs/details/heatflow.md``)."""
    isize = 8 if api.wide else 4
    if mode == "supernodal":
        return int((8 + isize) * _field(handle, "factor.xsize").value + 16 * isize * n)
    return int((8 + isize) * (1.2 * factor_nnz(handle, n, api) + 5 * n) + 13 * isize * n)


def factor_nnz(handle, n, api):
    """Nonzeros of the Cholesky factor an analysis (``cholmod_analyze``) predicts, from its column counts."""
    counts = _field(handle, "factor.ColCount").value
    if not counts:
        return 0
    ctype = ctypes.c_int64 if api.wide else ctypes.c_int32
    return int(np.ctypeslib.as_array(ctypes.cast(counts, ctypes.POINTER(ctype)), shape=(n,)).astype(np.int64).sum())


def _free(api, handle, contexts, finish=True):
    for c, X, Y, E in contexts:
        for h in (X, Y, E):
            if h:
                api.cholmod_free_dense(ctypes.byref(h), c)
    if handle.value and contexts:
        api.cholmod_free_factor(ctypes.byref(handle), contexts[0][0])
    for c, *_ in contexts if finish else ():
        api.cholmod_finish(c)


class CholmodFactor:
    """A CHOLMOD factor held through ctypes, as a simplicial LLᵀ. ``solve(b, threads)`` runs
    CHOLMOD's solve on contiguous groups of columns concurrently, each thread with its own
    cholmod_common and workspace (the factor is only read), or, from :data:`ROW_SOLVE_MIN`
    columns, the row-major substitution of :mod:`o3dheat.spectral._substitution` on the factor's
    own arrays; the result does not depend on the number of threads. ``ordering``: as for
    :class:`Analysis` (``.ordering``: the one used). A supernodal factor is made
    with the BLAS on one thread (its rounding would otherwise depend on the thread count), then
    converted to a simplicial LLᵀ; a simplicial LDLᵀ is converted too. Freed with the object.
    ``wide``: whether 64-bit indices were needed."""

    def __init__(self, api, A, mode, analysis=None, ordering="auto"):
        A = sp.csc_matrix(A)
        if not A.has_sorted_indices:
            A = A.sorted_indices()  # a copy: the caller's arrays are never reordered
        n = A.shape[0]
        fits = analysis is not None and analysis._fits(A, mode)
        if fits:
            api = analysis.api
        elif A.nnz >= 2**31 - 1:
            api = _wide_or_refuse(api, _TooLarge(f"the {n} x {n} matrix has more than 2^31 nonzeros"))
        self._lib, self.n, self._mode = api, n, mode
        self._lock = threading.Lock()
        self._fbuf, self._work, self._rows = None, [], None
        self._handle = ctypes.c_void_p()
        self._contexts = []
        self._finalizer = weakref.finalize(self, _free, api, self._handle, self._contexts)
        while True:
            S, keep = _sparse(self._lib, A)
            self._contexts[:] = [(_common(self._lib, mode, ordering), _DENSE_P(), _DENSE_P(), _DENSE_P())]
            c = self._contexts[0][0]
            try:
                if fits:  # the ordering and symbolic factor, made once
                    self.ordering = analysis.ordering
                    self._handle.value = self._lib.cholmod_copy_factor(analysis.handle, c)  # own common
                    if not self._handle.value:
                        raise OutOfMemory(f"CHOLMOD could not copy the analysis of the {n} x {n} matrix (out of memory)")
                else:
                    self._handle.value, self.ordering = _analyze(self._lib, S, c, n, ordering)
                break
            except _TooLarge as e:
                self._lib.cholmod_finish(c)
                self._contexts.clear()
                self._lib = _wide_or_refuse(self._lib, e)
                self._finalizer.detach()
                self._finalizer = weakref.finalize(self, _free, self._lib, self._handle, self._contexts)
        if _field(self._handle.value, "factor.n").value != n:
            raise _BindingError("unexpected cholmod_factor layout (n)")
        # the analysis knows the factor's size before it is made
        check_memory(factor_bytes(self._handle.value, self._lib, mode, n),
                     f"the Cholesky factor of {n} x {n} ({factor_nnz(self._handle.value, n, self._lib)} nonzeros)",
                     "use a smaller mesh (decimate it) or a machine with more memory")
        self._factorize(S, c, n)
        del keep
        #: CHOLMOD's own count of its peak memory over the analysis, factorization and conversion
        self.peak_bytes = int(_field(ctypes.addressof(c), "common.memory_usage").value)
        self._rows = self._row_arrays()
        self.nbytes = int(self._rows[2].nbytes * (1 + np.dtype(self._lib.index).itemsize / 8)) + 48 * n
        self.wide = self._lib.wide

    def _factorize(self, S, c, n):
        """The numeric factorization, then the conversion to a packed simplicial LLᵀ."""
        lib, handle = self._lib, self._handle
        if self._mode == "supernodal":
            with parallel.blas_one_thread():
                ok = lib.cholmod_factorize(ctypes.byref(S), handle, c)
        else:
            ok = lib.cholmod_factorize(ctypes.byref(S), handle, c)
        minor = _field(handle.value, "factor.minor").value
        if not ok and minor >= n:  # no failed pivot
            if _status(c) == _TOO_LARGE:
                raise TooLarge(f"the factor of the {n} x {n} matrix is too large for CHOLMOD's "
                               f"{64 if lib.wide else 32}-bit indices: use a smaller mesh")
            raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {n} x {n} matrix: use a smaller mesh")
        if not ok or minor < n:
            raise NotPositiveDefinite(f"CHOLMOD: the matrix is not positive definite (column {minor} of {n})")
        # -> simplicial LLᵀ (packed, monotonic): CHOLMOD_REAL, to_ll, to_super, packed, monotonic
        if not lib.cholmod_change_factor(_REAL, 1, 0, 1, 1, handle, c):
            raise OutOfMemory(f"CHOLMOD ran out of memory converting the factor of the {n} x {n} matrix")
        # the relaxed supernodes' explicit zeros (about 30% of the entries on meshes) are dropped:
        # every solve reads the factor twice, so it gets that much faster (about 17% at 1M rows);
        # a solve then only skips products with zeros (its results agree to rounding)
        if self._mode == "supernodal" and not lib.cholmod_resymbol(ctypes.byref(S), None, 0, 1, handle, c):
            raise OutOfMemory(f"CHOLMOD ran out of memory pruning the factor of the {n} x {n} matrix")

    def _row_arrays(self):
        """``(Lp, Li, Lx, Perm)``: the simplicial LLᵀ's own arrays (views, valid while the factor
        lives), checked: LLᵀ, not supernodal, monotonic, each column's diagonal first."""
        h, n = self._handle.value, self.n
        if ((_field(h, "factor.is_ll").value, _field(h, "factor.is_super").value,
             _field(h, "factor.is_monotonic").value) != (1, 0, 1)):
            raise _BindingError("unexpected cholmod_factor layout (is_ll, is_super, is_monotonic)")
        itype = ctypes.c_int64 if self._lib.wide else ctypes.c_int32

        def view(name, count, ctype):
            return np.ctypeslib.as_array(ctypes.cast(_field(h, name).value, ctypes.POINTER(ctype)), shape=(count,))

        Lp = view("factor.p", n + 1, itype)
        nnz = int(Lp[n])
        Li, Lx, perm = view("factor.i", nnz, itype), view("factor.x", nnz, ctypes.c_double), view("factor.Perm", n, itype)
        if Lp[0] != 0 or np.any(Lp[1:] <= Lp[:-1]) or not np.array_equal(Li[Lp[:-1]], np.arange(n, dtype=Li.dtype)):
            raise _BindingError("unexpected cholmod_factor layout (p, i)")
        return Lp, Li, Lx, perm

    def release(self):
        """Free the solve workspaces of every context and the buffers kept between solves."""
        with self._lock:
            for c, X, Y, E in self._contexts:
                for h in (X, Y, E):
                    if h:
                        self._lib.cholmod_free_dense(ctypes.byref(h), c)
            self._fbuf = None
            self._work = []

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
        threads = parallel.get_threads() if threads is None else threads
        if b2.shape[1] >= ROW_SOLVE_MIN and out2.flags.c_contiguous:
            with self._lock:
                _substitution.solve_rows(*self._rows, np.ascontiguousarray(b2), out2, self._work, threads)
            return out
        # CHOLMOD's simplicial solve works on groups of 4 columns (1-, 2-, 3- and 4-column kernels
        # round differently): the threads get whole groups, so results do not depend on their count
        groups = -(-b2.shape[1] // 4)
        t = min(threads, groups)
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

    Attributes
    ----------
    n : int
    mode : str
    ordering : str
        The ordering used ("amd" or "metis" for "auto", see the module notes).
    lnz : int
        Entries of the Cholesky factor (CHOLMOD's count, from the column counts).
    flops : float
        Floating-point operations of the numeric factorization (CHOLMOD's count).
    nbytes : int
        Peak bytes of a factorization of this pattern (:func:`factor_bytes`).
    wide : bool
        Whether 64-bit indices were needed (the factor has more than 2³¹ entries).

    Examples
    --------
    >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> A = sp.diags([[-1.0] * 4, [3.0] * 5, [-1.0] * 4], [-1, 0, 1], format="csc")
    >>> a = la.analyze(A)
    >>> f1, f2 = la.factorize(A, analysis=a), la.factorize(2 * A, analysis=a)
    >>> bool(np.allclose(f1.solve(np.ones(5)), 2 * f2.solve(np.ones(5)))), a.lnz
    (True, 9)
    """

    def __init__(self, api, A, mode, ordering="auto"):
        A = sp.csc_matrix(A)
        n = A.shape[0]
        if not A.has_sorted_indices:
            A = A.sorted_indices()
        if A.nnz >= 2**31 - 1:
            api = _wide_or_refuse(api, _TooLarge(f"the {n} x {n} matrix has more than 2^31 nonzeros"))
        self._indptr, self._indices = A.indptr.copy(), A.indices.copy()
        self.n, self.mode = n, mode
        while True:
            S, keep = _sparse(api, A, values=False)  # CHOLMOD_PATTERN: the values do not matter
            common = _common(api, mode, ordering)
            try:
                self.handle, self.ordering = _analyze(api, S, common, n, ordering)
                break
            except _TooLarge as e:
                api.cholmod_finish(common)
                api = _wide_or_refuse(api, e)
            except Exception:
                api.cholmod_finish(common)
                raise
        del keep
        give_back()  # METIS's freed work space, else held in the C heap
        self.api, self.common, self.wide = api, common, api.wide
        self._finalizer = weakref.finalize(self, _free, api, ctypes.c_void_p(self.handle), [(common, None, None, None)])
        address = ctypes.addressof(common)
        self.lnz = factor_nnz(self.handle, n, api)
        self.flops = float(_field(address, "common.fl").value)
        if int(_field(address, "common.lnz").value) != self.lnz:
            raise _BindingError("unexpected cholmod_common layout (lnz)")
        self.nbytes = factor_bytes(self.handle, api, mode, n)

    def __repr__(self):
        return (f"Analysis(n={self.n}, mode={self.mode!r}, ordering={self.ordering!r}, lnz={self.lnz}, "
                f"flops={self.flops:.3g}, nbytes={self.nbytes}, wide={self.wide})")

    def _fits(self, A, mode):
        """Whether ``A`` (CSC, sorted) has the analysed pattern and mode."""
        return (mode == self.mode and A.shape[0] == self.n and len(A.indices) == len(self._indices)
                and np.array_equal(A.indptr, self._indptr) and np.array_equal(A.indices, self._indices))
