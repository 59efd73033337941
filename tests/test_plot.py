"""Figures: written, not blank, headless (PAPER.md row P16)."""

import numpy as np
import pytest
from conftest import icosphere, torus

import o3dheat
import o3dheat.plot as plot


def not_blank(path):
    from matplotlib.image import imread

    img = imread(path)[..., :3]
    ink = np.any(img < 0.95, axis=2).mean()  # share of non-white pixels
    return img.std() > 0.05 and ink > 0.02


def test_field_with_level_sets_and_critical_points(tmp_path):
    V, F = torus(1.0, 0.4, 40, 20)
    f = V[:, 0] + 0.2 * np.random.default_rng(0).standard_normal(len(V))
    fig = plot.field((V, F), f, level_sets=8, critical_points=True, title="noisy")
    fig.savefig(tmp_path / "f.png")
    assert not_blank(tmp_path / "f.png")
    ax = fig.axes[0]
    colors = {tuple(np.round(c.get_facecolor()[0][:3], 2)) for c in ax.collections[2:]}
    assert {(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.5, 0.0)} <= colors  # red max, blue min, green saddle
    cp = o3dheat.critical_points((V, F), f)
    fig = plot.field((V, F), f, level_sets=[0.0], critical_points=cp, up="y")
    fig.savefig(tmp_path / "g.png")
    assert not_blank(tmp_path / "g.png")


def test_panels_and_scale_space(tmp_path):
    V, F = icosphere(3)
    f = V[:, 2] + 0.2 * np.random.default_rng(1).standard_normal(len(V))
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=60))
    ss = o3dheat.scale_space(K, f, stop="critical_points")
    fig = plot.fields((V, F), ss.fields[:, :3], titles=["a", "b", "c"], suptitle="scales")
    assert len(fig.axes) == 3
    fig.savefig(tmp_path / "p.png")
    assert not_blank(tmp_path / "p.png")
    fig = plot.scale_space(ss, title="Fig. 1c,d")
    fig.savefig(tmp_path / "s.png")
    assert not_blank(tmp_path / "s.png")


def test_paper_figures_for_a_mesh(tmp_path):
    V, F = icosphere(3)
    index = plot.paper_figures((V, F), tmp_path / "figs", k=40, name="sphere")
    text = index.read_text()
    pngs = sorted((tmp_path / "figs").glob("*.png"))
    assert len(pngs) == 8
    for p in pngs:
        assert p.name in text and not_blank(p)


def test_bad_input():
    V, F = icosphere(1)
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), np.zeros(3))
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), np.full(len(V), np.nan))
    with pytest.raises(o3dheat.MeshError):
        plot.field((V, F), V[:, 0], up="w")
    with pytest.raises(o3dheat.MeshError):
        plot.scale_space("not a scale space")
