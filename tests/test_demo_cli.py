"""The demo and the ``o3dheat`` command."""

import subprocess
import sys

import numpy as np

from o3dheat.cli import main
from o3dheat.demo import bumpy_torus, default_mesh, run
from o3dheat.io import read_mesh


def test_default_mesh_is_the_bunny():
    mesh, name = default_mesh()
    assert name == "bunny" and len(mesh.vertex.positions) > 20000


def test_demo_writes_everything(tmp_path):
    lines = []
    out = run(out=tmp_path / "d.ply", k=30, reduction=0.9, echo=lines.append)
    m = read_mesh(out["path"])
    n = len(m.vertex.positions)
    assert m.vertex["f_smooth"].shape == (n, 10) and m.vertex["hks"].shape == (n, 10)
    assert m.vertex.colors.shape == (n, 3)
    assert np.all(np.isfinite(m.vertex["hks"].numpy()))
    text = "\n".join(lines)
    assert "eps_inf" in text and "backend" in text and "seconds per stage" in text
    assert len(out["errors"]) == 10


def test_demo_on_procedural_surface(tmp_path):
    out = run(out=tmp_path / "t.ply", k=20, reduction=0.5, mesh=bumpy_torus(32, 16), echo=lambda s: None)
    assert out["n_vertices"] > 100


def test_cli_info_and_errors(tmp_path, capsys):
    run(out=tmp_path / "d.ply", k=10, reduction=0.95, echo=lambda s: None)
    assert main(["info", str(tmp_path / "d.ply")]) == 0
    assert "Euler characteristic: 2" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "missing.ply")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_console_script_runs():
    r = subprocess.run([sys.executable, "-m", "o3dheat.cli", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "demo" in r.stdout


def test_filters_package_importable():
    import o3dheat_filters  # noqa: F401
