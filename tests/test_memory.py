"""o3dheat.memory: the limits on this process's memory (system, cgroup, Dask worker, ulimit -v)."""

import pytest

import o3dheat.memory as mm
from o3dheat.errors import OutOfMemory


def test_available_memory_sees_an_address_space_limit():
    import subprocess
    import sys

    code = ("import resource, o3dheat.memory as mm; resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30));"
            "m = mm.available_memory(); print(m is not None and m < 4 * 2**30)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-500:]


def _cgroup_tree(tmp_path, proc_line, groups):
    """A fake /proc/self/cgroup and cgroup mount: ``groups`` maps a folder to its files."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "cgroup").write_text(proc_line + "\n")
    for folder, files in groups.items():
        d = tmp_path / "fs" / folder
        d.mkdir(parents=True, exist_ok=True)
        for name, text in files.items():
            (d / name).write_text(text)
    return str(tmp_path / "cgroup"), str(tmp_path / "fs")


def test_cgroup_v2_limit_counts_usage_but_not_reclaimable_cache(tmp_path):
    proc, root = _cgroup_tree(tmp_path, "0::/", {
        ".": {"memory.max": "1000000\n", "memory.current": "600000\n",
              "memory.stat": "anon 1\nfile 80000\nactive_file 30000\ninactive_file 50000\nshmem 5000\n"}})
    assert mm._cgroup_room(proc, root) == 1000000 - 600000 + 80000 - 5000  # shared memory is not reclaimed


def test_cgroup_v2_without_limit_and_with_a_tighter_parent(tmp_path):
    proc, root = _cgroup_tree(tmp_path, "0::/user.slice/job", {
        "user.slice/job": {"memory.max": "max\n", "memory.current": "5\n"},
        "user.slice": {"memory.max": "2000\n", "memory.current": "1500\n"},
        ".": {"memory.max": "max\n"}})
    assert mm._cgroup_room(proc, root) == 500  # the parent's limit binds
    proc, root = _cgroup_tree(tmp_path / "b", "0::/", {".": {"memory.max": "max\n", "memory.current": "5\n"}})
    assert mm._cgroup_room(proc, root) is None


def test_cgroup_v1_container_without_namespace_and_unlimited(tmp_path):
    # the group's path (the host's) does not exist in the container: its own group is the root
    proc, root = _cgroup_tree(tmp_path, "12:cpu:/\n4:memory:/docker/abc", {
        "memory": {"memory.limit_in_bytes": "3000\n", "memory.usage_in_bytes": "1000\n",
                   "memory.stat": "cache 9\ntotal_cache 150\ntotal_shmem 50\ntotal_inactive_file 100\n"}})
    assert mm._cgroup_room(proc, root) == 2100
    proc, root = _cgroup_tree(tmp_path / "b", "4:memory:/", {
        "memory": {"memory.limit_in_bytes": "9223372036854771712\n", "memory.usage_in_bytes": "1000\n"}})
    assert mm._cgroup_room(proc, root) is None
    assert mm._cgroup_room(str(tmp_path / "missing"), root) is None


def test_memory_check_names_the_limit_that_binds(monkeypatch):
    monkeypatch.setattr(mm, "_cgroup_room", lambda: 2**30)
    assert mm.memory_limits()["cgroup"] == 2**30 and mm.available_memory() <= 2**30
    with pytest.raises(OutOfMemory, match=r"needs about 2.00 GiB, but only 1.00 GiB .*cgroup: a container's"):
        mm.check_memory(2**31, "this eigensolve", "decimate the mesh")


def test_dask_worker_memory_limit_is_a_limit(monkeypatch):
    distributed = pytest.importorskip("distributed")
    import types

    assert mm._dask_worker_room() is None  # not in a worker
    worker = types.SimpleNamespace(memory_manager=types.SimpleNamespace(memory_limit=10 * 2**30),
                                   nanny="tcp://127.0.0.1:1")
    monkeypatch.setattr(distributed, "get_worker", lambda: worker)
    left = mm._dask_worker_room()
    assert 0 < left < 0.95 * 10 * 2**30 and mm.memory_limits()["Dask worker"] == pytest.approx(left, rel=0.01)
    import dask

    with dask.config.set({"distributed.worker.memory.terminate": False}):  # never restarted: no limit
        assert mm._dask_worker_room() is None
    worker.nanny = None  # nothing restarts a worker without a nanny (in-process, --no-nanny)
    assert mm._dask_worker_room() is None
    worker.nanny, worker.memory_manager.memory_limit = "tcp://127.0.0.1:1", None
    assert mm._dask_worker_room() is None


def test_in_process_dask_workers_have_no_memory_limit_to_fear():
    pytest.importorskip("distributed")
    from distributed import Client

    with Client(processes=False, n_workers=1, memory_limit="100MB", dashboard_address=None) as client:
        assert "Dask worker" not in client.submit(mm.memory_limits, pure=False).result()


def test_the_address_space_limit_keeps_a_reserve_per_thread():
    """Issue 22: under ulimit -v a 200k-vertex k=300 eigensolve passed the estimate, then could not
    start a thread or OpenBLAS aborted the process: the threads' stacks, arenas and buffers count
    against the address space. The room left now deducts them (measured by hand: refused at 2.0
    and 2.2 GB, completes at 2.3, 2.4 and 3.0 GB)."""
    import subprocess
    import sys

    code = ("import resource, o3dheat.memory as mm, o3dheat.parallel as p;"
            "resource.setrlimit(resource.RLIMIT_AS, (6 * 2**30, 6 * 2**30));"
            "room = mm.memory_limits()['address space']; left = 6 * 2**30 - mm._statm(0);"
            "print(abs(left - room - mm.THREAD_ADDRESS_SPACE * (p.get_threads() + 1)) < 64 * 2**20)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-500:]


def test_give_back_returns_the_c_heaps_freed_memory():
    """Issue 35: memory a C library freed in mid-sized blocks stays resident (glibc keeps it in its
    heap, below the last block in use) until give_back: 234 bytes per vertex after METIS at 1M."""
    import ctypes
    import os

    if mm._malloc_trim() is None:
        pytest.skip("not glibc")
    libc = ctypes.CDLL(None)
    libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    page = os.sysconf("SC_PAGE_SIZE")

    def resident():
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * page

    blocks = [libc.malloc(64 * 1024) for _ in range(3000)]  # 192 MiB in blocks under the mmap threshold
    for b in blocks:
        ctypes.memset(b, 1, 64 * 1024)
    for b in blocks[:-1]:
        libc.free(b)  # the last one stays: the heap cannot shrink from its top
    before = resident()
    mm.give_back()
    after = resident()
    libc.free(blocks[-1])
    assert before - after > 100 * 2**20, (before, after)


def test_what_is_cached_for_reuse_makes_room_before_a_refusal(monkeypatch):
    """Issue 35: at 10M vertices the cache kept a flow's 6 GB factor after the flow was gone (it
    keeps its newest entry whatever its size), and later work saw that memory as used. A check
    that does not fit empties the in-memory cache first, then measures again."""
    import numpy as np

    import o3dheat.spectral.cache as cache

    key = ("test", "held for reuse")
    cache.memoized(key, lambda: np.ones(10**6))
    need = 10**9
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": need - 1 if cache.memoized_has(key) else need})
    mm.check_memory(need, "this task", "nothing")  # fits once the cache is empty
    assert not cache.memoized_has(key)
    cache.memoized(key, lambda: np.ones(10))
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": need - 1})
    with pytest.raises(OutOfMemory, match="this task needs about 0.93 GiB"):
        mm.check_memory(need, "this task", "nothing")
    assert not cache.memoized_has(key)  # emptied, and still refused
