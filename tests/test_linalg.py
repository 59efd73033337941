"""o3dheat.linalg: CHOLMOD through ctypes (threaded block solves), its fallbacks."""

import gc
import sys
import threading

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import irregular

import o3dheat.linalg as la
from o3dheat import fem, parallel
from o3dheat.errors import SolverError

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
def test_threaded_solves_are_bit_identical_and_agree_with_scikit_sparse(spd):
    from sksparse.cholmod import cholesky

    b = np.random.default_rng(0).standard_normal((spd.shape[0], 8))
    f = la.factorize(spd, backend="cholmod")
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
    for e, g in zip(expected, got):
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

    import o3dheat.linalg as la

    A = sp.diags([np.full(99, -1.0), np.full(100, 3.0), np.full(99, -1.0)], [-1, 0, 1], format="csc")
    monkeypatch.setattr(la, "available_memory", lambda: 1000)  # bytes
    if la._library() is not None:
        with pytest.raises(la.OutOfMemory, match="Cholesky factor .* needs about"):
            la.factorize(A, backend="cholmod")
    tried = []
    monkeypatch.setattr(la, "_cholespy", lambda A: tried.append("cholespy"))

    def oom(A, mode):
        raise la.OutOfMemory("CHOLMOD ran out of memory")

    monkeypatch.setattr(la, "_cholmod", oom)
    with pytest.raises(la.OutOfMemory):
        la.factorize(A)
    assert tried == []  # cholespy would need as much memory, and crashes when it does not get it
    monkeypatch.setattr(la, "_cholmod", lambda A, mode: (_ for _ in ()).throw(MemoryError()))
    with pytest.raises(la.OutOfMemory, match="ran out of memory"):
        la.factorize(A)
    assert tried == []


def test_available_memory_sees_an_address_space_limit():
    import subprocess
    import sys

    code = ("import resource, o3dheat.linalg as la; resource.setrlimit(resource.RLIMIT_AS, (4 * 2**30, 4 * 2**30));"
            "m = la.available_memory(); print(m is not None and m < 4 * 2**30)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "True", out.stderr[-500:]
