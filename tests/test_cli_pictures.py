"""The commands that draw: ``o3dheat view`` (one offline page) and ``o3dheat figure`` (PNGs): what
they write and print, and bad input refused in one line before any work (nothing written)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere

from o3dheat.cli import main
from o3dheat.io import write_mesh


def write(path, V, F, **attributes):
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(V)
    m.triangle.indices = o3d.core.Tensor(F.astype(np.int32))
    for k, v in attributes.items():
        m.vertex[k] = o3d.core.Tensor(v)
    write_mesh(path, m)
    return path


def three_parts(path):
    """The report's three-part mesh: a torus, a sphere at +3 and a subdivided icosahedron at -3."""
    a = o3d.geometry.TriangleMesh.create_torus()
    b = o3d.geometry.TriangleMesh.create_sphere(0.5, 20).translate((3, 0, 0))
    c = o3d.geometry.TriangleMesh.create_icosahedron(0.7).subdivide_loop(3).translate((-3, 0, 0))
    o3d.io.write_triangle_mesh(str(path), a + b + c)
    return path


@pytest.fixture
def sphere(tmp_path):
    V, F = icosphere(3)
    bad = V[:, 0].copy()
    bad[7] = np.nan
    return write(tmp_path / "s.ply", V, F, g=V[:, 2].copy(), bad=bad)


def test_view_writes_one_page_and_says_what_it_does(sphere, tmp_path, capsys):
    out = tmp_path / "v.html"
    assert main(["view", str(sphere), "-o", str(out), "--attribute", "g", "--times", "0+0.05+0.5", "--no-tracks"]) == 0
    err = capsys.readouterr().err
    assert "vertices" in err and "wrote" in err and "3 scales by the exact heat flow" in err
    text = out.read_text()
    assert text.startswith("<!DOCTYPE html>") and "y up (the convention of .ply files" in text


@pytest.mark.parametrize("args, match", [
    (["--attribute", "nope"], "no vertex attribute 'nope'"),
    (["--attribute", "bad"], "NaN or infinite values \\(first at vertex 7\\)"),
    (["--times", "0.1+abc"], "--times takes numbers"),
    (["--max-faces", "5"], "--max-faces must be at least 100"),
    (["--column", "1"], "--column picks a column of --attribute"),
])
def test_view_refuses_bad_input_in_one_line_and_writes_nothing(sphere, tmp_path, capsys, args, match):
    import re

    out = tmp_path / "v.html"
    assert main(["view", str(sphere), "-o", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert re.search(match, err[-1]) and err[-1].startswith("o3dheat: error:") and not out.exists()


def test_view_never_replaces_a_file_unasked(sphere, tmp_path, capsys):
    out = tmp_path / "v.html"
    out.write_text("mine")
    assert main(["view", str(sphere), "-o", str(out)]) == 2
    assert "exists: add --overwrite" in capsys.readouterr().err and out.read_text() == "mine"
    assert main(["view", str(sphere), "-o", str(tmp_path / "v.png")]) == 2


def test_figure_says_when_and_why_it_decimates_and_which_axis_is_up(tmp_path, capsys):
    V, F = icosphere(4)
    mesh = write(tmp_path / "s.stl.ply", V, F)
    out = tmp_path / "fig"
    assert main(["figure", str(mesh), "-o", str(out), "--max-faces", "2000", "-k", "20"]) == 0
    err = capsys.readouterr().err
    assert "decimated 5,120 → 2,000 faces" in err and "--max-faces none keeps every face" in err
    assert "eigensolves" in err and "tracks across scales" in err
    index = (out / "index.md").read_text()
    assert "drawn with y up (the convention of .ply files" in index and "decimated from 5,120 faces" in index
    assert main(["figure", str(mesh), "-o", str(tmp_path / "f2"), "--seed", "-1"]) == 2


def test_three_figures_at_once_all_succeed_without_a_blank_panel(tmp_path):
    """pymeshlab's bone, the three-part mesh that once came out blank, and the bunny (decimated
    harder to keep the test short), drawn by three processes at once."""
    import pymeshlab
    from matplotlib.image import imread

    def not_blank(path):
        img = imread(path)[..., :3]
        return img.std() > 0.05 and np.any(img < 0.95, axis=2).mean() > 0.02

    samples = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes"
    meshes = [(samples / "bone.ply", []), (three_parts(tmp_path / "multi.ply"), []),
              (samples / "bunny.obj", ["--max-faces", "6000"])]
    meshes = [(m, a) for m, a in meshes if m.exists()]
    procs = [subprocess.Popen([sys.executable, "-m", "o3dheat.cli", "figure", str(m), "-o", str(tmp_path / m.stem),
                               "-k", "40", *a], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for m, a in meshes]
    for p, (m, _) in zip(procs, meshes, strict=True):
        out = p.communicate(timeout=600)[0]
        assert p.returncode == 0, out[-2000:]
        pngs = sorted((tmp_path / m.stem).glob("*.png"))
        assert len(pngs) == 12 and all(not_blank(png) for png in pngs), m
    assert len(meshes) == 3  # pymeshlab ships bone.ply and bunny.obj
