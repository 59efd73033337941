"""The feature_approx filter (and critical_points), against the topology functions."""

import numpy as np
from conftest import tmesh

import o3dheat
import o3dheat.pipelines.filters as flt


def test_topology_filters(sphere):
    V, F = sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy()
    f = V[:, 2] + 0.05 * np.random.default_rng(0).standard_normal(len(V))
    m = tmesh(V, F, f=f)
    lab = flt.apply(m, "critical_points", attribute="f").vertex["f_critical"].numpy()
    cp = o3dheat.critical_points((V, F), f)
    assert lab.dtype == np.int8 and np.array_equal(lab, cp.kind)
    few = flt.apply(m, "critical_points", attribute="f", delta=0.5).vertex["f_critical"].numpy()
    assert np.count_nonzero(few) < np.count_nonzero(lab) and np.count_nonzero(few) >= 2
    out = flt.apply(m, "feature_approx", attribute="f", k=30, keep_fraction=0.3, scale=2)
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    A = o3dheat.simplify_critical_points((V, F), f, keep_fraction=0.3)
    g, loc = o3dheat.feature_driven(K, f, A, K.scales()[1])
    assert np.allclose(out.vertex["f_glob"].numpy(), g) and np.allclose(out.vertex["f_loc"].numpy(), loc)
