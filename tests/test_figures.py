"""Figure recipes: the paper's kinds of figures and the study's plots, written and described."""

import numpy as np
import pytest
from conftest import glued_spheres, icosphere

import o3dheat
import o3dheat.figures as figures
import o3dheat.plot as plot


def not_blank(path):
    from matplotlib.image import imread

    img = imread(path)[..., :3]
    return img.std() > 0.05 and np.any(img < 0.95, axis=2).mean() > 0.02


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
@pytest.mark.skipif(not plot.renderer_available()[0], reason="no offscreen renderer here")
def test_paper_figures_on_the_bunny(tmp_path):
    from o3dheat.demo import default_mesh

    mesh, name = default_mesh()
    index = figures.paper_figures(mesh, tmp_path, k=60, name=name, up="y", max_faces=8000)
    assert len(list(tmp_path.glob("*.png"))) == 10 and index.exists()


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
