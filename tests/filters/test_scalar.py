"""The scalar filter."""

import numpy as np
import pytest
from conftest import icosphere, tmesh, torus

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.spectral.fem import voronoi_areas


def test_scalar_fields():
    V, F = icosphere(4, radius=2.0)
    m = tmesh(V, F)
    H = flt.apply(m, "scalar", kind="mean_curvature").vertex["mean_curvature"].numpy()
    K = flt.apply(m, "scalar", kind="gaussian_curvature").vertex["gaussian_curvature"].numpy()
    assert np.allclose(H, 0.5, rtol=0.02) and np.allclose(K, 0.25, rtol=0.05)
    Vt, Ft = torus()
    Kt = flt.apply(tmesh(Vt, Ft), "scalar", kind="gaussian_curvature").vertex["gaussian_curvature"].numpy()
    assert abs(Kt @ voronoi_areas(Vt, Ft)) < 1e-9  # Gauss-Bonnet: 2π χ = 0
    h = flt.apply(m, "scalar", kind="height", axis=0).vertex["height"].numpy()
    assert np.array_equal(h, V[:, 0])
    a = flt.apply(m, "scalar", kind="height")
    n1 = flt.apply(a, "scalar", kind="noise", attribute="height", sigma=0.1, seed=3).vertex["height_noisy"].numpy()
    n2 = flt.apply(a, "scalar", kind="noise", attribute="height", sigma=0.1, seed=3).vertex["height_noisy"].numpy()
    assert np.array_equal(n1, n2) and abs(np.std(n1 - V[:, 2]) - 0.1 * 4.0) < 0.03
    with pytest.raises(o3dheat.MeshError, match="needs attribute"):
        flt.get("scalar", kind="noise")
    with pytest.raises(o3dheat.MeshError, match="no vertex attribute 'nope'"):
        flt.apply(m, "scalar", kind="noise", attribute="nope")
