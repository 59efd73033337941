"""The mesh as the drawings see it (repaired, welded, oriented, vertices in no face left out) and
the figure around the panels (the legend fits) (PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import glued_spheres, icosphere

import o3dheat
import o3dheat.visualization.plot as plot


def legend_texts(fig):
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


def test_a_non_manifold_scan_is_drawn_repaired_with_a_warning(caplog):
    """Two spheres glued at one vertex (a bowtie vertex): topology needs a 2-manifold, so the
    figure is drawn on o3dheat.repair's result (the same surface), and says so."""
    VV, FF = glued_spheres()
    assert o3dheat.check_mesh((VV, FF)).non_manifold_vertices == 1
    with caplog.at_level("WARNING", logger="o3dheat"):
        fig = plot.field((VV, FF), VV[:, 2], renderer="auto")
    assert "o3dheat.repair" in caplog.text and "non-manifold" in caplog.text
    assert any(t.startswith("maxima") for t in legend_texts(fig))


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


@pytest.mark.parametrize("renderer", ["matplotlib", "raster"])
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
