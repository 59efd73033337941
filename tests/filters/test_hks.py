"""The hks filter (and heat_smooth), against the kernel."""

import numpy as np
import pytest

import o3dheat
import o3dheat.pipelines.filters as flt


def test_heat_smooth_and_hks_match_the_kernel(sphere):
    V, F = (sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy())
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    f = V[:, 2]
    out = flt.apply(sphere, "heat_smooth", attribute="height", k=30)
    assert np.allclose(out.vertex["height_smooth"].numpy(), K.smooth(f, K.scales()))
    one = flt.apply(sphere, "heat_smooth", attribute="height", k=30, times=[0.01], output="s")
    assert np.allclose(one.vertex["s"].numpy(), K.smooth(f, 0.01))
    col = flt.apply(out, "heat_smooth", attribute="height_smooth", column=2, k=30, times=[0.01, 0.02])
    assert np.allclose(col.vertex["height_smooth_smooth"].numpy(), K.smooth(K.smooth(f, K.scales())[:, 2], [0.01, 0.02]))
    with pytest.raises(o3dheat.MeshError, match="columns"):
        flt.apply(out, "heat_smooth", attribute="height_smooth", k=30)
    with pytest.raises(o3dheat.MeshError, match="column 12 does not exist"):
        flt.apply(out, "heat_smooth", attribute="height_smooth", column=12, k=30)
    h = flt.apply(sphere, "hks", k=30, form="paper").vertex["hks"].numpy()
    assert np.allclose(h, K.hks(K.scales(), form="paper"))
