"""o3dheat.spectral.linalg: CHOLMOD through ctypes (threaded block solves), its fallbacks."""

import gc
import sys
import threading

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import irregular

import o3dheat.spectral.linalg as la
from o3dheat import parallel
from o3dheat.errors import SolverError
from o3dheat.spectral import fem

needs_cholmod = pytest.mark.skipif("cholmod" not in la.available_backends(), reason="scikit-sparse not installed")


@pytest.fixture(scope="module")
def spd():
    V, F = irregular()
    L, B = fem.stiffness_matrix(V, F), fem.mass_matrix(V, F)
    return sp.csc_matrix(L + 0.1 * B)


@needs_cholmod
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="binding checked on Linux")
def test_the_ctypes_binding_is_used():
    # the library scikit-sparse loaded, bound and self-checked (a failed check would fall back)
    assert la._library() is not None


@needs_cholmod
@pytest.mark.parametrize("mode", ["simplicial", "supernodal"])
def test_threaded_solves_are_bit_identical_and_agree_with_scikit_sparse(spd, mode):
    from sksparse.cholmod import cholesky

    b = np.random.default_rng(0).standard_normal((spd.shape[0], 8))
    f = la.factorize(spd, backend="cholmod", mode=mode)
    assert f.backend == "cholmod"
    out = {}
    b = np.concatenate([b, b[:, :3]], axis=1)  # 11 columns: groups of 4, 4, 3
    for t in (1, 2, 3, 8):
        with parallel.threads(t):
            out[t] = f.solve(b)
    for t in (2, 3, 8):
        np.testing.assert_array_equal(out[t], out[1])
    ref = cholesky(spd).solve_A(b)
    np.testing.assert_allclose(out[1], ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(spd @ out[1], b, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(f.solve(b[:, 3]), out[1][:, 3], rtol=1e-10, atol=1e-12)  # one vector
    assert f.solve(b[:, :0]).shape == (spd.shape[0], 0)


@needs_cholmod
@pytest.mark.parametrize("mode", ["simplicial", "supernodal", "auto"])
def test_modes(spd, mode):
    b = np.ones((spd.shape[0], 3))
    np.testing.assert_allclose(spd @ la.factorize(spd, backend="cholmod", mode=mode).solve(b), b, atol=1e-9)


def test_auto_mode_is_supernodal_for_large_matrices_only():
    assert la._auto_mode("auto", la.SUPERNODAL_MIN_N - 1) == "simplicial"
    assert la._auto_mode("auto", la.SUPERNODAL_MIN_N) == "supernodal"
    assert la._auto_mode("simplicial", 10**7) == "simplicial"
    with pytest.raises(SolverError, match="unknown mode"):
        la.factorize(sp.identity(3, format="csc"), mode="fast")


def test_the_offsets_table_names_every_field_the_binding_touches():
    import ctypes
    import inspect
    import re

    src = inspect.getsource(la)
    used = set(re.findall(r'_field\([^,]+, "([a-zA-Z_.]+)"\)', src)) | set(re.findall(r'"(common\.[a-z_]+)"', src))
    assert used == set(la._OFFSETS)  # every field read or written is in the table, and only those
    for name, (offset, ctype, _) in la._OFFSETS.items():
        row = re.search(rf"#\s+cholmod_{re.escape(name)}\s+\S+( \*)?\s+(\d+)", src)
        assert row and int(row.group(2)) == offset, name  # the commented table says the same offset
        assert offset % ctypes.alignment(ctype) == 0


def _bound_or_skip():
    lib = la._library()
    if lib is None:
        pytest.skip("no ctypes binding here")
    return lib


@needs_cholmod
def test_an_unexpected_layout_is_detected_and_scikit_sparse_takes_over(spd, monkeypatch, caplog):
    _bound_or_skip()
    b = np.ones((spd.shape[0], 3))
    # a cholmod_common whose supernodal_switch is not where the table says (another CHOLMOD)
    offset, ctype, _ = la._OFFSETS["common.supernodal_switch"]
    monkeypatch.setitem(la._OFFSETS, "common.supernodal_switch", (offset + 8, ctype, 40.0))
    monkeypatch.setattr(la, "_LIB", None)  # bind again: the self-check sees the layout
    assert la._library() is None
    f = la.factorize(spd, backend="cholmod")
    assert f.backend == "cholmod"
    np.testing.assert_allclose(spd @ f.solve(b), b, atol=1e-9)


@needs_cholmod
@pytest.mark.parametrize("failure", ["cholmod_start", "layout", "solve"])
def test_any_binding_failure_falls_back_to_scikit_sparse(spd, monkeypatch, caplog, failure):
    lib = _bound_or_skip()
    b = np.random.default_rng(2).standard_normal((spd.shape[0], 5))
    expected = la.factorize(spd, backend="cholmod").solve(b)
    if failure == "cholmod_start":  # the library is bound, but a start fails later (a SolverError before)
        monkeypatch.setattr(lib, "cholmod_start", lambda c: 0)
    elif failure == "layout":
        monkeypatch.setitem(la._OFFSETS, "common.print", (144, la._OFFSETS["common.print"][1], 7))
    else:
        def broken(self, j, b, out):
            raise la._BindingError("CHOLMOD solve failed")

        monkeypatch.setattr(la._CholmodFactor, "_solve_columns", broken)
    la._WARNED.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        f = la.factorize(spd, backend="cholmod")
        got = f.solve(b)
        again = f.solve(b)  # the fallback stays
    assert f.backend == "cholmod"
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(got, again)
    assert "scikit-sparse's own solver" in caplog.text


@needs_cholmod
def test_a_matrix_that_is_not_positive_definite_does_not_retry_the_binding(monkeypatch):
    _bound_or_skip()
    called = []
    monkeypatch.setattr(la, "_sksparse", lambda A, mode: called.append(mode))
    with pytest.raises(SolverError, match="not positive definite"):
        la.factorize(sp.diags([1.0, 0.0, 2.0, 3.0], format="csc"), backend="cholmod")
    assert called == []


@needs_cholmod
@pytest.mark.parametrize("mode", ["simplicial", "supernodal"])
def test_singular_matrix_is_reported(mode):
    A = sp.diags([1.0, 0.0, 2.0, 3.0], format="csc")
    with pytest.raises(SolverError, match="not positive definite"):
        la.factorize(A, backend="cholmod", mode=mode)


@needs_cholmod
def test_factor_memory_is_freed(spd):
    lib = la._library()
    if lib is None:
        pytest.skip("no ctypes binding here")
    f = la._CholmodFactor(lib, spd, "simplicial")
    f.solve(np.ones((spd.shape[0], 4)), threads=2)
    finalizer = f._finalizer
    assert finalizer.alive
    del f
    gc.collect()
    assert not finalizer.alive


@needs_cholmod
def test_concurrent_solves_from_user_threads(spd):
    f = la.factorize(spd, backend="cholmod")
    rng = np.random.default_rng(1)
    rhs = [rng.standard_normal((spd.shape[0], 6)) for _ in range(8)]
    expected = [f.solve(b) for b in rhs]
    got = [None] * len(rhs)

    def work(i):
        with parallel.threads(3):
            got[i] = f.solve(rhs[i])

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(rhs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_array_equal(e, g)


@needs_cholmod
def test_scikit_sparse_when_the_binding_is_unavailable(spd, monkeypatch):
    b = np.ones((spd.shape[0], 2))
    monkeypatch.setattr(la, "_LIB", False)
    f = la.factorize(spd, backend="cholmod")
    assert f.backend == "cholmod"
    np.testing.assert_allclose(spd @ f.solve(b), b, atol=1e-9)
    with pytest.raises(SolverError, match="cholmod"):  # scikit-sparse's error, in the summary
        la.factorize(sp.diags([1.0, 0.0, 2.0], format="csc"), backend="cholmod")


def test_wrong_right_hand_side_is_named(spd):
    f = la.factorize(spd)
    with pytest.raises(SolverError, match="rows"):
        f.solve(np.ones(spd.shape[0] + 1))


@pytest.mark.parametrize("A, match", [
    (sp.csc_matrix(np.ones((3, 2))), "square"),
    (sp.diags([1.0, np.nan, 2.0], format="csc"), "NaN or infinite"),
    (sp.diags([1.0, np.inf, 2.0], format="csc"), "NaN or infinite"),
])
def test_bad_matrices_are_named(A, match):
    with pytest.raises(SolverError, match=match):
        la.factorize(A)


def test_the_input_matrix_is_not_reordered():
    A = sp.csc_matrix(np.array([[4.0, 1, 0], [1, 4, 1], [0, 1, 4]]))
    A.indices[:2], A.data[:2] = A.indices[:2][::-1].copy(), A.data[:2][::-1].copy()
    A.has_sorted_indices = False
    before = A.indices.copy(), A.data.copy()
    x = la.factorize(A).solve(np.ones(3))
    np.testing.assert_array_equal(A.indices, before[0])
    np.testing.assert_array_equal(A.data, before[1])
    np.testing.assert_allclose(A @ x, 1.0, rtol=1e-12)


def test_memory_is_checked_before_factorizing_and_out_of_memory_never_falls_back(monkeypatch):
    import scipy.sparse as sp

    import o3dheat.spectral.linalg as la

    A = sp.diags([np.full(99, -1.0), np.full(100, 3.0), np.full(99, -1.0)], [-1, 0, 1], format="csc")
    monkeypatch.setattr(la, "memory_limits", lambda: {"system": 1000})  # bytes
    if la._library() is not None:
        with pytest.raises(la.OutOfMemory, match="Cholesky factor .* needs about"):
            la.factorize(A, backend="cholmod")
    tried = []
    monkeypatch.setattr(la, "_cholespy", lambda A: tried.append("cholespy"))

    def oom(A, mode, analysis=None):
        raise la.OutOfMemory("CHOLMOD ran out of memory")

    monkeypatch.setattr(la, "_cholmod", oom)
    with pytest.raises(la.OutOfMemory):
        la.factorize(A)
    assert tried == []  # cholespy would need as much memory, and crashes when it does not get it
    monkeypatch.setattr(la, "_cholmod", lambda A, mode, analysis=None: (_ for _ in ()).throw(MemoryError()))
    with pytest.raises(la.OutOfMemory, match="ran out of memory"):
        la.factorize(A)
    assert tried == []


def test_available_memory_sees_an_address_space_limit():
    import subprocess
    import sys

    code = ("import resource, o3dheat.spectral.linalg as la; resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30));"
            "m = la.available_memory(); print(m is not None and m < 4 * 2**30)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-500:]


@pytest.mark.parametrize("backend", la.available_backends())
def test_solve_into_a_given_array(spd, backend):
    f = la.factorize(spd, backend=backend)
    b = np.random.default_rng(4).standard_normal((spd.shape[0], 6))
    out = np.full(b.shape, np.nan)
    x = f.solve(b, out=out)
    assert x is out
    np.testing.assert_array_equal(out, f.solve(b))
    for bad in (np.empty((spd.shape[0], 5)), np.empty(b.shape, order="F"), np.empty(b.shape, np.float32)):
        with pytest.raises(SolverError, match="out must be"):
            f.solve(b, out=bad)


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
    assert la._cgroup_room(proc, root) == 1000000 - 600000 + 80000 - 5000  # shared memory is not reclaimed


def test_cgroup_v2_without_limit_and_with_a_tighter_parent(tmp_path):
    proc, root = _cgroup_tree(tmp_path, "0::/user.slice/job", {
        "user.slice/job": {"memory.max": "max\n", "memory.current": "5\n"},
        "user.slice": {"memory.max": "2000\n", "memory.current": "1500\n"},
        ".": {"memory.max": "max\n"}})
    assert la._cgroup_room(proc, root) == 500  # the parent's limit binds
    proc, root = _cgroup_tree(tmp_path / "b", "0::/", {".": {"memory.max": "max\n", "memory.current": "5\n"}})
    assert la._cgroup_room(proc, root) is None


def test_cgroup_v1_container_without_namespace_and_unlimited(tmp_path):
    # the group's path (the host's) does not exist in the container: its own group is the root
    proc, root = _cgroup_tree(tmp_path, "12:cpu:/\n4:memory:/docker/abc", {
        "memory": {"memory.limit_in_bytes": "3000\n", "memory.usage_in_bytes": "1000\n",
                   "memory.stat": "cache 9\ntotal_cache 150\ntotal_shmem 50\ntotal_inactive_file 100\n"}})
    assert la._cgroup_room(proc, root) == 2100
    proc, root = _cgroup_tree(tmp_path / "b", "4:memory:/", {
        "memory": {"memory.limit_in_bytes": "9223372036854771712\n", "memory.usage_in_bytes": "1000\n"}})
    assert la._cgroup_room(proc, root) is None
    assert la._cgroup_room(str(tmp_path / "missing"), root) is None


def test_memory_check_names_the_limit_that_binds(monkeypatch):
    monkeypatch.setattr(la, "_cgroup_room", lambda: 2**30)
    assert la.memory_limits()["cgroup"] == 2**30 and la.available_memory() <= 2**30
    with pytest.raises(la.OutOfMemory, match=r"needs about 2.00 GiB, but only 1.00 GiB .*cgroup: a container's"):
        la.check_memory(2**31, "this eigensolve", "decimate the mesh")


def test_dask_worker_memory_limit_is_a_limit(monkeypatch):
    distributed = pytest.importorskip("distributed")
    import types

    assert la._dask_worker_room() is None  # not in a worker
    worker = types.SimpleNamespace(memory_manager=types.SimpleNamespace(memory_limit=10 * 2**30),
                                   nanny="tcp://127.0.0.1:1")
    monkeypatch.setattr(distributed, "get_worker", lambda: worker)
    left = la._dask_worker_room()
    assert 0 < left < 0.95 * 10 * 2**30 and la.memory_limits()["Dask worker"] == pytest.approx(left, rel=0.01)
    import dask

    with dask.config.set({"distributed.worker.memory.terminate": False}):  # never restarted: no limit
        assert la._dask_worker_room() is None
    worker.nanny = None  # nothing restarts a worker without a nanny (in-process, --no-nanny)
    assert la._dask_worker_room() is None
    worker.nanny, worker.memory_manager.memory_limit = "tcp://127.0.0.1:1", None
    assert la._dask_worker_room() is None


def test_in_process_dask_workers_have_no_memory_limit_to_fear():
    pytest.importorskip("distributed")
    from distributed import Client

    with Client(processes=False, n_workers=1, memory_limit="100MB", dashboard_address=None) as client:
        assert "Dask worker" not in client.submit(la.memory_limits, pure=False).result()


@pytest.mark.parametrize("binding", [True, False])
def test_cholespy_memory_is_estimated_before_it_starts(monkeypatch, binding):
    """Issue 22: factorize(backend="cholespy") segfaulted when memory ran out (cholespy reports
    nothing). Its need is estimated first (CHOLMOD's symbolic analysis when the binding exists,
    a mesh bound otherwise), and refused with OutOfMemory before cholespy is called."""
    import scipy.sparse as sp

    import o3dheat.spectral.linalg as la

    pytest.importorskip("cholespy")
    import cholespy

    A = sp.diags([np.full(999, -1.0), np.full(1000, 3.0), np.full(999, -1.0)], [-1, 0, 1], format="csc")
    if not binding:
        monkeypatch.setattr(la, "_library", lambda: None)
    need = la.cholespy_bytes(A)
    assert need > 64 * 1000
    ok = la.factorize(A, backend="cholespy")  # plenty of memory: it works
    np.testing.assert_allclose(A @ ok.solve(np.ones(1000)), 1.0)
    monkeypatch.setattr(la, "memory_limits", lambda: {"system": need - 1})
    monkeypatch.setattr(cholespy, "CholeskySolverD", lambda *a: pytest.fail("cholespy was started"))
    with pytest.raises(la.OutOfMemory, match="cholespy's factorization of the 1000 x 1000 matrix needs about"):
        la.factorize(A, backend="cholespy")
    # a mesh Laplacian: the estimate covers what cholespy was measured to use (38-60 B per n log2 n)
    from conftest import icosphere

    import o3dheat.spectral.fem as fem

    V, F = icosphere(4)
    L, B, _ = fem.operators(V, F, "consistent")
    assert la.cholespy_bytes(L + 1e-3 * B) >= 60 * len(V) * np.log2(len(V)) or binding


def test_the_address_space_limit_keeps_a_reserve_per_thread():
    """Issue 22: under ulimit -v a 200k-vertex k=300 eigensolve passed the estimate, then could not
    start a thread or OpenBLAS aborted the process: the threads' stacks, arenas and buffers count
    against the address space. The room left now deducts them (measured by hand: refused at 2.0
    and 2.2 GB, completes at 2.3, 2.4 and 3.0 GB)."""
    import subprocess
    import sys

    code = ("import resource, o3dheat.spectral.linalg as la, o3dheat.parallel as p;"
            "resource.setrlimit(resource.RLIMIT_AS, (6 * 2**30, 6 * 2**30));"
            "room = la.memory_limits()['address space']; left = 6 * 2**30 - la._statm(0);"
            "print(abs(left - room - la.THREAD_ADDRESS_SPACE * (p.get_threads() + 1)) < 64 * 2**20)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-500:]
