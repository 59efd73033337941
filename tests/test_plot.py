"""Drawing: real 3D renders (hidden surfaces removed, everything in frame), colorbars and legends,
the matplotlib fallback, and the charts' axes (PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import glued_spheres, icosphere, torus

import o3dheat
import o3dheat.visualization.plot as plot

needs_renderer = pytest.mark.skipif(not plot.renderer_available()[0], reason="no offscreen renderer here")


def not_blank(path):
    from matplotlib.image import imread

    img = imread(path)[..., :3]
    ink = np.any(img < 0.95, axis=2).mean()  # share of non-white pixels
    return img.std() > 0.05 and ink > 0.02


def pixels(img, color):
    """Pixels close to a pure colour ("red", "blue", "green"): the critical points' markers."""
    r, g, b = (img[..., i].astype(int) for i in range(3))
    return int({"red": (r > 120) & (g < 60) & (b < 60), "blue": (b > 120) & (r < 60) & (g < 60),
                "green": (g > 60) & (r < 40) & (b < 40)}[color].sum())


def ink(img):
    return np.any(img < 250, axis=2)


def legend_texts(fig):
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


@needs_renderer
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


@needs_renderer
def test_what_is_behind_the_surface_is_hidden():
    """x on a sphere seen from +x: the maximum (+x) shows, the minimum (-x) is behind the sphere;
    seen from -x the other way round. A level set on the far side leaves the picture unchanged."""
    V, F = icosphere(3)
    f = V[:, 0]
    front = plot.render((V, F), f, level_sets=None, view=(0, 0), cmap="gray")
    back = plot.render((V, F), f, level_sets=None, view=(0, 180), cmap="gray")
    assert pixels(front, "red") > 20 and pixels(front, "blue") == 0
    assert pixels(back, "blue") > 20 and pixels(back, "red") == 0
    plain = plot.render((V, F), f, level_sets=None, critical_points=False, view=(0, 0))
    far = plot.render((V, F), f, level_sets=[-0.7], critical_points=False, view=(0, 0))
    near = plot.render((V, F), f, level_sets=[0.7], critical_points=False, view=(0, 0))
    assert np.array_equal(plain, far)
    dark = (near.max(axis=2) < 60) & ~(plain.max(axis=2) < 60)
    assert dark.sum() > 100  # the near level set: a visible black ring


def touches_border(img):
    m = ink(img)
    return m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any()


@needs_renderer
def test_every_part_in_frame():
    """A mesh of two parts far apart, and pymeshlab's airplane (wide wings): everything is in the
    picture, with a margin, and the picture is no larger than the geometry needs."""
    from o3dheat.io import sample_mesh

    V1, F1 = icosphere(2)
    V = np.r_[V1, V1 * 0.5 + [6.0, 0.0, 1.0]]
    F = np.r_[F1, F1 + len(V1)]
    img = plot.render((V, F), V[:, 2], view=(10, -90))
    m = ink(img)
    assert not touches_border(img)
    cols = np.flatnonzero(m.any(axis=0))
    assert cols[0] < 0.06 * m.shape[1] and cols[-1] > 0.94 * m.shape[1]  # tight left and right
    assert m[:, : m.shape[1] // 3].any() and m[:, -m.shape[1] // 6:].any()  # both parts
    plane = sample_mesh("airplane")
    Vp = plane.vertex.positions.numpy()
    img = plot.render(plane, Vp[:, 0], critical_points=False)
    assert not touches_border(img) and ink(img).mean() > 0.1


@needs_renderer
def test_a_scan_far_from_the_origin_renders_the_same():
    V, F = icosphere(3)
    near = plot.render((V, F), V[:, 0])
    far = plot.render((V + [3e6, -2e6, 1e6], F), V[:, 0])  # float32 has ~0.25 units of resolution there
    assert near.shape == far.shape and np.abs(near.astype(int) - far).mean() < 1.0


@needs_renderer
def test_too_many_critical_points_are_not_drawn(monkeypatch):
    V, F = icosphere(3)
    f = V[:, 2] + 0.3 * np.random.default_rng(1).standard_normal(len(V))
    n = sum(o3dheat.critical_points((V, F), f).counts)
    monkeypatch.setattr(plot, "MAX_CRITICAL_POINTS", n - 1)
    fig = plot.field((V, F), f, level_sets=None, cmap="gray")
    img = fig.axes[0].get_images()[0].get_array()
    assert pixels(img, "red") == 0 and pixels(img, "blue") == 0
    assert f"{n:,} critical points: too many to draw" in [t.get_text() for t in fig.axes[0].texts]


@needs_renderer
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


def test_fallback_to_matplotlib_warns_and_still_draws(monkeypatch, tmp_path):
    V, F = torus(1.0, 0.4, 24, 12)
    monkeypatch.setitem(plot._state, "probe", (False, plot._MISSING + " (test)"))
    monkeypatch.setitem(plot._state, "renderer", None)
    monkeypatch.setitem(plot._state, "warned", False)
    monkeypatch.delenv("O3DHEAT_RENDERER", raising=False)
    with pytest.warns(RuntimeWarning, match="libvulkan1 and mesa-vulkan-drivers"):
        fig = plot.field((V, F), V[:, 0], label="x")
    assert fig.axes[0].name == "3d" and fig.axes[1].get_ylabel() == "x"
    fig.savefig(tmp_path / "m.png")
    assert not_blank(tmp_path / "m.png")
    with pytest.raises(o3dheat.MeshError, match="renderer='matplotlib'"):
        plot.field((V, F), V[:, 0], renderer="open3d")
    with pytest.raises(o3dheat.MeshError, match="mesa-vulkan-drivers"):
        plot.render((V, F), V[:, 0])


def test_matplotlib_on_purpose_is_quiet(monkeypatch, recwarn):
    V, F = torus(1.0, 0.4, 24, 12)
    monkeypatch.setenv("O3DHEAT_RENDERER", "matplotlib")
    fig = plot.fields((V, F), np.c_[V[:, 0], V[:, 1]], critical_points=False)
    assert fig.axes[0].name == "3d" and not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    monkeypatch.setenv("O3DHEAT_RENDERER", "vtk")
    with pytest.raises(o3dheat.MeshError, match="O3DHEAT_RENDERER"):
        plot.field((V, F), V[:, 0])


def test_scale_space_ticks_sit_on_the_scales():
    V, F = icosphere(2)
    f = V[:, 2] + 0.2 * np.random.default_rng(1).standard_normal(len(V))
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    for grid in ("paper", "log"):
        ss = o3dheat.scale_space(K, f, scales=K.scales(10, grid=grid))
        fig = plot.scale_space(ss, title="Fig. 1c,d")
        fig.canvas.draw()
        for ax in fig.axes:
            labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
            assert 2 <= len(labels) <= 6 and not [t for t in ax.get_xticklabels(minor=True) if t.get_text()]
        counts = fig.axes[1].get_yticks()
        assert np.allclose(counts, np.round(counts))  # critical points are counted in whole numbers


def study_table(descriptor, scales):
    import pandas as pd

    rows = [dict(descriptor=descriptor, error="", kind=k, kernel=kern, scale=s, rel_l2=(0.01 + 0.01 * s) * m)
            for k, m in (("decimate", 1.0), ("jitter", 30.0)) for kern in ("weighted", "linear") for s in scales]
    return pd.DataFrame(rows)


def test_study_axes():
    fig = plot.study(study_table("hks_density", range(1, 11)))
    fig.canvas.draw()
    a, b = fig.axes
    assert a.get_yscale() == b.get_yscale() == "log" and a.get_ylim() == b.get_ylim()  # compared panels
    ticks = a.get_xticks()
    assert np.allclose(ticks, np.round(ticks))  # integer scales: no tick at 1.5
    fig = plot.study(study_table("eigenvalues", [0]), descriptor="eigenvalues")
    a, b = fig.axes
    assert a.get_yscale() == b.get_yscale() == "linear" and a.get_ylim()[0] == 0  # bars never on a log axis
    with pytest.raises(o3dheat.MeshError):
        plot.study(study_table("hks_density", [1]), descriptor="nope")



def test_study_keeps_zero_discrepancies_on_the_chart():
    """Equal critical-point counts give a discrepancy of exactly 0: a log axis would drop those
    points off the chart; the axis becomes symlog and the points sit at 0, in view."""
    t = study_table("critical_points", range(1, 11))
    t.loc[(t["kernel"] == "weighted") & (t["scale"] <= 3), "rel_l2"] = 0.0
    fig = plot.study(t, descriptor="critical_points")
    fig.canvas.draw()
    a = fig.axes[0]
    assert a.get_yscale() == "symlog" and a.get_ylim()[0] == 0
    y = [line.get_ydata() for line in a.get_lines() if line.get_label() == "weighted"][0]
    assert (np.asarray(y) == 0).sum() == 3
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["linear", "weighted"]  # one legend, below
    assert all(ax.get_legend() is None for ax in fig.axes)

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


def test_a_non_manifold_scan_is_drawn_repaired_with_a_warning(caplog):
    """Two spheres glued at one vertex (a bowtie vertex): topology needs a 2-manifold, so the
    figure is drawn on o3dheat.repair's result (the same surface), and says so."""
    VV, FF = glued_spheres()
    assert o3dheat.check_mesh((VV, FF)).non_manifold_vertices == 1
    with caplog.at_level("WARNING", logger="o3dheat"):
        fig = plot.field((VV, FF), VV[:, 2], renderer="matplotlib" if not plot.renderer_available()[0] else "auto")
    assert "o3dheat.repair" in caplog.text and "non-manifold" in caplog.text
    assert any(t.startswith("maxima") for t in legend_texts(fig))


@needs_renderer
def test_the_legend_fits_a_narrow_figure():
    V, F = icosphere(3)
    V = V * [0.2, 0.2, 1.0]  # tall and thin: a narrow single figure
    fig = plot.field((V, F), V[:, 2] + 0.05 * np.sin(9 * V[:, 0]), label="a long field name")
    fig.canvas.draw()
    box = fig.legends[0].get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.width


def _sphere():
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)
    return m.vertex.positions.numpy().astype(float), m.triangle.indices.numpy().astype(np.int64)


@pytest.mark.parametrize("renderer", ["matplotlib", pytest.param("open3d", marks=needs_renderer)])
def test_the_picture_does_not_depend_on_the_winding(renderer, tmp_path):
    """Inward faces (common in OBJ/STL exports) or a mix of both windings draw the same picture:
    the normals that shade, lift the level sets and hide the back are taken after orienting."""
    from matplotlib.image import imread

    V, F = _sphere()
    f = V[:, 2] + 0.5 * V[:, 0]
    mixed = F.copy()
    mixed[::2] = mixed[::2, ::-1]
    images = []
    for i, faces in enumerate((F, F[:, ::-1], mixed)):
        plot.field((V, faces), f, renderer=renderer, size=2.5).savefig(tmp_path / f"{i}.png")
        images.append(imread(tmp_path / f"{i}.png"))
    for other in images[1:]:  # the same up to the rasterizer's rounding (a wrong winding made 27/255 on average)
        assert np.abs(other - images[0]).max() <= 2 / 255 and np.abs(other - images[0]).mean() < 1e-3


def test_style_arguments_are_checked():
    V, F = icosphere(1)
    for kw, what in [({"cmap": "nope"}, "cmap"), ({"size": 0}, "size"), ({"size": -1}, "size"),
                     ({"level_sets": 2.5}, "level_sets")]:
        with pytest.raises(o3dheat.MeshError, match=what):
            plot.field((V, F), V[:, 0], renderer="matplotlib", **kw)


@needs_renderer
def test_render_checks_its_range():
    V, F = icosphere(1)
    for bad in [(np.nan, 1.0), (1.0, 0.0), "ab", (1.0,)]:
        with pytest.raises(o3dheat.MeshError, match="vrange"):
            plot.render((V, F), V[:, 0], vrange=bad)


def test_a_study_of_zeros_only_is_drawn_at_zero(recwarn):
    t = study_table("critical_points", range(1, 11))
    t["rel_l2"] = 0.0
    fig = plot.study(t, descriptor="critical_points")
    fig.canvas.draw()
    assert fig.axes[0].get_yscale() == "linear" and fig.axes[0].get_ylim() == (0.0, 1.0)
    assert not [w for w in recwarn if "no positive values" in str(w.message)]


def test_an_unwelded_stl_is_drawn_welded(tmp_path):
    """An STL gives every triangle its own three vertices: drawn as they are, every triangle was
    a part of its own (a torus showed 600 minima). Welded, the torus has 1 + 1 minimum/maximum
    and 2 saddles (χ = 0)."""
    import open3d as o3d

    m = o3d.geometry.TriangleMesh.create_torus()
    m.compute_triangle_normals()
    o3d.io.write_triangle_mesh(str(tmp_path / "t.stl"), m)
    t = o3dheat.io.read_mesh(tmp_path / "t.stl")
    V = t.vertex.positions.numpy().astype(float)
    assert len(V) > len(np.unique(V, axis=0))  # vertex copies, as STL has
    fig = plot.field(t, V[:, 2], renderer="matplotlib")
    assert legend_texts(fig)[1:] == ["maxima (1)", "minima (1)", "saddles (2)"]


def test_vertices_in_no_face_are_left_out_and_said(caplog):
    V, F = icosphere(2)
    V2 = np.vstack([V, [[9.0, 9.0, 9.0]]])  # far away, in no face: not in the picture, not in its frame
    f = np.r_[V[:, 2], 100.0]
    with caplog.at_level("WARNING", logger="o3dheat"):
        fig = plot.field((V2, F), f, renderer="matplotlib")
    assert "1 vertices are in no face: not drawn" in caplog.text and "value 0" not in caplog.text
    assert fig.axes[1].get_ylim()[1] < 2  # the colour range is the drawn vertices'


def two_spheres(tiny=1.0):
    V, F = icosphere(3)
    return np.r_[V, tiny * V + [3.0, 0.0, 0.0]], np.r_[F, F + len(V)], len(V)


@needs_renderer
def test_a_part_constant_to_rounding_gets_no_critical_points():
    """Φ_t(e_i) is exactly 0 on a part without vertex i; computed, it is rounding errors there,
    with hundreds of "critical points" that buried the part under markers. Such a part is drawn
    constant: no markers on it, the legend does not count them, the panel says so."""
    V, F, n = two_spheres()
    f = np.r_[V[:n, 2], 1e-17 * np.random.default_rng(0).standard_normal(n)]
    assert sum(o3dheat.critical_points((V, F), f).counts) > 100
    assert plot.drawn_critical_points((V, F), f).counts == (1, 0, 1)
    fig = plot.field((V, F), f, level_sets=None, view=(0, -90))
    assert legend_texts(fig) == ["maxima (1)", "minima (1)", "saddles (0)"]
    img = fig.axes[0].get_images()[0].get_array()
    right = img[:, img.shape[1] // 2:]  # the flat sphere, at x = 3
    assert sum(pixels(right, c) for c in ("red", "blue", "green")) == 0
    assert any("constant on 1 part (to numerical error)" in t.get_text() for t in fig.axes[0].texts)
    g = np.r_[V[:n, 2], V[n:, 2]]  # a field that varies on both: nothing left out
    assert plot.drawn_critical_points((V, F), g).counts == o3dheat.critical_points((V, F), g).counts


@needs_renderer
def test_markers_on_a_small_part_are_sized_for_it():
    """A part a tenth the size of the other, with a noisy field: its markers cover a bounded
    share of its pixels (they were sized for the whole mesh and hid it)."""
    V, F, n = two_spheres(tiny=0.1)
    f = V[:, 2] + np.r_[np.zeros(n), 0.01 * np.random.default_rng(1).standard_normal(n)]
    cp = o3dheat.critical_points((V, F), f)
    assert 20 < sum(cp.counts) <= plot.MAX_CRITICAL_POINTS
    img = plot.render((V, F), f, level_sets=None, view=(0, -90))
    small = img[:, int(img.shape[1] * 0.85):]
    surface = ink(small).sum()
    marked = sum(pixels(small, c) for c in ("red", "blue", "green"))
    assert surface > 0 and marked < 0.15 * surface, (marked, surface)


@needs_renderer
def test_a_blank_render_is_refused(monkeypatch):
    V, F = icosphere(2)
    r = plot._renderer("open3d")
    calls = []

    def white(*args):
        calls.append(1)
        return np.full((r.size, r.size, 3), 255, np.uint8)

    monkeypatch.setattr(r, "image", white)
    with pytest.raises(o3dheat.SolverError, match="drew nothing"):
        plot.field((V, F), V[:, 2])
    assert len(calls) == 2  # drawn again once, then refused


def test_persistence_diagram_draws_sublevel_persistence_above_the_diagonal():
    """Dimension 1 is stored as (maximum, saddle) pairs of the superlevel sets, below the
    diagonal; drawn as the sublevel sets' (saddle, maximum), on or above it like dimension 0,
    with a legend that says how each reads; the classes that never die on the row ∞."""
    V, F = torus(1.0, 0.4, 40, 20)
    f = V[:, 0] + 0.1 * np.random.default_rng(0).standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    stored = d.intervals(1)
    assert len(stored) > 5 and np.all(stored[:, 1] <= stored[:, 0])  # as stored: below
    fig = plot.persistence_diagram(d, f)
    ax = fig.axes[0]
    dim0, dim1 = (np.asarray(c.get_offsets()) for c in ax.collections[:2])
    np.testing.assert_array_equal(dim0, d.intervals(0))
    np.testing.assert_array_equal(dim1, stored[:, ::-1])  # (saddle, maximum)
    for pts in (dim0, dim1):
        assert np.all(pts[:, 1] >= pts[:, 0])
    np.testing.assert_allclose(dim1[:, 1] - dim1[:, 0], d.persistence[d.dimension == 1])  # the same distance
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts[0].startswith("dim 0: born at a minimum, dies at a saddle")
    assert texts[1].startswith("dim 1: born at a saddle, dies at a maximum")
    essential = np.concatenate([np.asarray(c.get_offsets()) for c in ax.collections[2:]])
    assert len(essential) == len(d.essential) == 4  # minimum, two saddles of the genus, maximum
    assert np.all(essential[:, 1] > max(dim0.max(), dim1.max()))
    assert ax.get_yticklabels()[-1].get_text() == "∞"
    with pytest.raises(o3dheat.MeshError, match="PersistenceDiagram"):
        plot.persistence_diagram(d.intervals(0))


@needs_renderer
def test_a_small_part_holding_the_variation_gets_the_colours():
    """Φ_t(e_i) of a vertex of a part with 3% of the vertices: the others are constant (0, to the
    eigensolver's mixing of equal eigenvalues, 1e-9 of the field), and the colour range is the
    small part's, not the 2-98th percentile of the zeros (all one colour)."""
    V, F, n = two_spheres(tiny=0.5)
    V1, F1 = icosphere(1, 0.3)
    V = np.r_[V, V1 + [0.0, 0.0, 2.5]]
    F = np.r_[F, F1 + 2 * n]
    f = np.r_[1e-12 * np.random.default_rng(0).standard_normal(2 * n), V1[:, 2] + 1.0]
    fig = plot.field((V, F), f, level_sets=None, critical_points=False)
    lo, hi = fig.axes[1].get_ylim()
    assert lo < 0.75 and hi > 1.25  # the small part's values 0.7 .. 1.3 are in the range


# ------------------------------------------------------------------ tracks across scales (issue 24)
def torus_tracks(t=(0.0, 0.05, 0.1, 0.2, 0.4)):
    V, F = torus(1.0, 0.4, 40, 20)
    rng = np.random.default_rng(1)
    f = V[:, 0] + 0.3 * V[:, 2] + 0.05 * rng.standard_normal(len(V))
    t = np.asarray(t)
    Ft = o3dheat.heat_flow((V, F), f, t)
    return (V, F), Ft, o3dheat.track_critical_points((V, F), Ft, t)


@needs_renderer
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


def test_lifetime_chart_one_bar_per_track_on_a_log_axis_with_t0():
    mesh, Ft, tr = torus_tracks()
    fig = plot.lifetime_chart(tr)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and len(ax.patches) == len(tr)
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels[0] == "0"  # t = 0, one grid step left of the first positive time
    x0 = ax.get_xticks()[0]
    assert np.isclose(x0, tr.times[1] ** 2 / tr.times[2]) and ax.get_xlim()[0] < x0
    # bars start at their first scale; the tracks alive at the end run past the last scale
    alive = tr.last == len(tr.times) - 1
    ends = sorted(p.get_x() + p.get_width() for p in ax.patches)
    assert sum(e > tr.times[-1] * 1.01 for e in ends) == alive.sum()
    lives_on = [c for c in ax.collections if c.get_offsets().shape[0] == alive.sum()
                and np.allclose(c.get_offsets()[:, 0], ends[-1])]
    assert lives_on, "a marker says that they live on"
    assert any("lives on" in t.get_text() for t in ax.get_legend().get_texts())
    # the longest-lived at the top (rank 1), sorted by lifetime
    rank = {int(round(p.get_y() + p.get_height() / 2)): p.get_width() for p in ax.patches}
    widths = [rank[r] for r in sorted(rank)]
    assert widths == sorted(widths, reverse=True)
    # into a given axes; no t = 0: no "0" tick
    from matplotlib.figure import Figure

    _, _, tr2 = torus_tracks(t=(0.01, 0.05, 0.1))
    own = Figure()
    ax2 = own.subplots()
    assert plot.lifetime_chart(tr2, ax=ax2) is own and len(ax2.patches) == len(tr2)
    assert "0" not in [t.get_text() for t in ax2.get_xticklabels()]


def test_lifetime_chart_of_many_tracks_ranks_on_a_log_axis():
    """A noisy field has thousands of tracks: the rows are a log scale of the rank, so that the
    longest-lived keep rows of their own."""
    V, F = icosphere(4)
    f = V[:, 2] + 0.2 * np.random.default_rng(0).standard_normal(len(V))
    t = np.r_[0.0, np.geomspace(1e-3, 1.0, 12)]
    tr = o3dheat.track_critical_points((V, F), o3dheat.heat_flow((V, F), f, t), t)
    assert len(tr) > 100
    ax = plot.lifetime_chart(tr).axes[0]
    assert ax.get_yscale() == "log" and len(ax.patches) == len(tr)
    top, bottom = ax.get_ylim()[1], ax.get_ylim()[0]
    assert top < 1 < len(tr) < bottom  # rank 1 at the top


def test_an_offset_field_is_not_taken_for_flat():
    """Found in review: a field with a large offset (a georeferenced height, 5e6 + z) was drawn
    flat, with no critical points: flatness is now relative to the field's variation."""
    import open3d as o3d

    from o3dheat.visualization.plot import drawn_critical_points

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    z = m.vertex.positions.numpy()[:, 2].astype(float)
    assert drawn_critical_points(m, 5e6 + z).counts == o3dheat.critical_points(m, z).counts == (1, 0, 1)
