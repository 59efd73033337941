"""Figure recipes: the paper's kinds of figures and the study's plots, written and described."""

import numpy as np
import pytest
from conftest import glued_spheres, grid, icosphere, torus
from pictures import not_blank

import o3dheat
import o3dheat.visualization.charts as charts
import o3dheat.visualization.figures as figures


def test_paper_figures_for_a_mesh(tmp_path):
    V, F = icosphere(2)
    index = figures.paper_figures((V, F), tmp_path / "figs", k=30, name="sphere")
    text = index.read_text()
    pngs = sorted((tmp_path / "figs").glob("*.png"))
    assert len(pngs) == 10
    for p in pngs:
        assert p.name in text and not_blank(p)
    assert "red maxima, blue minima, green saddles" in text


def test_study_figures(tmp_path):
    import pandas as pd

    rows = [dict(descriptor=d, error=e, kind="jitter", kernel="weighted", scale=s, rel_l2=0.01 * (s + 1))
            for d, e in (("hks_density", ""), ("smooth", "failed")) for s in range(1, 4)]
    written = figures.study_figures(pd.DataFrame(rows), tmp_path)
    assert [p.name for p in written] == ["study_hks_density.png"] and not_blank(written[0])


@pytest.mark.slow
def test_paper_figures_on_the_bunny(tmp_path):
    from o3dheat.io import default_mesh

    mesh, name = default_mesh()
    index = figures.paper_figures(mesh, tmp_path, k=60, name=name, up="y", max_faces=8000)
    assert len(list(tmp_path.glob("*.png"))) == 10 and index.exists()


@pytest.mark.filterwarnings("error:constrained_layout not applied")  # a panel's note too wide
def test_a_non_manifold_mesh_gets_its_figures_repaired_and_no_empty_folder_on_failure(tmp_path, caplog):
    from o3dheat.cli import main

    VV, FF = glued_spheres()
    V, F = icosphere(2)
    with caplog.at_level("WARNING", logger="o3dheat"):
        out = figures.paper_figures((VV, FF), tmp_path / "figs", k=20)
    assert out.exists() and "o3dheat.repair" in caplog.text
    with pytest.raises(o3dheat.MeshError, match="one value per vertex"):
        figures.paper_figures((V, F), tmp_path / "two", field=np.c_[V[:, 0], V[:, 1]])
    assert not (tmp_path / "two").exists()
    # the command removes the folder it made when the recipe fails
    import open3d as o3d

    m = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F))
    o3dheat.io.write_mesh(tmp_path / "s.ply", m)
    assert main(["figure", str(tmp_path / "s.ply"), "-o", str(tmp_path / "k0"), "-k", "0"]) != 0
    assert not (tmp_path / "k0").exists()


def three_parts():
    """A torus, a sphere and a small icosphere apart, merged into one mesh."""
    import open3d as o3d

    V1, F1 = torus(1.0, 0.4, 36, 18)
    s = o3d.geometry.TriangleMesh.create_sphere(0.5, 14)
    V2, F2 = np.asarray(s.vertices) + [3.0, 0.0, 0.0], np.asarray(s.triangles)
    V3, F3 = icosphere(2, 0.3)
    V3 = V3 + [0.0, 3.0, 0.5]
    return np.vstack([V1, V2, V3]), np.vstack([F1, F2 + len(V1), F3 + len(V1) + len(V2)])


def wavy_sheet():
    """A rectangle with a boundary, bent so that it shades."""
    V, F = grid(2.0, 1.0, 36, 18)
    V[:, 2] = 0.25 * np.sin(2.5 * V[:, 0]) * np.cos(3.0 * V[:, 1])
    return V, F


def markers(img):
    """Pixels of the critical points' markers: a pure red, green or blue (shaded)."""
    c = img[..., :3].astype(int)
    pure = [(c[..., i] > 50) & (np.delete(c, i, axis=2).max(axis=2) < 20) for i in range(3)]
    return pure[0] | pure[1] | pure[2]


def panel_report(img):
    """(share of surface pixels, their colour spread, share of them under markers, pieces shown)."""
    from scipy import ndimage

    c = img[..., :3].astype(int)
    surface = (c < 250).any(axis=2)
    lab, k = ndimage.label(surface)
    sizes = np.bincount(lab.ravel())[1:]
    pieces = int((sizes > 2e-3 * surface.size).sum())
    spread = float(c[surface].std()) if surface.any() else 0.0
    return surface.mean(), spread, (markers(img) & surface).sum() / max(surface.sum(), 1), pieces


@pytest.mark.parametrize("which", ["three parts", "boundary"])
@pytest.mark.filterwarnings("error:constrained_layout not applied")
def test_every_recipe_shows_every_panels_surface_readably(tmp_path, monkeypatch, which):
    """Every figure of every recipe, on a multi-part mesh and on a mesh with boundary: each panel
    shows the surface (a good share of non-white pixels with varied colours; all three parts of the
    multi-part mesh), markers cover at most a bounded share of it, the PNG is not blank; the
    study's charts too. (The multi-part mesh's small parts were buried under hundreds of markers
    of rounding errors: the canonic basis is exactly 0 there.)"""
    import pandas as pd

    V, F = three_parts() if which == "three parts" else wavy_sheet()
    made = []
    save = figures._save
    monkeypatch.setattr(figures, "_save", lambda fig, path: (made.append((path.name, fig)), save(fig, path)))
    figures.paper_figures((V, F), tmp_path / "paper", k=40, name=which)
    rows = [dict(descriptor="hks_density", error="", kind=k, kernel=kern, scale=s, rel_l2=0.01 * s + e)
            for k in ("decimate", "jitter") for kern, e in (("weighted", 0.0), ("linear", 0.02)) for s in range(1, 11)]
    figures.study_figures(pd.DataFrame(rows), tmp_path)
    assert len(made) == 12  # ten figures, the study's chart and its ranking
    panels = 0
    for name, fig in made:
        assert not_blank(tmp_path / ("paper" if name.startswith("fig") else "") / name), name
        for i, ax in enumerate(fig.axes):
            if not ax.get_images():
                continue
            panels += 1
            img = np.asarray(ax.get_images()[0].get_array())
            share, spread, covered, pieces = panel_report(img)
            where = f"{name} panel {i}: surface {share:.3f}, spread {spread:.1f}, markers {covered:.3f}"
            assert share > 0.15 and spread > 10, where
            assert covered < 0.12, where
            if which == "three parts":
                assert pieces >= 3, where + f", {pieces} parts seen"
    assert panels == 4 * 3 + 4 + 5 + 4 + 3


def test_titles_count_the_critical_points_drawn(tmp_path, monkeypatch):
    """Fig. 2's ten eigenpairs leave the small parts constant up to rounding: the titles count no
    critical points of rounding errors there (hundreds were counted)."""
    V, F = three_parts()
    made = []
    save = figures._save
    monkeypatch.setattr(figures, "_save", lambda fig, path: (made.append((path.name, fig)), save(fig, path)))
    figures.paper_figures((V, F), tmp_path, k=40)
    fig = dict(made)["fig2_eigenpairs.png"]
    counts = [int(ax.get_title().split(", ")[-1].split()[0]) for ax in fig.axes if ax.get_images()]
    assert len(counts) == 4 and max(counts) < 60, counts


def gallery_cells(path):
    """The code cells of a sphinx-gallery example (split at the ``# %%`` lines), parsed."""
    import ast

    text = path.read_text()
    cells, current = [], []
    for line in text.splitlines():
        if line.startswith("# %%"):
            cells.append("\n".join(current))
            current = []
        else:
            current.append(line)
    cells.append("\n".join(current))
    return [ast.parse(c) for c in cells if c.strip()]


EXAMPLES = sorted((__import__("pathlib").Path(__file__).parents[2] / "docs" / "examples").glob("plot_*.py"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_gallery_cells_print_no_stray_repr(path):
    """sphinx-gallery prints the value of a cell's last expression: ``ax.legend()`` printed
    ``<matplotlib.legend.Legend at 0x...>`` under examples 01 and 03. A cell may end with an
    expression only if it is a print (or a docstring)."""
    import ast

    for tree in gallery_cells(path):
        last = tree.body[-1] if tree.body else None
        if isinstance(last, ast.Expr) and not isinstance(last.value, ast.Constant):
            call = last.value
            assert isinstance(call, ast.Call) and getattr(call.func, "id", None) == "print", \
                f"{path.name} line {last.lineno}: {ast.unparse(last)} prints its value"


def test_gallery_colorbars_name_the_field_drawn():
    """Example 04 draws the smoothed mean curvature: its colorbar said "height, smoothed"."""
    import ast

    path = next(p for p in EXAMPLES if p.name.startswith("plot_04"))
    calls = [n for t in gallery_cells(path) for n in ast.walk(t) if isinstance(n, ast.Call)
             and getattr(n.func, "attr", None) in ("field", "fields")]
    assert calls
    for c in calls:
        source = ast.unparse(c.args[1])
        label = next(ast.literal_eval(k.value) for k in c.keywords if k.arg == "label")
        assert source.startswith("F[") and "mean curvature" in label, (source, label)
    assert 'F = out.vertex["mean_curvature_smooth"]' in path.read_text()


# ------------------------------------------------------------------ tracks across scales (issue 24)
def bunny_like():
    from o3dheat.geometry.sampling import decimate
    from o3dheat.io import sample_mesh

    try:
        return decimate(sample_mesh("bunny"), target_faces=20000).arrays, "y"
    except o3dheat.MeshError:  # pymeshlab's sample absent: a bumpy torus of about the size
        return decimate(sample_mesh("torus"), target_faces=20000).arrays, "z"


@pytest.mark.parametrize("which", ["bunny", "three parts", "boundary"])
@pytest.mark.filterwarnings("error:constrained_layout not applied")
def test_track_figures_show_the_surface_and_one_bar_per_track(tmp_path, monkeypatch, which):
    """The tracks' figures of the default field's heat flow: the surface panel passes the checks
    of every recipe's panels (all three parts seen), the chart has one bar per track on a log
    time axis with t = 0 labelled, both are in index.md."""
    if which == "bunny":
        (V, F), up = bunny_like()
    else:
        (V, F), up = (three_parts() if which == "three parts" else wavy_sheet()), "z"
    made, charted = [], []
    save, chart = figures._save, charts.lifetime_chart
    monkeypatch.setattr(figures, "_save", lambda fig, path: (made.append((path.name, fig)), save(fig, path)))
    monkeypatch.setattr(charts, "lifetime_chart", lambda tr, **kw: (charted.append(tr), chart(tr, **kw))[1])
    index = figures.track_figures((V, F), tmp_path, name=which, up=up)
    text = index.read_text()
    assert [n for n, _ in made] == ["tracks_paths.png", "tracks_lifetimes.png"]
    for name, _ in made:
        assert name in text and not_blank(tmp_path / name), name
    paths, lifetimes = (fig for _, fig in made)
    images = [ax for ax in paths.axes if ax.get_images()]
    assert len(images) == 1
    share, spread, covered, pieces = panel_report(np.asarray(images[0].get_images()[0].get_array()))
    where = f"{which}: surface {share:.3f}, spread {spread:.1f}, markers and lines {covered:.3f}"
    assert share > 0.15 and spread > 10 and 0.0005 < covered < 0.12, where
    if which == "three parts":
        assert pieces >= 3, where + f", {pieces} parts seen"
    (tr,) = charted
    ax = lifetimes.axes[0]
    assert ax.get_xscale() == "log" and sum(len(c.get_paths()) for c in ax.collections if c.get_gid() == "bars") == len(tr) > 0
    assert ax.get_xticklabels()[0].get_text() == "0" and "t = 0 is drawn one grid step left" in text
    assert len(tr.times) == figures.TRACK_SCALES
    if which == "three parts":  # no track of a part's rounding errors (or of the order of its vertices)
        assert "left out" in text and (tr.last == len(tr.times) - 1).sum() < 20


def test_paper_figures_with_tracks_lists_them(tmp_path):
    V, F = icosphere(2)
    index = figures.paper_figures((V, F), tmp_path, k=20, tracks=True)
    pngs = sorted(p.name for p in tmp_path.glob("*.png"))
    assert len(pngs) == 12 and {"tracks_paths.png", "tracks_lifetimes.png"} <= set(pngs)
    text = index.read_text()
    assert all(p in text for p in pngs)
    with pytest.raises(o3dheat.MeshError, match="at least 3"):
        figures.track_figures((V, F), tmp_path / "x", count=2)
