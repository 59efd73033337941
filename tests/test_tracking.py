"""o3dheat.tracking: critical points followed across scales (issue 24)."""

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere

import o3dheat


def _check_invariants(tr, mesh, F):
    """Every critical point of every scale on exactly one living track; χ at every scale."""
    S = o3dheat.topology.Surface.of(mesh)
    for j in range(F.shape[1]):
        cp = o3dheat.critical_points(S, F[:, j])
        alive = tr.vertex[:, j] >= 0
        for kind, vs in (("minimum", cp.minima), ("saddle", cp.saddles), ("maximum", cp.maxima)):
            mine = np.sort(tr.vertex[alive & (tr.kind == kind), j])
            np.testing.assert_array_equal(mine, np.sort(vs))
        assert tr.euler_characteristic(j) == S.euler_characteristic == cp.euler_characteristic
    # every track ends in an event or at the last scale, and lives on one interval
    ended = {t for e in tr.events if e["kind"] in ("cancel", "death", "merge") for t in e["tracks"][:1]}
    ended |= {e["tracks"][1] for e in tr.events if e["kind"] == "cancel"}
    for i in range(len(tr)):
        life = np.flatnonzero(tr.vertex[i] >= 0)
        assert np.array_equal(life, np.arange(life[0], life[-1] + 1))
        assert tr.last[i] == F.shape[1] - 1 or i in ended


def test_bumps_die_in_order_of_width_each_with_one_saddle():
    """Ground truth: on a sphere, f = three Gaussian bumps of widths σ1 < σ2 < σ3 (equal heights):
    under the heat flow the narrowest bump's maximum dies first, each cancelled with a saddle."""
    V, F = icosphere(5)
    centres = np.array([[1.0, 0, 0], [-0.5, 0.8, 0.3], [-0.4, -0.6, -0.7]])
    centres /= np.linalg.norm(centres, axis=1)[:, None]
    sigmas = [0.12, 0.2, 0.3]
    f = sum(np.exp(-np.sum((V - c) ** 2, axis=1) / (2 * s**2)) for c, s in zip(centres, sigmas, strict=True))
    t = np.geomspace(1e-4, 2.0, 60)
    Ft = o3dheat.heat_flow((V, F), f, t)
    tr = o3dheat.track_critical_points((V, F), Ft, t)
    _check_invariants(tr, (V, F), Ft)
    tops = [int(np.argmin(np.linalg.norm(V - c, axis=1))) for c in centres]
    ids, last = [], []
    for v in tops:
        hits = np.flatnonzero((tr.kind == "maximum") & (tr.vertex[:, 0] == v))
        assert len(hits) == 1, "each bump's top is a maximum at the first scale"
        ids.append(int(hits[0]))
        last.append(tr.last[hits[0]])
    assert last[0] < last[1] <= last[2]
    for i in ids[:2]:  # the two narrower bumps end, each cancelled with one saddle
        ev = [e for e in tr.events if i in e["tracks"]]
        assert len(ev) == 1 and ev[0]["kind"] == "cancel" and tr.kind[ev[0]["tracks"][1]] == "saddle"


def test_the_torus_height_lives_forever_and_chi_holds_with_genus_and_boundary():
    m = o3d.t.geometry.TriangleMesh.create_torus(radial_resolution=40, tubular_resolution=20)
    x = m.vertex.positions.numpy()[:, 0]
    t = np.geomspace(1e-3, 1.0, 10)
    Ft = o3dheat.heat_flow(m, x, t)
    tr = o3dheat.track_critical_points(m, Ft, t)
    assert len(tr) == 4 and np.all(tr.first == 0) and np.all(tr.last == 9) and not tr.events
    assert np.all(np.isinf(tr.lifetime))
    _check_invariants(tr, m, Ft)
    # a disk (boundary, χ = 1) with a noisy field: many events, the invariants hold throughout
    g = np.linspace(-1, 1, 25)
    X, Y = np.meshgrid(g, g)
    Vd = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    idx = np.arange(X.size).reshape(X.shape)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    Fd = np.r_[np.c_[a, b, d], np.c_[a, d, c]]
    f = np.random.default_rng(2).standard_normal(len(Vd))
    t = np.geomspace(1e-4, 1.0, 25)
    Ft = o3dheat.heat_flow((Vd, Fd), f, t)
    tr = o3dheat.track_critical_points((Vd, Fd), Ft, t)
    _check_invariants(tr, (Vd, Fd), Ft)
    assert sum(e["kind"] == "cancel" for e in tr.events) > 10


@pytest.mark.parametrize("bad, msg", [
    (lambda F, t: (F, t[::-1]), "strictly increasing"),
    (lambda F, t: (F[:, :2], t), "columns for 3 times"),
    (lambda F, t: (np.where(F > 0.5, np.nan, F), t), "NaN"),
    (lambda F, t: (F[:5], t), "shape"),
])
def test_bad_input_is_named(bad, msg):
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    x = m.vertex.positions.numpy()[:, 0]
    F, t = np.c_[x, x, x], np.array([0.0, 0.1, 0.2])
    with pytest.raises(o3dheat.MeshError, match=msg):
        o3dheat.track_critical_points(m, *bad(F, t))


def test_feature_approx_picks_the_long_lived_critical_points():
    """Issue 24: the lifetime criterion beside δ-persistence: a bump that dies early under the
    heat flow is not a feature with lifetime past its death; it is with a shorter lifetime."""
    import o3dheat.filters as flt

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    V = m.vertex.positions.numpy().astype(float)
    f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
    t = np.geomspace(1e-3, 1.0, 12)
    tr = o3dheat.track_critical_points(m, o3dheat.heat_flow(m, f, t), t)
    death = tr.times[tr.last[tr.last < len(t) - 1].max() + 1]  # the shallow maximum is gone here
    m.vertex["f"] = o3d.core.Tensor(f)
    flow = o3dheat.HeatFlow(m)
    outs, features = {}, {}
    for life in (t[1], 2 * death):
        out = flt.apply(m, "feature_approx", attribute="f", lifetime=float(life), method="exact", t=0.01)
        outs[life] = out.vertex["f_glob"].numpy()
        times = np.r_[0.0, np.geomspace(life / 1000, life, 40)]
        features[life] = o3dheat.track_critical_points(m, flow.apply(f, times), times).features()
        # the filter's A is the tracks' long-lived critical points: the same global component
        np.testing.assert_allclose(outs[life], o3dheat.feature_driven(flow, f, features[life], 0.01)[0], atol=1e-6)
    assert len(features[t[1]]) == 4 and len(features[2 * death]) == 2  # a maximum and a saddle did not last
    assert np.abs(outs[t[1]] - outs[2 * death]).max() > 0.01
    with pytest.raises(o3dheat.MeshError, match="one of delta, keep_fraction and lifetime"):
        flt.get("feature_approx", attribute="f", lifetime=0.1, delta=0.1)
    with pytest.raises(o3dheat.MeshError, match="lifetime"):
        flt.get("feature_approx", attribute="f", lifetime=-1.0)
