"""o3dheat.spectral._substitution: the row-major triangular solves of a simplicial LLᵀ factor."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from o3dheat.spectral._substitution import solve_rows


def _factor(A):
    """A dense Cholesky factor of A[perm][:, perm] in CSC (the arrays the solve reads)."""
    n = A.shape[0]
    perm = np.random.default_rng(n).permutation(n)
    L = sp.csc_matrix(np.tril(sla.cholesky(A[np.ix_(perm, perm)], lower=True)))
    L.sort_indices()
    return L.indptr, L.indices, L.data, perm


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 40), c=st.integers(1, 40), threads=st.integers(1, 3), seed=st.integers(0, 2**16))
def test_solves_against_a_dense_solve_and_bits_do_not_depend_on_threads(n, c, threads, seed):
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    A = M @ M.T + n * np.eye(n)
    B = rng.standard_normal((n, c))
    args = _factor(A)
    x = solve_rows(*args, B, np.empty((n, c)), [], threads=threads)
    np.testing.assert_allclose(x, np.linalg.solve(A, B), rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(x, solve_rows(*args, B, np.empty((n, c)), [], threads=1))
    for j in range(0, c, 7):  # each column alone: the same operations, the same bits
        np.testing.assert_array_equal(x[:, j:j + 1], solve_rows(*args, B[:, j:j + 1], np.empty((n, 1)), []))


@pytest.mark.parametrize("index", [np.int32, np.int64])
def test_both_index_widths_and_workspaces_reused(index):
    A = np.array([[4.0, 2.0, 0.0], [2.0, 5.0, 1.0], [0.0, 1.0, 3.0]])
    Lp, Li, Lx, perm = _factor(A)
    work = []
    B = np.eye(3)
    x = solve_rows(Lp.astype(index), Li.astype(index), Lx, perm.astype(index), B, np.empty((3, 3)), work)
    np.testing.assert_allclose(x, np.linalg.inv(A), atol=1e-14)
    kept = [w for w in work]
    solve_rows(Lp, Li, Lx, perm, 2 * B, np.empty((3, 3)), work)
    assert all(a is b for a, b in zip(work, kept, strict=True))  # the same shape: the same arrays
