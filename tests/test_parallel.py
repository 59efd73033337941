"""o3dheat.parallel: thread count, the shared pool, row-parallel loops."""

import itertools
import multiprocessing
import sys
import threading

import numpy as np
import pytest

from o3dheat import parallel
from o3dheat.errors import MeshError


def test_thread_count_from_environment_and_context(monkeypatch):
    monkeypatch.setenv("O3DHEAT_NUM_THREADS", "3")
    assert parallel.get_threads() == 3
    with parallel.threads(2):
        assert parallel.get_threads() == 2
        with parallel.threads(1):
            assert parallel.get_threads() == 1
        assert parallel.get_threads() == 2
    assert parallel.get_threads() == 3
    monkeypatch.delenv("O3DHEAT_NUM_THREADS")
    assert 1 <= parallel.get_threads() <= 8


@pytest.mark.parametrize("bad", ["0", "-2", "two", "1.5"])
def test_bad_environment_value_is_named(monkeypatch, bad):
    monkeypatch.setenv("O3DHEAT_NUM_THREADS", bad)
    with pytest.raises(MeshError, match="O3DHEAT_NUM_THREADS"):
        parallel.get_threads()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "x", None])
def test_bad_thread_count_is_named(bad):
    with pytest.raises(MeshError, match="positive integer"), parallel.threads(bad):
        pass


def test_row_parts_cover_the_rows():
    for n in (0, 1, 5, 100, 1000):
        parts = parallel.row_parts(n, 64)
        assert parts[0][0] == 0 and parts[-1][1] == n
        assert all(a < z or n == 0 for a, z in parts)
        assert all(p[1] == q[0] for p, q in itertools.pairwise(parts))


def test_run_keeps_order_and_uses_threads():
    seen = set()

    def work(i):
        seen.add(threading.current_thread().name)
        return i * i

    with parallel.threads(4):
        assert parallel.run(work, [(i,) for i in range(10)]) == [i * i for i in range(10)]
    assert len(seen) > 1  # the calling thread and pool threads
    with parallel.threads(1):
        seen.clear()
        assert parallel.run(work, [(i,) for i in range(10)]) == [i * i for i in range(10)]
        assert seen == {threading.current_thread().name}


def test_run_reraises_after_every_thread_finished():
    done = []

    def work(i):
        if i == 0:
            raise ValueError("part 0 failed")
        done.append(i)

    with parallel.threads(3), pytest.raises(ValueError, match="part 0 failed"):
        parallel.run(work, [(i,) for i in range(6)])  # groups (0, 1), (2, 3), (4, 5)
    assert sorted(done) == [2, 3, 4, 5]  # the other groups ran to the end before the raise


def test_nested_run_does_not_deadlock():
    def inner(i):
        return sum(parallel.run(lambda j: j, [(j,) for j in range(4)]))

    with parallel.threads(8):
        assert parallel.run(inner, [(i,) for i in range(16)]) == [6] * 16


def _blas_threads():
    from threadpoolctl import threadpool_info

    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


def test_blas_one_thread_and_back():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(2, user_api="blas"):
        before = _blas_threads()
        if max(before) < 2:
            pytest.skip("BLAS runs one thread here anyway")
        with parallel.blas_one_thread():
            assert set(_blas_threads()) == {1}
        assert _blas_threads() == before


@pytest.fixture
def two_blas_threads():
    """BLAS set to two threads, with no thread holding threadpoolctl's control of OpenBLAS (as in a
    fresh process); put back afterwards."""
    from threadpoolctl import OpenBLASController, ThreadpoolController

    blas = ThreadpoolController().select(user_api="blas")
    limiter = blas.limit(limits=2)
    OpenBLASController.clear_controlling_thread()
    try:
        if min(_blas_threads()) < 2:
            pytest.skip("BLAS cannot run two threads here")
        yield
    finally:
        OpenBLASController.clear_controlling_thread(force=True)
        limiter.restore_original_limits()
        OpenBLASController.clear_controlling_thread()


def test_overlapping_blas_one_thread_blocks_in_threads(two_blas_threads):
    """Issue 30: with threadpoolctl's blocks, the first thread to leave its block put BLAS back on
    two threads under a thread still inside its own (whose results then changed: another rounding),
    and the last left one thread behind for good. The blocks are counted: one thread inside any
    block, the setting found by the first restored by the last."""
    a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
    seen = {}

    def first():
        with parallel.blas_one_thread():
            a_in.set()
            b_in.wait(10)
            seen["a"] = _blas_threads()
        a_out.set()

    def second():
        a_in.wait(10)
        with parallel.blas_one_thread():
            b_in.set()
            a_out.wait(10)  # the first block has ended: this one goes on
            seen["b"] = _blas_threads()

    threads = [threading.Thread(target=f) for f in (first, second)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(20)
    assert set(seen["a"]) == {1}
    assert set(seen["b"]) == {1}, "BLAS threads came back under a block still running"
    assert min(_blas_threads()) == 2, "the blocks left BLAS on one thread"
    with parallel.blas_one_thread():  # and the next block, in this thread, still works
        assert set(_blas_threads()) == {1}
    assert min(_blas_threads()) == 2


def _child(q):
    with parallel.threads(2):
        q.put(parallel.run(lambda i: i + 1, [(i,) for i in range(4)]))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork")
def test_pool_works_after_fork():
    with parallel.threads(2):
        parallel.run(lambda i: i, [(i,) for i in range(4)])  # the parent's pool exists
    ctx = multiprocessing.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_child, args=(q,))
    p.start()
    p.join(60)
    assert p.exitcode == 0 and q.get(timeout=5) == [1, 2, 3, 4]


def test_reductions_do_not_depend_on_the_thread_count(monkeypatch):
    import scipy.sparse as sp

    from o3dheat.spectral.lanczos import _Rows

    monkeypatch.setattr(parallel, "CHUNK", 64)
    rng = np.random.default_rng(0)
    X, Y = rng.standard_normal((1000, 30)), rng.standard_normal((1000, 8))
    M = sp.random(1000, 1000, density=0.01, random_state=1, format="csr")
    rows = _Rows(M)
    assert len(rows.parts) == 16
    out = {}
    for t in (1, 2, 3):
        with parallel.threads(t):
            Z = Y.copy()
            rows.sub(Z, X[:, :8], np.eye(8))
            out[t] = (rows.inner(X, Y), rows.dot(X, np.ones((30, 4))), rows.spmul(0, Y), Z)
    for t in (2, 3):
        for a, b in zip(out[1], out[t], strict=True):
            np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(out[1][0], X.T @ Y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[1][2], M @ Y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[1][3], Y - X[:, :8], rtol=1e-12, atol=1e-12)


def test_thread_setting_belongs_to_the_calling_thread():
    seen = {}
    gate = threading.Barrier(2)

    def worker(name, n):
        with parallel.threads(n):
            gate.wait()  # both inside their with blocks at once
            seen[name] = parallel.get_threads()
            gate.wait()

    a = threading.Thread(target=worker, args=("a", 1))
    b = threading.Thread(target=worker, args=("b", 3))
    a.start(), b.start()
    a.join(), b.join()
    assert seen == {"a": 1, "b": 3}
    with parallel.threads(2):
        assert parallel.get_threads() == 2


def test_threads_that_cannot_start_mean_fewer_threads_not_an_error(monkeypatch, caplog):
    """Issue 22: under ulimit -v, starting a pool thread raised "can't start new thread" in the
    middle of a computation. The pool's threads are started at once; if only some (or none)
    start, the work runs on those, in the same order, with one warning."""
    import logging
    import threading

    import o3dheat.parallel as par

    real_start, started = threading.Thread.start, []

    def start(self):
        if self.name.startswith(par._PREFIX) and len(started) >= allowed:
            raise RuntimeError("can't start new thread")
        started.append(self.name)
        real_start(self)

    for allowed in (0, 1):
        started.clear()
        monkeypatch.setattr(threading.Thread, "start", start)
        monkeypatch.setattr(par, "_POOL", None)
        with par.threads(4), caplog.at_level(logging.WARNING, logger="o3dheat"):
            caplog.clear()
            out = par.run(lambda a, z: (a, z), par.row_parts(100, 10))
            assert par.background(sum, [1, 2]).result() == 3
        assert out == par.row_parts(100, 10)
        assert f"could start only {allowed} of 3 worker threads" in caplog.text
        monkeypatch.undo()
    monkeypatch.setattr(par, "_POOL", None)
