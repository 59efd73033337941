"""The memory this process may still use, and the check made before large work: :func:`check_memory`.

Entry points: :func:`available_memory`, :func:`memory_limits` (the system's memory, a memory
cgroup's limit, a Dask worker's, ``ulimit -v``), :func:`check_memory`, which raises
:class:`~o3dheat.errors.OutOfMemory` when an estimate exceeds the tightest of them.
"""

from __future__ import annotations

from collections.abc import Callable

from o3dheat import parallel
from o3dheat.errors import OutOfMemory

__all__ = ["available_memory", "memory_limits", "check_memory", "give_back", "on_shortage", "peak_memory",
           "THREAD_ADDRESS_SPACE"]


def available_memory() -> int | None:
    """Bytes this process may still allocate: the smallest of what each known limit leaves (see
    :func:`memory_limits`); None when no limit is known.

    Examples
    --------
    >>> import o3dheat.memory as mm
    >>> m = mm.available_memory(); m is None or m > 0
    True
    """
    room = memory_limits()
    return min(room.values()) if room else None


#: address space mapped by a thread beyond the memory it uses (bytes): an 8 MiB stack, a 64 MiB
#: malloc arena and OpenBLAS's 32 MiB buffer (measured: the peak address space of an eigensolve
#: exceeds its resident peak by about 1 GiB on 2 cores, whatever the mesh size)
THREAD_ADDRESS_SPACE = 104 * 2**20


def memory_limits() -> dict[str, int]:
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
    >>> import o3dheat.memory as mm
    >>> room = mm.memory_limits()
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


def give_back() -> None:
    """Return the memory that C libraries freed to the system (glibc's ``malloc_trim(0)``; nothing
    where the C library is another).

    Libraries that make many mid-sized allocations (METIS's ordering, fast-simplification's
    decimation) leave their freed memory in the C heap, still counted in the process' resident
    size and no longer in the system's available memory, which :func:`check_memory` reads:
    measured 234 bytes per vertex after the METIS analysis of a 1M-vertex ellipsoid (605 -> 371
    held). Called after those steps; it takes milliseconds.

    Examples
    --------
    >>> from o3dheat.memory import give_back
    >>> give_back()
    """
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


def _malloc_trim():
    """The C library's ``malloc_trim`` (glibc), or None (another C library)."""
    global _TRIM
    if _TRIM is False:
        import ctypes
        import ctypes.util

        try:
            _TRIM = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
            _TRIM.argtypes, _TRIM.restype = [ctypes.c_size_t], ctypes.c_int
        except (OSError, AttributeError):
            _TRIM = None
    return _TRIM


_TRIM = False  # not looked up yet


def on_shortage(release: Callable[[], object]) -> None:
    """Register ``release``, which frees memory held only for reuse (the in-memory cache of
    spectra and factors registers itself): :func:`check_memory` calls it before it refuses work,
    then measures again. A module above this one hands its memory back without this module
    importing it.

    Parameters
    ----------
    release : callable
        Called without arguments; registered once however often it is passed.

    Examples
    --------
    >>> import o3dheat.memory as mm
    >>> mm.on_shortage(lambda: None)
    """
    if release not in _SHORTAGE:
        _SHORTAGE.append(release)


_SHORTAGE: list[Callable[[], object]] = []


def check_memory(needed: int, what: str, advice: str, *, release: Callable[[], object] | None = None) -> None:
    """Raise :class:`~o3dheat.errors.OutOfMemory` when ``needed`` bytes exceed what this process may allocate
    (the message names the limit: the system's memory, a cgroup's, a Dask worker's, ulimit -v).
    Before refusing, what is held only for reuse is released (:func:`on_shortage`: the in-memory
    cache of spectra and factors) and the memory measured again.

    Parameters
    ----------
    needed : int
        Bytes the work is estimated to need.
    what : str
        The work, as the message names it.
    advice : str
        What to do instead, ending the message.
    release : callable, optional
        The caller's own memory held for reuse, released with the registered ones before a refusal.

    Raises
    ------
    OutOfMemory
        ``needed`` exceeds the tightest limit of :func:`memory_limits`, even after the release.

    Examples
    --------
    >>> import o3dheat.memory as mm
    >>> mm.check_memory(1024, "a small task", "nothing")         # fits: no error
    """
    room = memory_limits()
    releases = _SHORTAGE + ([release] if release is not None else [])
    if room and needed > min(room.values()) and releases:  # what is held for reuse goes first
        import gc

        for free in releases:
            free()
        gc.collect()
        give_back()
        room = memory_limits()
    name = min(room, key=room.get) if room else None
    if name is not None and needed > room[name]:
        have = room[name]
        where = _LIMIT_NAMES.get(name, "")
        raise OutOfMemory(f"{what} needs about {needed / 2**30:.2f} GiB, but only {have / 2**30:.2f} GiB "
                          f"are available{where}: {advice}")


def peak_memory(n: int, k: int = 100, block: int = 8, factor: int | None = None) -> int:
    """Estimated peak memory of an iterative :func:`o3dheat.spectral.spectrum.eigensolve`, in bytes.

    The Lanczos basis (``max(2k, k + 4 block) + block`` vectors of ``n`` float64), the Cholesky
    factorization's peak ``factor`` (:attr:`o3dheat.spectral.linalg.Analysis.nbytes`, known from the
    symbolic analysis before the factor is made; without it 1800 bytes per vertex, what a uniform
    torus's AMD factor takes), 1350 bytes per vertex for the operators, their renumbered copies
    and the blocks of vectors, and 64 MiB. Calibrated against the measured peaks of k = 100 at
    250k, 1M, 2M and 4M vertices on a curvature-adaptive and a uniform mesh
    (``scripts/bench_memory.py``, ``docs/details/large.md``): 4-19% above each. A mesh fits when this is below the memory
    available; eigensolve refuses with :class:`o3dheat.errors.OutOfMemory` otherwise.

    Parameters
    ----------
    n : int
        Vertices.
    k, block : int
        As for :func:`o3dheat.spectral.spectrum.eigensolve`.
    factor : int, optional
        The factorization's peak bytes, from its symbolic analysis.

    Returns
    -------
    int

    Examples
    --------
    >>> from o3dheat.memory import peak_memory
    >>> round(peak_memory(1_000_000, 100) / 2**30, 1), round(peak_memory(1_000_000, 100, factor=691 * 2**20) / 2**30, 1)
    (4.5, 3.5)
    """
    basis = min(n, max(2 * k, k + 4 * block)) + block
    return int(n * (8 * basis + 1350) + (1800 * n if factor is None else factor) + 64 * 2**20)
