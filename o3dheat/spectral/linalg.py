"""Sparse Cholesky factorizations behind one interface: CHOLMOD (scikit-sparse) -> cholespy -> SuperLU.

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
import ctypes
import ctypes.util
import logging
import threading
import weakref

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from o3dheat import parallel
from o3dheat.errors import SolverError

__all__ = ["BACKENDS", "Factor", "available_backends", "factorize", "analyze", "Analysis", "available_memory",
           "memory_limits", "OutOfMemory"]

log = logging.getLogger("o3dheat")

#: the factorization backends, in the order ``backend="auto"`` tries them
BACKENDS = ("cholmod", "cholespy", "superlu")
_WARNED = set()
ORDERING = "default"  # CHOLMOD tries AMD, then METIS when the fill is high: best or near-best on meshes
MODES = ("auto", "simplicial", "supernodal")
SUPERNODAL_MIN_N = 100_000  # "auto": supernodal from here (measured in scripts/bench_spectrum.py)


class OutOfMemory(SolverError):
    """The work does not fit in the memory this process may use (estimated before, or reported by
    CHOLMOD): no other backend is tried, since it would need as much and may crash the process.

    Examples
    --------
    >>> import o3dheat, o3dheat.spectral.linalg as la
    >>> issubclass(la.OutOfMemory, o3dheat.SolverError)
    True
    >>> try:
    ...     la.check_memory(2**70, "this eigensolve", "use a smaller mesh")    # 1 ZiB
    ... except la.OutOfMemory as e:
    ...     print(str(e).split(",")[0])
    this eigensolve needs about 1099511627776.00 GiB
    """


def available_memory():
    """Bytes this process may still allocate: the smallest of what each known limit leaves (see
    :func:`memory_limits`); None when no limit is known.

    Examples
    --------
    >>> import o3dheat.spectral.linalg as la
    >>> m = la.available_memory(); m is None or m > 0
    True
    """
    room = memory_limits()
    return min(room.values()) if room else None


#: address space mapped by a thread beyond the memory it uses (bytes): an 8 MiB stack, a 64 MiB
#: malloc arena and OpenBLAS's 32 MiB buffer (measured: the peak address space of an eigensolve
#: exceeds its resident peak by about 1 GiB on 2 cores, whatever the mesh size)
THREAD_ADDRESS_SPACE = 104 * 2**20


def memory_limits():
    """What each limit on this process's memory still leaves, in bytes, by name.

    * ``"system"``: the system's available memory (``MemAvailable`` of /proc/meminfo);
    * ``"cgroup"``: a memory cgroup's limit (a container's ``--memory``, a systemd or batch
      scheduler's slice; cgroup v2 ``memory.max`` or v1 ``memory.limit_in_bytes``, of the
      process's group and every group above it) less its usage, the page cache (but shared
      memory) not counted as used: the kernel reclaims it before it kills a process of a group
      that reaches its limit;
    * ``"Dask worker"``: inside a Dask worker that has a nanny and a memory limit, the fraction of
      it at which the nanny restarts the worker (``distributed.worker.memory.terminate``, 95% by
      default) less the process's resident memory. A worker that is restarted kills its task, and
      Dask retries it on another worker, which dies the same way;
    * ``"address space"``: an address-space limit (``ulimit -v``) less the process's address space
      and a reserve of :data:`THREAD_ADDRESS_SPACE` per thread that may still start (the worker
      threads of :func:`o3dheat.parallel.get_threads` and one more): what each one maps without
      using it (its stack, a malloc arena, a BLAS buffer) counts against this limit, not against
      the others. Without it a 200k-vertex k=300 eigensolve passed the check under ``ulimit -v``
      2 GB and then failed to start a thread, or OpenBLAS aborted the process.

    Returns
    -------
    dict
        Name -> bytes left (at least 0), for the limits that apply.

    Examples
    --------
    >>> import o3dheat.spectral.linalg as la
    >>> room = la.memory_limits()
    >>> set(room) <= {"system", "cgroup", "Dask worker", "address space"}, all(v >= 0 for v in room.values())
    (True, True)
    """
    room = {}
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    room["system"] = int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    for name, left in (("cgroup", _cgroup_room()), ("Dask worker", _dask_worker_room())):
        if left is not None:
            room[name] = left
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            reserve = THREAD_ADDRESS_SPACE * (parallel.get_threads() + 1)
            room["address space"] = max(soft - _statm(0) - reserve, 0)
    except (ImportError, OSError, ValueError):
        pass
    return room


def _statm(field):
    """Field of /proc/self/statm in bytes (0: address space, 1: resident)."""
    import resource

    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[field]) * resource.getpagesize()


#: cgroup v2 and v1 files: limit, usage, and the memory.stat keys of the page cache (which the
#: kernel reclaims before it kills) and of the shared memory counted in it (which it cannot)
_CGROUP_FILES = {"v2": ("memory.max", "memory.current", ("file", "shmem")),
                 "v1": ("memory.limit_in_bytes", "memory.usage_in_bytes", ("total_cache", "total_shmem"))}


def _cgroup_room(proc="/proc/self/cgroup", root="/sys/fs/cgroup"):
    """Bytes left under the tightest memory cgroup limit of this process and its parent groups
    (v2 unified or v1 memory controller), or None without a limit.

    A group's path may not exist under ``root`` (a v1 container without a cgroup namespace sees
    its own group at the root): parents are tried up to the root, which is the container's."""
    from pathlib import Path

    try:
        lines = Path(proc).read_text().splitlines()
    except OSError:
        return None
    rooms = []
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        if parts[1] == "" and parts[0] == "0":
            base, files = Path(root), _CGROUP_FILES["v2"]
        elif "memory" in parts[1].split(","):
            base, files = Path(root) / "memory", _CGROUP_FILES["v1"]
        else:
            continue
        group = base / parts[2].strip().lstrip("/")
        while True:
            left = _group_room(group, *files)
            if left is not None:
                rooms.append(left)
            if group == base or base not in group.parents:
                break
            group = group.parent
    return min(rooms) if rooms else None


def _group_room(group, limit_file, usage_file, cache_keys):
    try:
        text = (group / limit_file).read_text().strip()
        if text == "max":
            return None
        limit = int(text)
        if limit >= 2**60:  # v1's "no limit" (LONG_MAX rounded to pages)
            return None
        usage = int((group / usage_file).read_text())
    except (OSError, ValueError):
        return None
    stat = {}
    try:
        for line in (group / "memory.stat").read_text().splitlines():
            key, _, value = line.partition(" ")
            if key in cache_keys:
                stat[key] = int(value)
    except (OSError, ValueError):
        pass
    cache = max(stat.get(cache_keys[0], 0) - stat.get(cache_keys[1], 0), 0)
    return max(limit - usage + cache, 0)


def _dask_worker_room():
    """Bytes left before this Dask worker's nanny restarts it, or None (not in a Dask worker's task,
    a worker without a nanny, which nothing restarts, no memory limit, or restarts disabled)."""
    import sys

    if "distributed" not in sys.modules:  # never imported: not a worker
        return None
    try:
        import dask
        from distributed import get_worker

        worker = get_worker()
        if not getattr(worker, "nanny", None):  # no nanny (in-process workers, --no-nanny): no restart
            return None
        limit = getattr(getattr(worker, "memory_manager", None), "memory_limit", None)
        fraction = dask.config.get("distributed.worker.memory.terminate", 0.95)
    except (ImportError, ValueError, AttributeError):
        return None
    if not limit or not fraction:
        return None
    try:
        return max(int(float(fraction) * limit) - _statm(1), 0)
    except (OSError, ValueError):
        return None


_LIMIT_NAMES = {"cgroup": " (under the memory limit of this process's cgroup: a container's, a job's)",
                "Dask worker": " (under the Dask worker's memory limit)",
                "address space": " (under the address-space limit, ulimit -v)"}


def check_memory(needed, what, advice):
    """Raise :class:`OutOfMemory` when ``needed`` bytes exceed what this process may allocate
    (the message names the limit: the system's memory, a cgroup's, a Dask worker's, ulimit -v)."""
    room = memory_limits()
    name = min(room, key=room.get) if room else None
    if name is not None and needed > room[name]:
        have = room[name]
        where = _LIMIT_NAMES.get(name, "")
        raise OutOfMemory(f"{what} needs about {needed / 2**30:.2f} GiB, but only {have / 2**30:.2f} GiB "
                          f"are available{where}: {advice}")


def available_backends():
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

    def solve(self, b, out=None):
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
            raise SolverError(f"right-hand side has {b.shape[0]} rows, the matrix {self.shape[0]}")
        if out is None:
            x = self._solve(b)
        else:
            if out.shape != b.shape or out.dtype != np.float64 or not out.flags.c_contiguous:
                raise SolverError(f"out must be a C-ordered float64 array of shape {b.shape}")
            into = getattr(self._solve, "into", None)
            x = into(b, out) if into is not None else out
            if into is None:
                np.copyto(out, self._solve(b))
        if not np.all(np.isfinite(x)):
            raise SolverError(f"the {self.backend} solve produced non-finite values: the matrix is "
                              "singular or badly conditioned")
        return x

    __call__ = solve

    def release(self):
        """Give back the memory of the last solve's workspaces (they are made again by the next
        solve): CHOLMOD keeps about three ``(n, columns)`` arrays per thread between solves.

        Examples
        --------
        >>> import numpy as np, scipy.sparse as sp, o3dheat.spectral.linalg as la
        >>> f = la.factorize(sp.diags([2.0, 4.0]).tocsc())
        >>> f.release(); f.solve([2.0, 4.0]).tolist()
        [1.0, 1.0]
        """
        release = getattr(self._solve, "release", None)
        if release is not None:
            release()


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


class _NotPositiveDefinite(SolverError):
    """A property of the matrix: no other CHOLMOD call would factorize it."""


def _field(address, name):
    """The ctypes object of a struct field of the table above, at a struct's address."""
    offset, ctype, _ = _OFFSETS[name]
    return ctype.from_address(address + offset)


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
        if not np.allclose(_CholmodFactor(lib, A, mode).solve(A @ x, 2), x, rtol=1e-12, atol=1e-12):
            raise _BindingError(f"self-check failed ({mode})")
    try:
        _CholmodFactor(lib, sp.diags([1.0, 0.0, 2.0], format="csc"), "simplicial")
    except _NotPositiveDefinite:
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


class _CholmodFactor:
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
        lnz = _factor_nnz(self._handle.value, n)
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
            raise _NotPositiveDefinite(f"CHOLMOD: the matrix is not positive definite (column {minor} of {n})")
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
    once by :func:`analyze` and shared by factorizations of matrices with that very pattern
    (``factorize(A, analysis=...)``), for example ``W + γL`` for several ``γ``. Freed with the
    object.

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


def analyze(A, mode="auto"):
    """The symbolic analysis of ``A``'s pattern, for :func:`factorize` (``analysis=``) of any
    matrix with that pattern; None where CHOLMOD's binding is not available (each factorization
    then analyses its own matrix). Runs without Python's GIL: it can overlap other work.

    Parameters
    ----------
    A : (n, n) scipy.sparse matrix
        Only its pattern is read.
    mode : {"auto", "simplicial", "supernodal"}
        As for :func:`factorize` (the factorizations must use the same).

    Returns
    -------
    Analysis or None

    Examples
    --------
    >>> import scipy.sparse as sp, o3dheat.spectral.linalg as la
    >>> a = la.analyze(sp.identity(3, format="csc"))
    >>> a is None or a.n
    3
    """
    mode = _auto_mode(mode, A.shape[0])
    lib = _library()
    if lib is None:
        return None
    try:
        return Analysis(lib, A, mode)
    except OutOfMemory:
        raise
    except Exception as e:  # noqa: BLE001 - too big for the binding...: each factorization analyses itself
        log.info("CHOLMOD analysis unavailable (%s): each factorization analyses its own matrix", e)
        return None


def _auto_mode(mode, n):
    if mode not in MODES:
        raise SolverError(f"unknown mode {mode!r}: use one of {MODES}")
    if mode == "auto":
        return "supernodal" if n >= SUPERNODAL_MIN_N else "simplicial"
    return mode


def _cholmod(A, mode, analysis=None):
    lib = _library()
    if lib is not None:
        try:
            return _fallback_solve(_CholmodFactor(lib, A, mode, analysis), A, mode)
        except (OutOfMemory, _NotPositiveDefinite):
            raise  # a property of the matrix or of the machine: scikit-sparse would fail alike
        except Exception as e:  # noqa: BLE001 - too big for the int32 interface, another layout...
            _warn_binding(e)
    return _sksparse(A, mode)


def _warn_binding(e):
    reason = f"{type(e).__name__}: {e}"
    level = logging.INFO if ("binding", reason) in _WARNED else logging.WARNING
    _WARNED.add(("binding", reason))
    log.log(level, "CHOLMOD through ctypes failed (%s): scikit-sparse's own solver instead (one thread)", reason)


def _fallback_solve(factor, A, mode):
    """``factor.solve``, replaced for good by scikit-sparse's solver when a solve fails in the
    binding (the matrix is kept for that: about a tenth of the factor's memory)."""
    state = {"solve": None}

    def solve(b, out=None):
        if state["solve"] is None:
            try:
                return factor.solve(b, out=out)
            except (OutOfMemory, MemoryError):
                raise
            except Exception as e:  # noqa: BLE001 - any failure of the binding
                _warn_binding(e)
                state["solve"] = _sksparse(A, mode)
        x = state["solve"](b)
        if out is None:
            return x
        np.copyto(out, x)
        return out

    solve.into = lambda b, out: solve(b, out)
    solve.nbytes = getattr(factor, "nbytes", 0)
    solve.release = factor.release
    return solve


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
    except (CholmodOutOfMemoryError, CholmodTooLargeError) as e:
        raise OutOfMemory(f"CHOLMOD ran out of memory factorizing the {A.shape[0]} x {A.shape[0]} matrix ({e}): "
                          "use a smaller mesh") from e
    return f.solve_A


def _factor_nnz(handle, n):
    """Nonzeros of the Cholesky factor an analysis (``cholmod_analyze``) predicts, from its column
    counts; None when the factor holds none."""
    counts = _field(handle, "factor.ColCount").value
    if not counts:
        return None
    return int(np.ctypeslib.as_array(ctypes.cast(counts, ctypes.POINTER(ctypes.c_int32)), shape=(n,))
               .astype(np.int64).sum())


def cholespy_bytes(A):
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
    lib = _library()
    if lib is not None:
        try:
            a = Analysis(lib, sp.csc_matrix(A), "supernodal")
            lnz = _factor_nnz(a.handle, n)
            if lnz is not None:
                return 40 * lnz + 64 * n
        except OutOfMemory:
            raise
        except Exception:  # noqa: BLE001 - too big for the binding: the bound below
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


def factorize(A, backend="auto", mode="auto", analysis=None):
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
    SolverError
        ``A`` is not square or has non-finite entries, the requested backend is missing, or
        every backend failed.

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
        raise SolverError(f"unknown backend {backend!r}: use 'auto' or one of {BACKENDS}")
    A = sp.csc_matrix(A, dtype=np.float64)
    if A.shape[0] != A.shape[1]:
        raise SolverError(f"the matrix to factorize must be square, got shape {A.shape}")
    mode = _auto_mode(mode, A.shape[0])
    if not np.all(np.isfinite(A.data)):
        raise SolverError("the matrix to factorize has NaN or infinite entries: check the mesh "
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
