"""o3dheat.spectral.linalg: factorize and its backends (CHOLMOD, cholespy, SuperLU), the memory checks before them."""


import numpy as np
import pytest
import scipy.sparse as sp
from linalg_cases import needs_cholmod, spd_matrix

import o3dheat.memory as mm
import o3dheat.spectral._cholmod as ch
import o3dheat.spectral.linalg as la
from o3dheat.errors import MeshError, OutOfMemory
from o3dheat.spectral import fem


@pytest.fixture(scope="module")
def spd():
    return spd_matrix()


@needs_cholmod
@pytest.mark.parametrize("mode", ["simplicial", "supernodal", "auto"])
def test_modes(spd, mode):
    b = np.ones((spd.shape[0], 3))
    np.testing.assert_allclose(spd @ la.factorize(spd, backend="cholmod", mode=mode).solve(b), b, atol=1e-9)


def test_auto_mode_is_supernodal_for_large_matrices_only():
    assert la._auto_mode("auto", la.SUPERNODAL_MIN_N - 1) == "simplicial"
    assert la._auto_mode("auto", la.SUPERNODAL_MIN_N) == "supernodal"
    assert la._auto_mode("simplicial", 10**7) == "simplicial"
    with pytest.raises(MeshError, match="unknown mode"):
        la.factorize(sp.identity(3, format="csc"), mode="fast")


def test_wrong_right_hand_side_is_named(spd):
    f = la.factorize(spd)
    with pytest.raises(MeshError, match="rows"):
        f.solve(np.ones(spd.shape[0] + 1))


@pytest.mark.parametrize("A, match", [
    (sp.csc_matrix(np.ones((3, 2))), "square"),
    (sp.diags([1.0, np.nan, 2.0], format="csc"), "NaN or infinite"),
    (sp.diags([1.0, np.inf, 2.0], format="csc"), "NaN or infinite"),
])
def test_bad_matrices_are_named(A, match):
    with pytest.raises(MeshError, match=match):
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
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": 1000})  # bytes
    if ch.library() is not None:
        with pytest.raises(OutOfMemory, match="Cholesky factor .* needs about"):
            la.factorize(A, backend="cholmod")
    tried = []
    monkeypatch.setattr(la, "_cholespy", lambda A: tried.append("cholespy"))

    def oom(A, mode, analysis=None):
        raise OutOfMemory("CHOLMOD ran out of memory")

    monkeypatch.setattr(la, "_cholmod", oom)
    with pytest.raises(OutOfMemory):
        la.factorize(A)
    assert tried == []  # cholespy would need as much memory, and crashes when it does not get it
    monkeypatch.setattr(la, "_cholmod", lambda A, mode, analysis=None: (_ for _ in ()).throw(MemoryError()))
    with pytest.raises(OutOfMemory, match="ran out of memory"):
        la.factorize(A)
    assert tried == []


@pytest.mark.parametrize("backend", la.available_backends())
def test_solve_into_a_given_array(spd, backend):
    f = la.factorize(spd, backend=backend)
    b = np.random.default_rng(4).standard_normal((spd.shape[0], 6))
    out = np.full(b.shape, np.nan)
    x = f.solve(b, out=out)
    assert x is out
    np.testing.assert_array_equal(out, f.solve(b))
    for bad in (np.empty((spd.shape[0], 5)), np.empty(b.shape, order="F"), np.empty(b.shape, np.float32)):
        with pytest.raises(MeshError, match="out must be"):
            f.solve(b, out=bad)


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
        monkeypatch.setattr(la, "library", lambda: None)
    need = la.cholespy_bytes(A)
    assert need > 64 * 1000
    ok = la.factorize(A, backend="cholespy")  # plenty of memory: it works
    np.testing.assert_allclose(A @ ok.solve(np.ones(1000)), 1.0)
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": need - 1})
    monkeypatch.setattr(cholespy, "CholeskySolverD", lambda *a: pytest.fail("cholespy was started"))
    with pytest.raises(OutOfMemory, match="cholespy's factorization of the 1000 x 1000 matrix needs about"):
        la.factorize(A, backend="cholespy")
    # a mesh Laplacian: the estimate covers what cholespy was measured to use (38-60 B per n log2 n)
    from conftest import icosphere


    V, F = icosphere(4)
    L, B, _ = fem.operators(V, F, "consistent")
    assert la.cholespy_bytes(L + 1e-3 * B) >= 60 * len(V) * np.log2(len(V)) or binding


