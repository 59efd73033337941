"""Large cases, behind the `slow` marker (bash scripts/test.sh -m slow): not run in CI."""

import numpy as np
import pytest
from conftest import torus

import o3dheat


@pytest.mark.slow
def test_lanczos_matches_arpack_at_100k():
    V, F = torus(1.0, 0.4, 448, 224)  # 100k vertices: the block Lanczos is the default here
    a = o3dheat.eigensolve((V, F), k=100)
    b = o3dheat.eigensolve((V, F), k=100, method="arpack")
    np.testing.assert_allclose(a.eigenvalues[1:], b.eigenvalues[1:], rtol=1e-10)
    assert a.residuals.max() < 1e-8
    X, B = a.eigenvectors, a.mass
    np.testing.assert_allclose(X.T @ (B @ X), np.eye(100), atol=1e-10)
