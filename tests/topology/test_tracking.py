"""o3dheat.topology.tracking: critical points followed across scales (issue 24)."""

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
        assert tr.euler_characteristic[j] == S.euler_characteristic == cp.euler_characteristic
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
    import o3dheat.pipelines.filters as flt

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


def _fields_on_closed_surfaces():
    """Three smooth fields under the heat flow on a fine grid of scales: bumps with noise on a
    sphere, a noisy height on a torus, a noisy product of waves on a sphere."""
    rng = np.random.default_rng(7)
    V, F = icosphere(4)
    centres = np.array([[1.0, 0, 0], [-0.5, 0.8, 0.3], [-0.4, -0.6, -0.7], [0, 0, 1]])
    centres /= np.linalg.norm(centres, axis=1)[:, None]
    bumps = sum(np.exp(-np.sum((V - c) ** 2, axis=1) / (2 * s**2)) for c, s in zip(centres, [0.15, 0.2, 0.3, 0.25],
                                                                                  strict=True))
    m = o3d.t.geometry.TriangleMesh.create_torus(radial_resolution=60, tubular_resolution=30)
    Vt = m.vertex.positions.numpy().astype(float)
    Ft = m.triangle.indices.numpy().astype(np.int64)
    waves = np.sin(3 * V[:, 0]) * np.cos(2 * V[:, 1]) + 0.5 * V[:, 2]
    for (Vm, Fm), f in (((V, F), bumps + 0.05 * rng.standard_normal(len(V))),
                        ((Vt, Ft), Vt[:, 0] + 0.1 * rng.standard_normal(len(Vt))),
                        ((V, F), waves + 0.1 * rng.standard_normal(len(V)))):
        t = np.geomspace(1e-4, 1.0, 60)
        yield (Vm, Fm), o3dheat.heat_flow((Vm, Fm), f, t), t


def test_tracks_agree_with_the_bottleneck_matching_of_consecutive_diagrams():
    """Issue 24: an independent check of the tracks against gudhi's bottleneck distance.

    Between scales i and i + 1 let ε = ‖F_i − F_{i+1}‖∞ and δ = the bottleneck distance (gudhi)
    between the diagrams of F_i and F_{i+1}, dimension by dimension.

    (a) Stability (Cohen-Steiner, Edelsbrunner, Harer): δ ≤ ε; on a fine grid of scales both are
        small against the field's range.
    (b) The tracks carry the diagrams: at every scale the finite persistences of the extremum
        tracks are the diagram's persistences (each pair has one extremum).
    (c) On a closed surface, an extremum track with persistence p > 2ε at scale i (or ∞) goes on
        to scale i + 1, and its value moves by at most ε: for a maximum v, paired with a saddle of
        value f_i(v) − p, let C be the component of v in {F_i ≥ f_i(v) − 2ε} (vertex graph, the
        topology's (value, index) order): v is its highest vertex, since the saddle is below that
        level. The steepest ascent from v in F_{i+1} climbs through F_{i+1} ≥ F_{i+1}(v) ≥
        f_i(v) − ε, hence F_i ≥ f_i(v) − 2ε: it stays in C and stops at a maximum w of F_{i+1}
        (closed: a vertex above its whole link is a maximum), with f_i(v) − ε ≤ F_{i+1}(v) ≤
        F_{i+1}(w) ≤ F_i(w) + ε ≤ f_i(v) + ε. Another maximum u whose ascent reaches w is joined to
        v's component above f_i(u) − 2ε and is lower than v (if u ∈ C, by the definition of C; if
        not, the ascent enters C from a vertex x with f_i(u) − 2ε ≤ F_i(x) < f_i(v) − 2ε), so its
        persistence is at most 2ε < p: the "most persistent" rule keeps v's track. Minima alike.
        So no extremum track whose persistence exceeds 2ε ends between i and i + 1 (the bottleneck
        matching keeps such points off the diagonal as well: 2ε ≥ 2δ).

    Not claimed: that a continuing track's persistence moves by at most 2ε. Two peaks whose
    heights cross swap their pairing: the diagram moves little (δ ≤ ε) while each track's
    persistence jumps; the tracks follow the flow, the bottleneck matching follows the values.
    """
    import gudhi

    checked = ended_small = 0
    for mesh, Ft, t in _fields_on_closed_surfaces():
        S = o3dheat.topology.Surface(mesh)
        tr = o3dheat.track_critical_points(S, Ft, t)
        _check_invariants(tr, mesh, Ft)
        span = np.ptp(Ft[:, 0])
        dgs = [o3dheat.persistence(S, Ft[:, j]) for j in range(len(t))]
        ext = tr.kind != "saddle"
        for j, dg in enumerate(dgs):  # (b)
            alive = ext & (tr.vertex[:, j] >= 0)
            p = tr.persistence[alive, j]
            np.testing.assert_array_equal(np.sort(p[np.isfinite(p)]), np.sort(dg.persistence))
            assert np.sum(~np.isfinite(p)) == np.sum(dg.essential_dimension != 1)
        for i in range(len(t) - 1):
            eps = np.abs(Ft[:, i] - Ft[:, i + 1]).max()
            for dim in (0, 1):  # (a)
                delta = gudhi.bottleneck_distance(dgs[i].intervals(dim), dgs[i + 1].intervals(dim))
                assert delta <= eps + 1e-12
            assert eps < 0.1 * span
            here = np.flatnonzero(ext & (tr.vertex[:, i] >= 0))
            p = tr.persistence[here, i]
            big, small = here[p > 2 * eps], here[p <= 2 * eps]
            assert np.all(tr.vertex[big, i + 1] >= 0), "a persistent extremum's track ended"  # (c)
            moved = np.abs(Ft[tr.vertex[big, i + 1], i + 1] - Ft[tr.vertex[big, i], i])
            assert np.all(moved <= eps + 1e-12)
            checked += len(big)
            ended_small += int(np.sum(tr.vertex[small, i + 1] < 0))
    assert checked > 1000 and ended_small > 20  # neither side of the bound is vacuous


def test_persistence_is_computed_on_first_read_and_pickled():
    import pickle

    V, F = icosphere(3)
    f = V[:, 2] + 0.3 * np.random.default_rng(0).standard_normal(len(V))
    t = np.geomspace(1e-3, 1.0, 8)
    Ft = o3dheat.heat_flow((V, F), f, t)
    tr = o3dheat.track_critical_points((V, F), Ft, t)
    back = pickle.loads(pickle.dumps(tr))  # carries the persistence, not the fields
    for j in range(len(t)):
        dg = o3dheat.persistence((V, F), Ft[:, j])
        alive = tr.vertex[:, j] >= 0
        for track in np.flatnonzero(alive):
            v = tr.vertex[track, j]
            q = dg.persistence[(dg.pairs == v).any(axis=1)]
            assert tr.persistence[track, j] == (q.max() if len(q) else np.inf)
        assert np.all(np.isnan(tr.persistence[~alive, j]))
    np.testing.assert_array_equal(back.persistence, tr.persistence)
    assert back._source is None and back.events == tr.events


def test_the_stop_criterion_reads_the_tracks():
    """Issue 24: scale_space(stop="tracks") stops at the first scale where no extremum is born or
    dies (the critical points may move); "critical_points" needs the very same vertices, so it
    stops no earlier, and at the tracks' stop the counts agree."""
    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    z = mesh.vertex.positions.numpy()[:, 2]
    noisy = z + 0.1 * np.random.default_rng(0).standard_normal(len(z))
    t = np.geomspace(1e-3, 1, 30)
    flow = o3dheat.HeatFlow(mesh)
    tr = o3dheat.scale_space(flow, noisy, scales=t, stop="tracks")
    cp = o3dheat.scale_space(flow, noisy, scales=t, stop="critical_points")
    j = tr.stop_index
    assert tr.stopped and tr.tracks is not None and 1 <= j < cp.stop_index
    assert tr.critical_counts[j].tolist() == tr.critical_counts[j - 1].tolist()
    assert not any(e["scale"] == j - 1 and "saddle" not in tr.tracks.kind[e["tracks"]][:1] for e in tr.tracks.events)
    assert not tr.critical[j].same_as(tr.critical[j - 1])  # they moved: the tracks see it, the sets do not
    assert cp.tracks is None


def test_chi_at_every_scale_on_genus_two():
    """Issue 24's ground truth: χ at every scale on genus 2 too (χ = -2), for a noisy field."""
    from topology_cases import genus2

    V, F = genus2()
    f = V[:, 0] + 0.05 * np.random.default_rng(3).standard_normal(len(V))
    t = np.geomspace(1e-4, 1.0, 20)
    Ft = o3dheat.heat_flow((V, F), f, t)
    tr = o3dheat.track_critical_points((V, F), Ft, t)
    _check_invariants(tr, (V, F), Ft)
    assert tr.euler_characteristic.tolist() == [-2] * len(t)


def test_lifetime_features_are_critical_points_of_the_field_with_the_truncated_kernel_too(monkeypatch):
    """Found in review: with method="spectral" the first tracked field was the truncated kernel's
    projection at t = 0, not the field: some features were not critical points of it."""
    import o3dheat.pipelines.filters as flt
    import o3dheat_filters.feature_approx as feature_approx

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    V = m.vertex.positions.numpy().astype(float)
    f = V[:, 2] + 0.1 * np.random.default_rng(0).standard_normal(len(V))
    m.vertex["f"] = o3d.core.Tensor(f)
    calls = []
    real = o3dheat.feature_driven
    monkeypatch.setattr(feature_approx, "feature_driven", lambda kernel, g, A, t: calls.append(np.asarray(A))
                        or real(kernel, g, A, t))
    flt.apply(m, "feature_approx", attribute="f", lifetime=0.01, method="spectral", k=100)
    crit = o3dheat.critical_points(m, f)
    assert calls and set(calls[0].tolist()) <= set(crit.minima) | set(crit.saddles) | set(crit.maxima)


def test_without_positions_a_saddle_on_its_vertex_continues():
    """A Surface of faces alone (scale_space's tracks): saddles that stay on their vertex are one
    track, not a death and a birth at every scale."""
    m = o3d.t.geometry.TriangleMesh.create_torus(radial_resolution=40, tubular_resolution=20)
    x = m.vertex.positions.numpy()[:, 0]
    F = m.triangle.indices.numpy()
    S = o3dheat.topology.Surface.from_faces(len(x), F)
    tr = o3dheat.track_critical_points(S, np.c_[x, 2 * x, 3 * x], [0.0, 0.1, 0.2])
    assert len(tr) == 4 and not tr.events


def test_text_radius_and_a_scale_past_the_end_are_one_line_errors():
    """Issue 30: radius='1' gave a TypeError, Tracks.features(99) an IndexError."""
    V, F = icosphere(2)
    G = np.c_[V[:, 2], V[:, 2] / 2]
    with pytest.raises(o3dheat.MeshError, match="radius must be a positive number"):
        o3dheat.track_critical_points((V, F), G, [0.0, 1.0], radius="1")
    tr = o3dheat.track_critical_points((V, F), G, [0.0, 1.0])
    with pytest.raises(o3dheat.MeshError, match="scale must be an index of the 2 scales"):
        tr.features(99)
    assert np.array_equal(tr.features(-2), tr.features(0))


def test_euler_characteristic_is_an_attribute_like_first_last_and_lifetime():
    """Issue 30: Tracks.euler_characteristic was the one method among attributes (first, last,
    lifetime, positions); it is a (T,) array now, and the former call still works with a warning."""
    import warnings

    m = o3d.t.geometry.TriangleMesh.create_torus()
    x = m.vertex.positions.numpy()[:, 0].astype(np.float64)
    t = [0.0, 0.1, 0.2]
    tr = o3dheat.track_critical_points(m, np.c_[x, 2 * x, 3 * x], t)
    assert isinstance(vars(o3dheat.Tracks)["euler_characteristic"], property)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # reading the attribute says nothing
        chi = tr.euler_characteristic
        assert isinstance(chi, np.ndarray) and chi.shape == (len(t),) and chi.dtype == np.int64
        assert chi.tolist() == [0, 0, 0] and repr(chi) == "array([0, 0, 0])"
        assert type(chi == 0) is np.ndarray and type(chi + 1) is np.ndarray  # what is computed is plain
        assert np.array_equal(chi, [o3dheat.critical_points(m, c).euler_characteristic for c in (x, 2 * x, 3 * x)])
    # the former method: the int at a scale, with a DeprecationWarning naming the new spelling
    with pytest.warns(DeprecationWarning, match=r"write tr\.euler_characteristic\[scale\]"):
        assert tr.euler_characteristic(1) == 0
    with pytest.warns(DeprecationWarning):
        value = tr.euler_characteristic(scale=-1)
    assert type(value) is int and value == 0
    # a subset keeps the invariant only for what it keeps: the sum over its tracks
    kept = tr.subset(tr.kind != "saddle")
    assert kept.euler_characteristic.tolist() == [2, 2, 2]


def test_critical_points_given_are_used_as_computed_and_checked():
    """``critical=`` (a scene has them already) gives the very tracks computed without it; a wrong
    number of them, another mesh's, or something else is a one-line MeshError."""
    V, F = icosphere(4)
    f = V[:, 2] + 0.2 * np.random.default_rng(3).standard_normal(len(V))
    t = np.geomspace(1e-4, 0.3, 8)
    Ft = o3dheat.heat_flow((V, F), f, t)
    S = o3dheat.topology.Surface.of((V, F))
    cps = [o3dheat.critical_points(S, Ft[:, j]) for j in range(len(t))]
    a = o3dheat.track_critical_points(S, Ft, t)
    b = o3dheat.track_critical_points(S, Ft, t, critical=cps)
    assert len(a) > 4 and a.events == b.events
    np.testing.assert_array_equal(a.vertex, b.vertex)
    np.testing.assert_array_equal(a.kind, b.kind)
    other = o3dheat.critical_points(icosphere(2), icosphere(2)[0][:, 2])
    for bad, msg in ((cps[:-1], "sequence of 8 CriticalPoints"), (cps[:-1] + [other], r"critical\[7\] is of a mesh"),
                     (cps[:-1] + ["x"], r"critical\[7\] is a str"), ("abcdefgh", "sequence of 8"), (3, "sequence of 8")):
        with pytest.raises(o3dheat.MeshError, match=msg):
            o3dheat.track_critical_points(S, Ft, t, critical=bad)
