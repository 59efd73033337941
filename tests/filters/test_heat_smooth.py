"""The heat_smooth filter's exact method (and feature_approx's)."""

import numpy as np
import pytest
from conftest import tmesh

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.errors import MeshError


def test_the_exact_method_is_the_full_kernel(sphere, monkeypatch):
    V, F = (sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy())
    f = V[:, 2] + 0.1 * np.sin(7 * V[:, 0])
    m = tmesh(V, F, f=f)
    out = flt.apply(m, "heat_smooth", attribute="f", method="exact", times=[0.01, 0.1], tol=1e-10)
    assert np.allclose(out.vertex["f_smooth"].numpy(), o3dheat.heat_flow((V, F), f, [0.01, 0.1], tol=1e-10),
                       rtol=0, atol=1e-12)
    # without times: the paper's scales of the k-eigenpair spectrum, the full kernel at them
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    exact = flt.apply(m, "heat_smooth", attribute="f", method="exact", k=30).vertex["f_smooth"].numpy()
    assert np.allclose(exact, o3dheat.heat_flow((V, F), f, K.scales()), rtol=0, atol=1e-9)
    spectral = flt.apply(m, "heat_smooth", attribute="f", k=30).vertex["f_smooth"].numpy()
    assert np.abs(exact - spectral).max() > 1e-3  # the truncation smooths more at t_1
    # feature_approx: f_glob = Φ_t(pr_A f) of the full kernel
    A = o3dheat.simplify_critical_points((V, F), f, keep_fraction=0.5)
    glob = flt.apply(m, "feature_approx", attribute="f", keep_fraction=0.5, method="exact", t=0.05)
    assert np.allclose(glob.vertex["f_glob"].numpy(),
                       o3dheat.heat_flow((V, F), o3dheat.topology.approximation.project(f, A), 0.05), atol=1e-9)
    # a bad method or tol is refused before any work
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    for bad, match in (({"method": "fast"}, "method must be one of 'spectral', 'exact'"),
                       ({"method": "exact", "tol": 0.0}, r"heat_smooth.tol must be in \(0, 1\), got 0.0")):
        with pytest.raises(MeshError, match=match):
            flt.Chain([("heat_smooth", {"attribute": "f", **bad})])(m)
