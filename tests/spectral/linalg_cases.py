"""Helpers of the spectral tests."""

import pytest
import scipy.sparse as sp
from conftest import irregular

import o3dheat.spectral.linalg as la
from o3dheat.spectral import fem

needs_cholmod = pytest.mark.skipif("cholmod" not in la.available_backends(), reason="scikit-sparse not installed")


def spd_matrix():
    """L + 0.1 B of an irregular mesh: sparse, symmetric positive definite."""
    V, F = irregular()
    L, B = fem.stiffness_matrix((V, F)), fem.mass_matrix((V, F))
    return sp.csc_matrix(L + 0.1 * B)
