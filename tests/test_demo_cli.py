"""The demo and the ``o3dheat`` command."""

import subprocess
import sys
from pathlib import Path

import numpy as np

import o3dheat
from o3dheat.cli import main
from o3dheat.demo import run
from o3dheat.io import bumpy_torus, default_mesh, read_mesh


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
    # the exact hierarchy beside the truncated one: the full kernel at the same times
    import o3dheat

    assert m.vertex["f_exact"].shape == (n, 10)
    V, F, f = m.vertex.positions.numpy(), m.triangle.indices.numpy(), m.vertex["f"].numpy()
    assert np.allclose(m.vertex["f_exact"].numpy(), o3dheat.heat_flow((V, F), f, out["scales"]), atol=1e-9)
    cp = out["critical_points"]
    exact, truncated = cp[21:31], cp[1:11]
    # t alone smooths; not monotone at every step: the heat flow on a surface can create critical
    # points (the tracks' "creation" events: 28 -> 30 at one scale of this field)
    assert exact[0] > 3 * truncated[0] and exact[-1] < exact[0] / 5 and exact[-1] == min(exact)
    assert "exact" in text and "certificate" in text and np.all(out["truncation_bound"] > 0)


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


# ------------------------------------------------------------------------ the other commands
import open3d as o3d  # noqa: E402
import pytest  # noqa: E402


@pytest.fixture
def sphere_ply(tmp_path):
    from o3dheat.io import write_mesh

    p = tmp_path / "sphere.ply"
    write_mesh(p, o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12))
    return p


def test_cli_filters(capsys):
    assert main(["filters"]) == 0
    out = capsys.readouterr().out
    assert "heat_smooth" in out and "colorize" in out
    lines = out.strip().splitlines()
    assert len(lines) == 9  # one line per built-in filter
    for line in lines:  # plain text, whole sentences
        assert "``" not in line and "`" not in line and ":func:" not in line and line.endswith("."), line
    assert main(["filters", "hks"]) == 0
    out = capsys.readouterr().out
    assert "form" in out and "default 'density'" in out
    assert main(["filters", "nope"]) == 2
    assert "unknown filter" in capsys.readouterr().err


def test_cli_apply_chain_round_trip(tmp_path, sphere_ply, capsys):
    out, chain = tmp_path / "out.ply", tmp_path / "chain.toml"
    rc = main(["apply", str(sphere_ply), str(out), "-f", "scalar:kind=height",
               "-f", "heat_smooth:attribute=height,k=20,times=0.01+0.02", "-f", "colorize:attribute=height_smooth,column=1",
               "--save-chain", str(chain)])
    assert rc == 0, capsys.readouterr().err
    assert "height_smooth (" in capsys.readouterr().out
    m = read_mesh(out)
    assert m.vertex["height_smooth"].shape[1] == 2 and "colors" in m.vertex
    again = tmp_path / "again.npz"
    assert main(["apply", str(sphere_ply), str(again), "--chain", str(chain)]) == 0
    assert np.array_equal(read_mesh(again).vertex["height_smooth"].numpy(), m.vertex["height_smooth"].numpy())


@pytest.mark.parametrize("args, message", [
    (["-f", "nope"], "unknown filter"),
    (["-f", "hks:kk=3"], "no parameter 'kk'"),
    (["-f", "hks:k=many"], "integer"),
    (["-f", "hks:form=other"], "one of"),
    (["-f", "hks:k"], "key=value"),
    (["-f", "heat_smooth:attribute=missing,k=10"], "no vertex attribute 'missing'"),
    ([], "no filter given"),
    (["-f", "heat_smooth:attribute=height,times=0.01,0.05"], "write lists with +: times=0.01+0.05"),
    (["-f", "heat_smooth:times=0.01,0.05,0.1,k=20"], "'0.05' is not key=value: write lists with +: times=0.01+0.05+0.1"),
    (["-f", "scalar", "-f", "heat_smooth:attribute=height,k=10,times=0.01+0.02",
      "-f", "colorize:attribute=height_smooth"], "attribute 'height_smooth' has 2 columns (0..1): pick one with column=N"),
    (["--chain", "/no/chain.toml"], "cannot read chain"),
])
def test_cli_apply_user_errors(tmp_path, sphere_ply, capsys, args, message):
    out = tmp_path / "o.ply"
    assert main(["apply", str(sphere_ply), str(out)] + args) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()  # nothing half-written


def test_cli_apply_never_overwrites_by_accident(tmp_path, sphere_ply, capsys):
    before = sphere_ply.read_bytes()
    assert main(["apply", str(sphere_ply), str(sphere_ply), "-f", "scalar"]) == 2
    assert "refusing to overwrite the input" in capsys.readouterr().err
    assert sphere_ply.read_bytes() == before
    out = tmp_path / "o.ply"
    out.write_text("keep me")
    assert main(["apply", str(sphere_ply), str(out), "-f", "scalar"]) == 2
    assert out.read_text() == "keep me"
    assert main(["apply", str(sphere_ply), str(out), "-f", "scalar", "--overwrite"]) == 0
    assert main(["apply", str(sphere_ply), str(tmp_path / "o.stl"), "-f", "scalar"]) == 2
    assert main(["apply", str(tmp_path / "missing.ply"), str(tmp_path / "x.ply"), "-f", "scalar"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_cli_save_chain_never_replaces_a_file_by_accident(tmp_path, sphere_ply, capsys):
    """--save-chain obeys the no-overwrite rule and can never be the input, the output or the
    --chain file (it used to turn the input mesh into TOML); all checked before computing."""
    before = sphere_ply.read_bytes()
    out = tmp_path / "o.ply"
    chain = tmp_path / "c.toml"
    chain.write_text('[[filter]]\nname = "scalar"\n')
    cases = [
        ([str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(sphere_ply)], "should end in .toml"),
        ([str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(sphere_ply), "--overwrite"],
         "should end in .toml"),
        ([str(sphere_ply), str(out), "--chain", str(chain), "--save-chain", str(chain), "--overwrite"],
         "is the --chain file"),
        ([str(sphere_ply), str(out), "--chain", str(chain), "--save-chain", str(chain)], "is the --chain file"),
        ([str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(tmp_path)], "should end in .toml"),
        ([str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(tmp_path / "no" / "c.toml")],
         "does not exist"),
        ([str(sphere_ply), str(tmp_path / "no" / "o.ply"), "-f", "scalar"], "does not exist"),
    ]
    for args, message in cases:
        assert main(["apply"] + args) == 2, args
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err
        assert not out.exists()  # refused before anything was computed or written
    assert sphere_ply.read_bytes() == before and chain.read_text() == '[[filter]]\nname = "scalar"\n'
    (tmp_path / "d.ply").mkdir()
    assert main(["apply", str(sphere_ply), str(tmp_path / "d.ply"), "-f", "scalar"]) == 2
    assert "is a folder" in capsys.readouterr().err
    saved = tmp_path / "saved.toml"
    saved.write_text("keep me")
    assert main(["apply", str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(saved)]) == 2
    assert saved.read_text() == "keep me" and not out.exists()
    assert main(["apply", str(sphere_ply), str(out), "-f", "scalar", "--save-chain", str(saved), "--overwrite"]) == 0
    assert "scalar" in saved.read_text()


def test_cli_version(capsys):
    import o3dheat

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"o3dheat {o3dheat.__version__}"


def test_missing_output_folders_are_refused_before_any_work(tmp_path, sphere_ply, capsys, monkeypatch):
    """Every subcommand that writes a file refuses a folder that does not exist, and every one
    that writes into a folder refuses one it cannot create, before computing (exit status 2)."""
    import o3dheat.demo as demo
    import o3dheat.spectral.spectrum as spectrum
    import o3dheat.visualization.figures as figures

    monkeypatch.setattr(demo, "run", lambda **kw: pytest.fail("the demo ran"))
    monkeypatch.setattr(figures, "paper_figures", lambda *a, **kw: pytest.fail("the figures were drawn"))
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **kw: pytest.fail("eigensolve called"))
    missing = tmp_path / "nonexistent_dir"
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    cases = [
        (["apply", str(sphere_ply), str(missing / "out.ply"), "-f", "hks:k=10"], "the folder"),
        (["repair", str(sphere_ply), str(missing / "out.ply")], "the folder"),
        (["spectrum", str(sphere_ply), "-o", str(missing / "s.npz")], "the folder"),
        (["demo", "--out", str(missing / "bunny.ply")], "the folder"),
        (["figure", str(sphere_ply), "-o", str(a_file / "figs")], "cannot create the folder"),
        (["study", str(tmp_path / "study.toml"), "--out", str(a_file / "r")], "cannot create the folder"),
        (["batch", str(sphere_ply), "--out", str(a_file), "-f", "scalar", "--scheduler", "sequential"], ""),
    ]
    for args, message in cases:
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert err.startswith("o3dheat: error:") and message in err and "Traceback" not in err, (args, err)
        assert not missing.exists()
    assert "does not exist: create it first" in (main(["spectrum", str(sphere_ply), "-o", str(missing / "s.npz")]),
                                                 capsys.readouterr().err)[1]


def test_cli_figure_column(tmp_path, sphere_ply, capsys, monkeypatch):
    import o3dheat.visualization.figures as figures
    from o3dheat.io import write_mesh

    m = read_mesh(sphere_ply)
    n = len(m.vertex.positions)
    H = np.arange(3 * n, dtype=np.float64).reshape(n, 3)
    m.vertex["hks"] = o3d.core.Tensor(H)
    m.vertex["f"] = o3d.core.Tensor(H[:, :1].copy())  # (n, 1): no column needed
    p = tmp_path / "m.ply"
    write_mesh(p, m)
    seen = []
    monkeypatch.setattr(figures, "paper_figures", lambda mesh, out, field=None, **kw: seen.append(field) or Path(out) / "index.md")
    figs = str(tmp_path / "figs")
    assert main(["figure", str(p), "-o", figs, "--attribute", "hks"]) == 2
    assert ("attribute 'hks' has 3 columns (0..2): pick one with --column N (0 is the first, -1 the last)"
            in capsys.readouterr().err) and not seen
    assert main(["figure", str(p), "-o", figs, "--attribute", "hks", "--column", "3"]) == 2
    assert "column 3 does not exist" in capsys.readouterr().err
    assert main(["figure", str(p), "-o", figs, "--column", "1"]) == 2
    assert "give --attribute too" in capsys.readouterr().err
    assert main(["figure", str(p), "-o", figs, "--attribute", "hks", "--column", "-1"]) == 0
    assert main(["figure", str(p), "-o", figs, "--attribute", "f", "--overwrite"]) == 0
    assert np.array_equal(seen[0], H[:, 2]) and np.array_equal(seen[1], H[:, 0]) and seen[0].ndim == 1


def test_cli_spectrum_and_figure(tmp_path, sphere_ply, capsys):
    spec = tmp_path / "s.npz"
    assert main(["spectrum", str(sphere_ply), "-k", "9", "-o", str(spec)]) == 0
    with np.load(spec) as z:
        assert np.allclose(z["eigenvalues"][1:4], 2.0, rtol=0.05) and z["eigenvectors"].shape[1] == 9
    # issue 22: the command's file has a loader, which gives back the spectrum of the mesh
    loaded = o3dheat.Spectrum.load(spec)
    direct = o3dheat.eigensolve(o3dheat.io.read_mesh(sphere_ply), k=9)
    np.testing.assert_allclose(loaded.eigenvalues, direct.eigenvalues, rtol=1e-10)
    assert (loaded.stiffness != direct.stiffness).nnz == 0 and loaded.faces.shape == direct.faces.shape
    assert main(["spectrum", str(sphere_ply), "-k", "9", "-o", str(spec)]) == 2  # exists
    assert main(["spectrum", str(sphere_ply), "-k", "0", "-o", str(tmp_path / "t.npz")]) == 2
    figs = tmp_path / "figs"
    assert main(["figure", str(sphere_ply), "-o", str(figs), "-k", "30", "--up", "y"]) == 0
    assert (figs / "index.md").exists() and len(list(figs.glob("*.png"))) == 12  # 10 + the tracks' 2 (issue 24)
    assert main(["figure", str(sphere_ply), "-o", str(figs), "--attribute", "nope", "--overwrite"]) == 2
    assert "no vertex attribute" in capsys.readouterr().err
    before = (figs / "index.md").read_bytes()
    assert main(["figure", str(sphere_ply), "-o", str(figs), "-k", "30"]) == 2  # an earlier run's figures
    assert "earlier run" in capsys.readouterr().err and (figs / "index.md").read_bytes() == before
    assert main(["figure", str(sphere_ply), "-o", str(sphere_ply)]) == 2
    assert "is a file" in capsys.readouterr().err


def test_every_subcommand_has_examples():
    for cmd in ("demo", "info", "filters", "apply", "batch", "spectrum", "figure", "study"):
        r = subprocess.run([sys.executable, "-m", "o3dheat.cli", cmd, "--help"], capture_output=True, text=True)
        assert r.returncode == 0 and "examples:" in r.stdout, cmd


def test_cli_demo_never_replaces_an_earlier_result(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    import o3dheat.demo as demo

    calls = []
    monkeypatch.setattr(demo, "run", lambda out, **kw: (calls.append(str(out)), Path(out).parent.mkdir(exist_ok=True),
                                                        Path(out).write_text("result")))
    assert main(["demo"]) == 0 and main(["demo"]) == 0
    assert calls == ["o3dheat-demo/bunny_heat.ply", "o3dheat-demo/bunny_heat-1.ply"]
    assert main(["demo", "--out", "o3dheat-demo/bunny_heat.ply"]) == 2
    assert "exists" in capsys.readouterr().err
    assert main(["demo", "--out", "o3dheat-demo/bunny_heat.ply", "--overwrite"]) == 0


def test_every_subcommand_is_dispatched_through_one_table():
    """Issue 23: the command dispatches through a table (COMMANDS), one entry per subcommand."""
    import argparse

    from o3dheat.cli import COMMANDS, _parser

    subs = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    assert sorted(subs.choices) == sorted(COMMANDS)
    assert main([]) == 1  # no subcommand: the help, exit status 1


def test_a_bad_filter_value_names_its_parameter_and_a_nan_attribute_its_vertex(tmp_path, capsys):
    """Issue 30: '-f hks:scales=abc' said "cannot read 'abc' as an integer" without naming scales;
    apply on a NaN attribute did not name the first bad vertex (figure did)."""
    from o3dheat.io import write_mesh

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    g = m.vertex.positions.numpy()[:, 2].astype(np.float64)
    g[5] = np.nan
    m.vertex["g"] = o3d.core.Tensor(g)
    write_mesh(tmp_path / "nan.ply", m)
    assert main(["apply", str(tmp_path / "nan.ply"), str(tmp_path / "o.ply"), "-f", "hks:scales=abc"]) == 2
    assert "-f hks: parameter 'scales': cannot read 'abc' as an integer" in capsys.readouterr().err
    assert main(["apply", str(tmp_path / "nan.ply"), str(tmp_path / "o.ply"), "-f", "heat_smooth:attribute=g,k=10"]) == 2
    assert "attribute 'g' has 1 NaN or infinite values (first at vertex 5)" in capsys.readouterr().err
    assert not (tmp_path / "o.ply").exists()


def test_spectrum_mass_takes_the_kernel_variants(tmp_path, sphere_ply, capsys):
    """Issue 30: `spectrum --mass` named masses (consistent, identity, ...) where the filters, the study
    and HeatKernel name kernel variants; it takes the variants' names, and the former spellings with a
    one-line note on stderr."""
    from o3dheat.spectral import fem, variants

    with pytest.raises(SystemExit):
        main(["spectrum", "--help"])
    assert "--mass {" + ",".join(variants.VARIANTS) + "}" in capsys.readouterr().out
    for variant in variants.VARIANTS:
        out = tmp_path / f"{variant}.npz"
        assert main(["spectrum", str(sphere_ply), "-k", "5", "--mass", variant, "-o", str(out)]) == 0
        assert capsys.readouterr().err == ""
        s = o3dheat.Spectrum.load(out)
        assert s.mass_kind == variants.mass_of(variant)
        o3dheat.HeatKernel(s, variant=variant)  # the kernel of the same name pairs with it
    assert main(["spectrum", str(sphere_ply), "-k", "5", "-o", str(tmp_path / "default.npz")]) == 0
    assert o3dheat.Spectrum.load(tmp_path / "default.npz").mass_kind == variants.mass_of("weighted")
    # the former spellings (mass kinds that are not a variant's name) still work, with a note
    former = [kind for kind in fem.MASS_KINDS if kind not in variants.VARIANTS]
    assert former  # consistent, identity
    for kind in former:
        out = tmp_path / f"former-{kind}.npz"
        assert main(["spectrum", str(sphere_ply), "-k", "5", "--mass", kind, "-o", str(out)]) == 0
        err = capsys.readouterr().err
        assert err == (f"o3dheat: note: --mass {kind} is deprecated: write --mass {variants.variant_of_mass(kind)} "
                       "(the same mass)\n")
        same = o3dheat.Spectrum.load(tmp_path / f"{variants.variant_of_mass(kind)}.npz")
        np.testing.assert_array_equal(o3dheat.Spectrum.load(out).eigenvalues, same.eigenvalues)
    # anything else: one line naming the variants, before any work
    assert main(["spectrum", str(sphere_ply), "--mass", "area", "-o", str(tmp_path / "x.npz")]) == 2
    assert capsys.readouterr().err == ("o3dheat: error: unknown --mass 'area': use a kernel variant, one of "
                                       + ", ".join(variants.VARIANTS) + "\n")
    assert not (tmp_path / "x.npz").exists()
