"""The tracks filter (issue 24)."""

import numpy as np
import open3d as o3d
import pytest
from conftest import tmesh

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.errors import MeshError


# ------------------------------------------------------------------------- tracks (issue 24)
def _bump_sphere(resolution=40, shift=(0.0, 0.0, 0.0)):
    """A tilted height and a Gaussian bump: the pole's shallow maximum cancels with a saddle."""
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, resolution)
    V = m.vertex.positions.numpy().astype(np.float64)
    f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
    return tmesh(V + np.asarray(shift), m.triangle.indices.numpy(), f=f)


def _pole_and_bump(V, kind, life):
    maxima = np.flatnonzero(kind == 3)
    pole, bump = maxima[np.argmax(V[maxima, 2])], maxima[np.argmax(V[maxima, 0])]
    return life[pole], life[bump]


def test_tracks_the_shallow_maximum_and_its_saddle_die_first():
    from o3dheat.pipelines.site import Site
    from o3dheat_filters.tracks import TracksFilter

    mesh = _bump_sphere()
    step = TracksFilter(attribute="f")
    out = step(mesh)
    assert "f_lifetime" not in mesh.vertex  # the input is unchanged
    life, kind = out.vertex["f_lifetime"].numpy(), out.vertex["f_track_kind"].numpy()
    assert life.dtype == np.float64 and kind.dtype == np.int8 and np.all(np.isfinite(life))
    # the kinds are the critical points of the field itself (t = 0 first)
    labels = flt.apply(mesh, "critical_points", attribute="f").vertex["f_critical"].numpy()
    assert np.array_equal(kind, labels) and np.bincount(kind, minlength=4).tolist()[1:] == [1, 1, 2]
    assert np.all(life[kind == 0] == 0)
    t = step.grid(Site(mesh))
    assert t[0] == 0 and np.all(np.diff(t) > 0) and len(t) == 41
    V = mesh.vertex.positions.numpy()
    pole, bump = _pole_and_bump(V, kind, life)
    saddle, minimum = life[kind == 2][0], life[kind == 1][0]
    assert 0 < pole == saddle < bump == minimum == t[-1]  # cancelled together; the others survive
    # thresholding at a time of the grid is the tracks' features at that scale
    tr = o3dheat.track_critical_points(mesh, np.c_[mesh.vertex["f"].numpy(),
                                                   o3dheat.heat_flow(mesh, mesh.vertex["f"].numpy(), t[1:])], t)
    for j in (0, 10, 40):
        assert np.array_equal(np.flatnonzero((kind > 0) & (life >= t[j])), tr.features(j))


def test_tracks_with_given_times_and_the_spectral_method():
    mesh = _bump_sphere(30)
    times = [0.01, 0.03, 0.1, 0.3, 1.0]
    out = flt.apply(mesh, "tracks", attribute="f", times=times, radius=0.5)
    life, kind = out.vertex["f_lifetime"].numpy(), out.vertex["f_track_kind"].numpy()
    assert set(np.unique(life[kind > 0])) <= set(times) | {0.0}
    pole, bump = _pole_and_bump(mesh.vertex.positions.numpy(), kind, life)
    assert pole < bump == 1.0
    spectral = flt.apply(mesh, "tracks", attribute="f", times=[0.0, *times], method="spectral", k=60)
    s_life, s_kind = spectral.vertex["f_lifetime"].numpy(), spectral.vertex["f_track_kind"].numpy()
    assert np.array_equal(s_kind, kind)  # t = 0 is the field itself, not its spectral projection
    pole, bump = _pole_and_bump(mesh.vertex.positions.numpy(), s_kind, s_life)
    assert pole < bump == 1.0


def test_tracks_on_a_mesh_of_two_parts():
    a, b = _bump_sphere(30), _bump_sphere(30, shift=(10.0, 0.0, 0.0))
    Va, Fa = a.vertex.positions.numpy(), a.triangle.indices.numpy()
    Vb, Fb = b.vertex.positions.numpy(), b.triangle.indices.numpy()
    f = np.r_[a.vertex["f"].numpy(), 0.5 * b.vertex["f"].numpy()]
    mesh = tmesh(np.r_[Va, Vb], np.r_[Fa, Fb + len(Va)], f=f)
    out = flt.apply(mesh, "tracks", attribute="f", scales=30)
    life, kind = out.vertex["f_lifetime"].numpy(), out.vertex["f_track_kind"].numpy()
    n = len(Va)
    assert np.bincount(kind, minlength=4).tolist()[1:] == [2, 2, 4]  # M - s + m = 4: two spheres
    top = life.max()
    for part in (slice(0, n), slice(n, None)):
        V, k, lf = mesh.vertex.positions.numpy()[part], kind[part], life[part]
        pole, bump = _pole_and_bump(V, k, lf)
        assert 0 < pole == lf[k == 2][0] < bump == lf[k == 1][0] == top
        assert np.all(lf[k == 0] == 0)


@pytest.mark.parametrize("params, match", [
    ({"times": (0.1, 0.1)}, r"tracks.times must be strictly increasing, got \(0.1, 0.1\)"),
    ({"times": (0.2, 0.1)}, r"tracks.times must be strictly increasing"),
    ({"times": (0.1, -1.0)}, r"tracks.times must be >= 0 \(every value\)"),
    ({"scales": 0}, r"tracks.scales must be in \[1, 100000\], got 0"),
    ({"radius": 0.0}, r"tracks.radius must be > 0, got 0.0"),
    ({"radius": float("inf")}, r"tracks.radius must be a finite number"),
    ({"k": 0}, r"tracks.k must be >= 1, got 0"),
    ({"tol": 2.0}, r"tracks.tol must be in \(0, 1\), got 2.0"),
    ({"method": "nope"}, r"tracks.method must be one of"),
    ({"variant": "nope"}, r"variant"),
])
def test_tracks_refuses_bad_parameters_before_any_work(params, match, monkeypatch):
    from o3dheat.spectral import heatflow, spectrum
    from o3dheat_filters.tracks import TracksFilter

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    monkeypatch.setattr(heatflow.HeatFlow, "smooth", lambda *a, **k: pytest.fail("a heat flow ran"))
    smooth = [("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 10, "scales": 2})]
    with pytest.raises(MeshError, match=match):  # by name: at construction
        flt.Chain([*smooth, ("tracks", {"attribute": "height", **params})])
    with pytest.raises(MeshError, match=match):  # made directly: the same check
        TracksFilter(attribute="height", **params)


def test_tracks_plan_and_missing_attribute_before_any_work(monkeypatch):
    from o3dheat.spectral import spectrum

    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)
    chain = flt.Chain([("scalar", {"kind": "height"}), ("tracks", {"attribute": "height", "times": [0.1, 0.5]})])
    planned = chain.check(mesh)
    assert planned["height_lifetime"] == 1 and planned["height_track_kind"] == 1
    assert planned == flt.attribute_columns(chain(mesh))
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    with pytest.raises(MeshError, match="no vertex attribute 'nope'"):
        flt.Chain([("tracks", {"attribute": "nope"})]).check(mesh)
    with pytest.raises(MeshError, match="no vertex attribute 'nope'"):
        flt.apply(mesh, "tracks", attribute="nope")
    with pytest.raises(MeshError, match=r"attribute 'positions' has 3 columns"):
        flt.apply(mesh, "tracks", attribute="positions")


def test_tracks_from_the_command(tmp_path, capsys):
    from o3dheat.cli import main
    from o3dheat.io import read_mesh, write_mesh

    src, out = tmp_path / "in.ply", tmp_path / "out.ply"
    write_mesh(src, o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16))
    rc = main(["apply", str(src), str(out), "-f", "scalar:kind=height", "-f", "tracks:attribute=height"])
    assert rc == 0, capsys.readouterr().err
    m = read_mesh(out)
    life, kind = m.vertex["height_lifetime"].numpy(), m.vertex["height_track_kind"].numpy()
    assert kind.dtype == np.int8 and np.bincount(kind, minlength=4).tolist() == [len(kind) - 2, 1, 0, 1]
    assert np.all(life[kind == 0] == 0) and np.all(life[kind > 0] == life.max()) and life.max() > 0
    # finite lifetimes: a colour map takes them, and the file keeps them
    colored = tmp_path / "colored.ply"
    assert main(["apply", str(out), str(colored), "-f", "colorize:attribute=height_lifetime"]) == 0
    assert "colors" in read_mesh(colored).vertex
    assert "tracks" in flt.names()
