"""Drawing fields: colorbars and legends, panels sharing a colorbar or not, the arguments checked,
the tracks across scales (PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import icosphere, torus
from pictures import not_blank, pixels, torus_tracks

import o3dheat
import o3dheat.visualization.plot as plot


def legend_texts(fig):
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


def test_field_has_a_named_colorbar_and_a_legend(tmp_path):
    V, F = torus(1.0, 0.4, 40, 20)
    fig = plot.field((V, F), V[:, 0], level_sets=8, title="x on a torus", label="x coordinate")
    assert fig.axes[1].get_ylabel() == "x coordinate"  # the colorbar
    texts = legend_texts(fig)
    assert texts == ["level sets (8)", "maxima (1)", "minima (1)", "saddles (2)"]
    img = fig.axes[0].get_images()[0].get_array()
    assert pixels(img, "red") and pixels(img, "green")  # the maximum and a saddle face the viewer
    assert fig.axes[0].get_title() == "x on a torus"
    fig.savefig(tmp_path / "f.png")
    assert not_blank(tmp_path / "f.png")
    cp = o3dheat.critical_points((V, F), V[:, 0])
    fig = plot.field((V, F), V[:, 0], level_sets=[0.0], critical_points=cp, up="y")
    fig.savefig(tmp_path / "g.png")
    assert not_blank(tmp_path / "g.png")


def test_panels_share_a_colorbar_or_have_their_own(tmp_path):
    V, F = icosphere(3)
    f = V[:, 2] + 0.2 * np.random.default_rng(1).standard_normal(len(V))
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=60))
    ss = o3dheat.scale_space(K, f, stop="critical_points")
    fig = plot.fields((V, F), ss.fields[:, :3], titles=["a", "b", "c"], suptitle="scales", label="Φ_t f")
    assert len(fig.axes) == 4 and fig.axes[3].get_ylabel() == "Φ_t f"  # three pictures, one colorbar
    assert fig.get_suptitle() == "scales" and [a.get_title() for a in fig.axes[:3]] == ["a", "b", "c"]
    assert legend_texts(fig) == ["level sets (10)", "maxima", "minima", "saddles"]
    fig.savefig(tmp_path / "p.png")
    assert not_blank(tmp_path / "p.png")
    fig = plot.fields((V, F), ss.fields[:, :2], shared_range=False, critical_points=False, level_sets=None)
    assert len(fig.axes) == 4 and not fig.legends  # one colorbar per panel, nothing to explain
    with pytest.raises(o3dheat.MeshError, match="2 titles for 3 fields"):
        plot.fields((V, F), ss.fields[:, :3], titles=["a", "b"])


def test_bad_input():
    V, F = icosphere(1)
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), np.zeros(3))
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), np.full(len(V), np.nan))
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), V[:, 0], up="w")
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), V[:, 0], renderer="vtk")
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), V[:, 0], view="front")
    with pytest.raises(o3dheat.MeshError):
        plot.scale_space("not a scale space")
    with pytest.raises(o3dheat.MeshError, match="0 columns"):
        plot.fields((V, F), np.zeros((len(V), 0)))


def test_style_arguments_are_checked():
    V, F = icosphere(1)
    for kw, what in [({"cmap": "nope"}, "cmap"), ({"size": 0}, "size"), ({"size": -1}, "size"),
                     ({"level_sets": 2.5}, "level_sets")]:
        with pytest.raises(o3dheat.MeshError, match=what):
            plot.field((V, F), V[:, 0], renderer="matplotlib", **kw)


def test_render_checks_its_range():
    V, F = icosphere(1)
    for bad in [(np.nan, 1.0), (1.0, 0.0), "ab", (1.0,)]:
        with pytest.raises(o3dheat.MeshError, match="vrange"):
            plot.render((V, F), V[:, 0], vrange=bad)


def test_tracks_draws_lines_and_end_markers_in_the_kinds_colours(tmp_path):
    mesh, Ft, tr = torus_tracks()
    fig = plot.tracks(mesh, tr, Ft, title="tracks", label="f")
    img = fig.axes[0].get_images()[0].get_array()
    assert pixels(img, "red") and pixels(img, "blue") and pixels(img, "green")
    assert fig.axes[1].get_ylabel() == "f (first scale)"  # the colorbar
    texts = legend_texts(fig)
    assert len(texts) == 3 and all(k in " ".join(texts) for k in ("minima", "saddles", "maxima"))
    total = sum(int(s.split("(")[1].split()[0].replace(",", "")) for s in texts)
    assert total == len(tr)
    fig.savefig(tmp_path / "tracks.png")
    assert not_blank(tmp_path / "tracks.png")
    # the longest-lived only: the legend counts what is drawn, the panel says how many of how many
    few = plot.tracks(mesh, tr, longest=3)
    assert sum(int(s.split("(")[1].split()[0]) for s in legend_texts(few)) == 3
    assert any(f"3 longest-lived of {len(tr)}" in t.get_text() for t in few.axes[0].texts)


def test_tracks_with_matplotlib_and_bad_input():
    mesh, Ft, tr = torus_tracks()
    fig = plot.tracks(mesh, tr, Ft[:, 0], renderer="matplotlib")
    assert fig.axes[0].name == "3d" and len(fig.axes[0].collections) >= 2  # the surface and the lines
    with pytest.raises(o3dheat.MeshError, match="expected Tracks"):
        plot.tracks(mesh, "tracks")
    with pytest.raises(o3dheat.MeshError, match="not of this mesh"):
        plot.tracks(icosphere(2), tr)
    with pytest.raises(o3dheat.MeshError, match="expected Tracks"):
        plot.lifetime_chart(None)
