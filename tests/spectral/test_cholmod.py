"""o3dheat.spectral._cholmod: CHOLMOD through ctypes (threaded block solves), its fallback to scikit-sparse."""

import gc
import sys
import threading

import numpy as np
import pytest
import scipy.sparse as sp
from linalg_cases import needs_cholmod, spd_matrix

import o3dheat.spectral._cholmod as ch
import o3dheat.spectral.linalg as la
from o3dheat import parallel
from o3dheat.errors import SolverError


@pytest.fixture(scope="module")
def spd():
    return spd_matrix()


@needs_cholmod
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="binding checked on Linux")
def test_the_ctypes_binding_is_used():
    # the library scikit-sparse loaded, bound and self-checked (a failed check would fall back)
    assert ch.library() is not None


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


def test_the_offsets_table_names_every_field_the_binding_touches():
    import ctypes
    import inspect
    import re

    src = inspect.getsource(ch)
    used = set(re.findall(r'_field\([^,]+, "([a-zA-Z_.]+)"\)', src)) | set(re.findall(r'"(common\.[a-z_]+)"', src))
    assert used == set(ch._OFFSETS)  # every field read or written is in the table, and only those
    for name, (offset, ctype, _) in ch._OFFSETS.items():
        row = re.search(rf"#\s+cholmod_{re.escape(name)}\s+\S+( \*)?\s+(\d+)", src)
        assert row and int(row.group(2)) == offset, name  # the commented table says the same offset
        assert offset % ctypes.alignment(ctype) == 0


def _bound_or_skip():
    lib = ch.library()
    if lib is None:
        pytest.skip("no ctypes binding here")
    return lib


@needs_cholmod
def test_an_unexpected_layout_is_detected_and_scikit_sparse_takes_over(spd, monkeypatch, caplog):
    _bound_or_skip()
    b = np.ones((spd.shape[0], 3))
    # a cholmod_common whose supernodal_switch is not where the table says (another CHOLMOD)
    offset, ctype, _ = ch._OFFSETS["common.supernodal_switch"]
    monkeypatch.setitem(ch._OFFSETS, "common.supernodal_switch", (offset + 8, ctype, 40.0))
    monkeypatch.setattr(ch, "_LIB", None)  # bind again: the self-check sees the layout
    assert ch.library() is None
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
        monkeypatch.setitem(ch._OFFSETS, "common.print", (144, ch._OFFSETS["common.print"][1], 7))
    else:
        def broken(self, j, b, out):
            raise ch._BindingError("CHOLMOD solve failed")

        monkeypatch.setattr(ch.CholmodFactor, "_solve_columns", broken)
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
    lib = ch.library()
    if lib is None:
        pytest.skip("no ctypes binding here")
    f = ch.CholmodFactor(lib, spd, "simplicial")
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
    monkeypatch.setattr(ch, "_LIB", False)
    f = la.factorize(spd, backend="cholmod")
    assert f.backend == "cholmod"
    np.testing.assert_allclose(spd @ f.solve(b), b, atol=1e-9)
    with pytest.raises(SolverError, match="cholmod"):  # scikit-sparse's error, in the summary
        la.factorize(sp.diags([1.0, 0.0, 2.0], format="csc"), backend="cholmod")


