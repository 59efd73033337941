"""o3dheat.spectral._cholmod: CHOLMOD through ctypes (threaded block solves), its fallback to scikit-sparse."""

import gc
import sys
import threading

import numpy as np
import pytest
import scipy.sparse as sp
from linalg_cases import needs_cholmod, spd_matrix

import o3dheat.memory as mm
import o3dheat.spectral._cholmod as ch
import o3dheat.spectral.linalg as la
from o3dheat import parallel
from o3dheat.errors import MeshError, OutOfMemory, SolverError
from o3dheat.spectral import fem


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
    code = src.replace(src[src.index("_OFFSETS = {"):src.index("}", src.index("_OFFSETS = {"))], "")
    used = set(re.findall(r'"((?:common|factor)\.[A-Za-z0-9_]+)"', code))
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




def _grid(m):
    """The 5-point Laplacian of an m x m grid (+ identity), in natural order."""
    T = sp.diags([-np.ones(m - 1), 4 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    S = sp.diags([-np.ones(m - 1), -np.ones(m - 1)], [-1, 1])
    return sp.csc_matrix(sp.kron(sp.identity(m), T) + sp.kron(S, sp.identity(m)) + sp.identity(m * m))


@needs_cholmod
def test_a_factor_too_large_for_32_bit_indices_is_analysed_with_64_bit_ones(monkeypatch):
    """Issue 35: a 1400² grid in natural order has a factor of 2.74e9 entries (> 2³¹): the 32-bit
    analysis says "too large", the 64-bit one counts it, and the factorization is refused by the
    memory estimate made from that count (never "out of memory" from CHOLMOD's 32-bit failure)."""
    _bound_or_skip()
    m = 1400
    A = _grid(m)
    a = la.analyze(A, ordering="natural")
    assert a.wide and a.ordering == "natural"
    n = m * m
    assert m * (n - m) <= a.lnz <= (m + 1) * n  # the band fills: about m entries per column
    assert a.lnz > 2**31
    assert a.nbytes >= 16 * a.lnz  # 8-byte values and 8-byte indices
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": 32 * 2**30})
    with pytest.raises(OutOfMemory, match=r"Cholesky factor of 1960000 x 1960000 \(2744\d+ nonzeros\) needs about 4\d\.\d\d GiB"):
        la.factorize(A, analysis=a)
    assert not la.analyze(A).wide  # AMD: a factor of about 1e8 entries, 32-bit


@needs_cholmod
def test_too_large_is_said_so_when_64_bit_indices_are_missing(monkeypatch):
    lib = _bound_or_skip()
    monkeypatch.setattr(lib, "wide_api", lambda: None)
    with pytest.raises(ch.TooLarge, match="too large for CHOLMOD's 32-bit indices.*64-bit interface is unavailable"):
        la.analyze(_grid(1400), ordering="natural")


@needs_cholmod
@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("mode", ["simplicial", "supernodal"])
def test_the_factor_memory_estimate_is_within_25_percent_above_cholmods_peak(mode, wide):
    """The estimate made from the symbolic analysis, against CHOLMOD's own count of its peak
    (analysis, factorization and conversion): over, never under, by at most 25%."""
    from conftest import icosphere, irregular

    lib = _bound_or_skip()
    api = lib.wide_api() if wide else lib
    assert api is not None and api.wide == wide
    for V, F in (irregular(), icosphere(5), _bunny_like()):
        L, B = fem.stiffness_matrix((V, F)), fem.mass_matrix((V, F))
        A = sp.csc_matrix(B + 0.01 * L)
        estimate = ch.Analysis(api, A, mode).nbytes
        peak = ch.CholmodFactor(api, A, mode).peak_bytes
        assert peak <= estimate <= 1.25 * peak, (len(V), estimate, peak)


def _bunny_like():
    """The embedded bunny, decimated (an adaptive, irregular sampling)."""
    from o3dheat.geometry.sampling import decimate
    from o3dheat.io import default_mesh

    return decimate(default_mesh()[0], 0.5).arrays


@needs_cholmod
def test_the_ordering_is_amd_unless_amds_flops_say_metis_pays(spd, monkeypatch):
    """Issue 35: "auto" is AMD, then METIS when AMD's flops per row exceed METIS_FLOPS_PER_ROW, the
    ordering of fewer flops kept (the same choice every time); fill and flops reported."""
    _bound_or_skip()
    auto, amd, natural = la.analyze(spd), la.analyze(spd, ordering="amd"), la.analyze(spd, ordering="natural")
    assert auto.ordering == "amd" and (auto.lnz, auto.flops) == (amd.lnz, amd.flops)  # a small mesh: AMD
    assert 0 < amd.lnz < natural.lnz and 0 < amd.flops < natural.flops
    metis = la.analyze(spd, ordering="metis")  # METIS where CHOLMOD has it, else CHOLMOD's AMD backup
    assert metis.lnz > 0 and metis.nbytes > 0
    monkeypatch.setattr(ch, "METIS_FLOPS_PER_ROW", 0.0)  # METIS always tried
    tried = [la.analyze(spd) for _ in range(2)]
    assert tried[0].flops == min(amd.flops, metis.flops) and tried[0].ordering in ("amd", "metis")
    assert (tried[1].ordering, tried[1].lnz, tried[1].flops) == (tried[0].ordering, tried[0].lnz, tried[0].flops)
    f = la.factorize(spd, backend="cholmod")  # its own analysis: the same choice
    b = np.ones((spd.shape[0], 2))
    np.testing.assert_allclose(spd @ f.solve(b), b, atol=1e-9)
    with pytest.raises(MeshError, match="unknown ordering"):
        la.analyze(spd, ordering="best")


@needs_cholmod
@pytest.mark.parametrize("mode", ["simplicial", "supernodal"])
def test_row_solves_agree_with_cholmods_and_do_not_depend_on_threads_or_columns(spd, mode):
    f = la.factorize(spd, backend="cholmod", mode=mode)
    c = 2 * ch.ROW_SOLVE_MIN + 5  # row by row, on up to two threads
    b = np.random.default_rng(3).standard_normal((spd.shape[0], c))
    out = {}
    for t in (1, 2, 3):
        with parallel.threads(t):
            out[t] = f.solve(b)
    np.testing.assert_array_equal(out[2], out[1])
    np.testing.assert_array_equal(out[3], out[1])
    with parallel.threads(1):  # the first columns alone give the same bits
        np.testing.assert_array_equal(f.solve(b[:, :ch.ROW_SOLVE_MIN]), out[1][:, :ch.ROW_SOLVE_MIN])
    cholmods = np.column_stack([f.solve(b[:, j:j + 4]) for j in range(0, c, 4)])  # CHOLMOD's solve
    np.testing.assert_allclose(out[1], cholmods, rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(spd @ out[1], b, rtol=1e-9, atol=1e-9)
