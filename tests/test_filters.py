"""Filters: registry, built-in filters, chains, plugins, point clouds (issue 5)."""

import re
import subprocess
import sys
import textwrap

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere, torus

import o3dheat
import o3dheat.pipelines.filters as flt
from o3dheat.spectral.fem import voronoi_areas

BUILTIN = ["colorize", "critical_points", "feature_approx", "heat_smooth", "hks", "scalar"]


def tmesh(V, F, **attrs):
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(np.asarray(V, np.float64))
    m.triangle.indices = o3d.core.Tensor(np.asarray(F, np.int64))
    for k, v in attrs.items():
        m.vertex[k] = o3d.core.Tensor(np.ascontiguousarray(v))
    return m


@pytest.fixture(scope="module")
def sphere():
    V, F = icosphere(3)
    return tmesh(V, F, height=V[:, 2].copy())


def sphere_points(n=4000, seed=0):
    P = np.random.default_rng(seed).standard_normal((n, 3))
    return P / np.linalg.norm(P, axis=1)[:, None]


# ---------------------------------------------------------------------------------- registry
def test_builtins_are_registered_and_described():
    assert set(BUILTIN) <= set(flt.names())
    for name in BUILTIN:
        d = flt.describe(name)
        assert d["summary"] and d["parameters"]
        for p in d["parameters"]:
            assert p.help, f"{name}.{p.name} has no help"
            assert p.type and str(p)


def test_get_checks_names_and_parameters():
    with pytest.raises(o3dheat.MeshError, match="unknown filter 'hkz'.*did you mean hks"):
        flt.get("hkz")
    with pytest.raises(o3dheat.MeshError, match="no parameter 'kk'"):
        flt.get("hks", kk=3)
    with pytest.raises(o3dheat.MeshError, match="integer"):
        flt.get("hks", k="many")
    with pytest.raises(o3dheat.MeshError, match="one of"):
        flt.get("hks", form="other")
    with pytest.raises(o3dheat.MeshError, match="axis"):
        flt.get("scalar", axis=5)
    assert flt.get("heat_smooth", times=[0.1, 0.2]).times == (0.1, 0.2)
    assert flt.get("hks", normalize=None).normalize is None


def test_parse_value_reads_command_line_text():
    import typing

    assert flt.parse_value("1e-3+0.5", tuple[float, ...]) == (1e-3, 0.5)
    assert flt.parse_value("none", typing.Optional[float]) is None  # noqa: UP045 - Optional is what is tested
    assert flt.parse_value("true", bool) is True
    with pytest.raises(o3dheat.MeshError):
        flt.parse_value("x", int)


# --------------------------------------------------------------------------- built-in filters
def test_filters_keep_attributes_and_never_mutate(sphere):
    m = sphere.clone()
    n = len(m.vertex.positions)
    m.vertex["extra"] = o3d.core.Tensor(np.arange(2 * n, dtype=np.int32).reshape(n, 2))
    m.vertex.colors = o3d.core.Tensor(np.full((n, 3), 0.25, np.float32))
    before = sorted(k for k in m.vertex)
    for name, params in [("scalar", {"kind": "mean_curvature"}), ("heat_smooth", {"k": 20}), ("hks", {"k": 20}),
                         ("critical_points", {}), ("feature_approx", {"k": 20}), ("colorize", {})]:
        out = flt.apply(m, name, **params)
        assert isinstance(out, o3d.t.geometry.TriangleMesh) and out is not m
        assert sorted(k for k in m.vertex) == before  # the input is unchanged
        assert set(before) <= {k for k in out.vertex}
        assert np.array_equal(out.vertex["extra"].numpy(), m.vertex["extra"].numpy())
    legacy = flt.apply(m.to_legacy(), "scalar")
    assert isinstance(legacy, o3d.t.geometry.TriangleMesh) and "height" in legacy.vertex


def test_scalar_fields():
    V, F = icosphere(4, radius=2.0)
    m = tmesh(V, F)
    H = flt.apply(m, "scalar", kind="mean_curvature").vertex["mean_curvature"].numpy()
    K = flt.apply(m, "scalar", kind="gaussian_curvature").vertex["gaussian_curvature"].numpy()
    assert np.allclose(H, 0.5, rtol=0.02) and np.allclose(K, 0.25, rtol=0.05)
    Vt, Ft = torus()
    Kt = flt.apply(tmesh(Vt, Ft), "scalar", kind="gaussian_curvature").vertex["gaussian_curvature"].numpy()
    assert abs(Kt @ voronoi_areas(Vt, Ft)) < 1e-9  # Gauss-Bonnet: 2π χ = 0
    h = flt.apply(m, "scalar", kind="height", axis=0).vertex["height"].numpy()
    assert np.array_equal(h, V[:, 0])
    a = flt.apply(m, "scalar", kind="height")
    n1 = flt.apply(a, "scalar", kind="noise", attribute="height", sigma=0.1, seed=3).vertex["height_noisy"].numpy()
    n2 = flt.apply(a, "scalar", kind="noise", attribute="height", sigma=0.1, seed=3).vertex["height_noisy"].numpy()
    assert np.array_equal(n1, n2) and abs(np.std(n1 - V[:, 2]) - 0.1 * 4.0) < 0.03
    with pytest.raises(o3dheat.MeshError, match="needs attribute"):
        flt.get("scalar", kind="noise")
    with pytest.raises(o3dheat.MeshError, match="no vertex attribute 'nope'"):
        flt.apply(m, "scalar", kind="noise", attribute="nope")


def test_heat_smooth_and_hks_match_the_kernel(sphere):
    V, F = (sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy())
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    f = V[:, 2]
    out = flt.apply(sphere, "heat_smooth", attribute="height", k=30)
    assert np.allclose(out.vertex["height_smooth"].numpy(), K.smooth(f, K.scales()))
    one = flt.apply(sphere, "heat_smooth", attribute="height", k=30, times=[0.01], output="s")
    assert np.allclose(one.vertex["s"].numpy(), K.smooth(f, 0.01))
    col = flt.apply(out, "heat_smooth", attribute="height_smooth", column=2, k=30, times=[0.01, 0.02])
    assert np.allclose(col.vertex["height_smooth_smooth"].numpy(), K.smooth(K.smooth(f, K.scales())[:, 2], [0.01, 0.02]))
    with pytest.raises(o3dheat.MeshError, match="columns"):
        flt.apply(out, "heat_smooth", attribute="height_smooth", k=30)
    with pytest.raises(o3dheat.MeshError, match="column 12 does not exist"):
        flt.apply(out, "heat_smooth", attribute="height_smooth", column=12, k=30)
    h = flt.apply(sphere, "hks", k=30, form="paper").vertex["hks"].numpy()
    assert np.allclose(h, K.hks(K.scales(), form="paper"))


def test_the_exact_method_is_the_full_kernel(sphere, monkeypatch):
    V, F = (sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy())
    f = V[:, 2] + 0.1 * np.sin(7 * V[:, 0])
    m = tmesh(V, F, f=f)
    out = flt.apply(m, "heat_smooth", attribute="f", method="exact", times=[0.01, 0.1], tol=1e-10)
    assert np.allclose(out.vertex["f_smooth"].numpy(), o3dheat.heat_flow((V, F), f, [0.01, 0.1], tol=1e-10),
                       rtol=0, atol=1e-12)
    # without times: the paper's scales of the k-eigenpair spectrum, the full kernel at them
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    exact = flt.apply(m, "heat_smooth", attribute="f", method="exact", k=30).vertex["f_smooth"].numpy()
    assert np.allclose(exact, o3dheat.heat_flow((V, F), f, K.scales()), rtol=0, atol=1e-9)
    spectral = flt.apply(m, "heat_smooth", attribute="f", k=30).vertex["f_smooth"].numpy()
    assert np.abs(exact - spectral).max() > 1e-3  # the truncation smooths more at t_1
    # feature_approx: f_glob = Φ_t(pr_A f) of the full kernel
    A = o3dheat.simplify_critical_points((V, F), f, keep_fraction=0.5)
    glob = flt.apply(m, "feature_approx", attribute="f", keep_fraction=0.5, method="exact", t=0.05)
    assert np.allclose(glob.vertex["f_glob"].numpy(),
                       o3dheat.heat_flow((V, F), o3dheat.topology.approximation.project(f, A), 0.05), atol=1e-9)
    # a bad method or tol is refused before any work
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    for bad, match in (({"method": "fast"}, "method must be one of 'spectral', 'exact'"),
                       ({"method": "exact", "tol": 0.0}, r"heat_smooth.tol must be in \(0, 1\), got 0.0")):
        with pytest.raises(MeshError, match=match):
            flt.Chain([("heat_smooth", {"attribute": "f", **bad})])(m)


def test_topology_filters(sphere):
    V, F = sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy()
    f = V[:, 2] + 0.05 * np.random.default_rng(0).standard_normal(len(V))
    m = tmesh(V, F, f=f)
    lab = flt.apply(m, "critical_points", attribute="f").vertex["f_critical"].numpy()
    cp = o3dheat.critical_points((V, F), f)
    assert lab.dtype == np.int8 and np.array_equal(lab, cp.kind)
    few = flt.apply(m, "critical_points", attribute="f", delta=0.5).vertex["f_critical"].numpy()
    assert np.count_nonzero(few) < np.count_nonzero(lab) and np.count_nonzero(few) >= 2
    out = flt.apply(m, "feature_approx", attribute="f", k=30, keep_fraction=0.3, scale=2)
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    A = o3dheat.simplify_critical_points((V, F), f, keep_fraction=0.3)
    g, loc = o3dheat.feature_driven(K, f, A, K.scales()[1])
    assert np.allclose(out.vertex["f_glob"].numpy(), g) and np.allclose(out.vertex["f_loc"].numpy(), loc)


def test_colorize(sphere):
    out = flt.apply(sphere, "colorize", attribute="height", colormap="viridis", range=[-1.0, 1.0])
    c = out.vertex["colors"].numpy()
    assert c.dtype == np.float32 and c.shape == (len(c), 3) and 0 <= c.min() and c.max() <= 1
    assert np.unique(c, axis=0).shape[0] > 50  # a ramp, not one colour
    with pytest.raises(o3dheat.MeshError, match="colormap"):
        flt.apply(sphere, "colorize", colormap="nope")
    with pytest.raises(o3dheat.MeshError, match="range"):
        flt.get("colorize", range=[1.0, 0.0])


# ------------------------------------------------ one rule for multi-column attributes (issue 15)
def test_every_filter_follows_the_column_rule(sphere):
    """A filter that reads one column of an (n, c) attribute needs column= (0-based, negative from
    the end); without it, it refuses listing the columns; a one-column attribute needs none."""
    V = sphere.vertex.positions.numpy()
    n = len(V)
    G = np.stack([V[:, 2], V[:, 0] + 0.1 * V[:, 1], V[:, 1]], 1)
    m = sphere.clone()
    m.vertex["g"] = o3d.core.Tensor(G)
    m.vertex["g1"] = o3d.core.Tensor(np.ascontiguousarray(G[:, 1]))  # the same column, alone
    m.vertex["g_one"] = o3d.core.Tensor(np.ascontiguousarray(G[:, 1:2]))  # (n, 1)
    m.vertex["cube"] = o3d.core.Tensor(G[:, :2].reshape(n, 1, 2).copy())  # (n, 1, 2): columns row-major
    cases = [("colorize", {}, "colors"), ("critical_points", {}, "{a}_critical"),
             ("feature_approx", {"k": 20, "keep_fraction": 0.5}, "{a}_loc"),
             ("heat_smooth", {"k": 20, "times": [0.01, 0.02]}, "{a}_smooth")]
    for name, params, output in cases:
        with pytest.raises(o3dheat.MeshError, match=r"attribute 'g' has 3 columns \(0\.\.2\): pick one with "
                                                    r"column=N \(0 is the first, -1 the last\)"):
            flt.apply(m, name, attribute="g", **params)
        with pytest.raises(o3dheat.MeshError, match=r"attribute 'g' has 3 columns \(0\.\.2\): column 3 does not exist"):
            flt.apply(m, name, attribute="g", column=3, **params)
        ref = flt.apply(m, name, attribute="g1", **params).vertex[output.format(a="g1")].numpy()
        for attribute, column in [("g", 1), ("g", -2), ("g_one", None), ("g_one", 0), ("g1", -1), ("cube", 1)]:  # cube: (n, 1, 2), column 1 is G[:, 1]
            got = flt.apply(m, name, attribute=attribute, column=column, **params)
            assert np.array_equal(got.vertex[output.format(a=attribute)].numpy(), ref), (name, attribute, column)
    # heat_smooth at one time smooths every column (no column needed); several times need one
    one = flt.apply(m, "heat_smooth", attribute="g", k=20, times=[0.01]).vertex["g_smooth"].numpy()
    assert one.shape == (n, 3)
    col = flt.apply(m, "heat_smooth", attribute="g", column=1, k=20, times=[0.01]).vertex["g_smooth"].numpy()
    assert np.allclose(one[:, 1], col)
    with pytest.raises(o3dheat.MeshError, match="give one time"):
        flt.apply(m, "heat_smooth", attribute="g", k=20)
    # scalar noise perturbs every column (it reads no single column)
    noisy = flt.apply(m, "scalar", kind="noise", attribute="g").vertex["g_noisy"].numpy()
    assert noisy.shape == (n, 3)
    with pytest.raises(o3dheat.MeshError, match="must be an integer"):
        flt.apply(m, "colorize", attribute="g", column=1.5)


def test_one_column_is_checked_before_the_eigensolve(sphere, monkeypatch):
    import o3dheat.spectral.spectrum as spectrum

    o3dheat.spectral.spectrum.clear_cache()
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("eigensolve called"))
    m = flt.apply(sphere, "scalar", kind="noise", attribute="positions")
    for name, params in [("heat_smooth", {"k": 20}), ("critical_points", {}), ("feature_approx", {"k": 20})]:
        with pytest.raises(o3dheat.MeshError, match="pick one with column=N"):
            flt.apply(m, name, attribute="positions_noisy", **params)


def test_summaries_and_help_are_plain_text():
    for name in flt.names():
        d = flt.describe(name)
        texts = [d["summary"]] + [p.help for p in d["parameters"]]
        for text in texts:
            assert "``" not in text and not re.search(r":\w+:`", text) and "`" not in text, (name, text)
            assert "\n" not in text
        assert d["summary"].endswith("."), (name, d["summary"])  # a whole paragraph, not its first line
    assert flt.describe("critical_points")["summary"].endswith("3 maximum.")
    assert flt.plain_text(":func:`o3dheat.spectral.kernel.smooth` and :meth:`~o3dheat.HeatKernel.hks`::") == \
        "o3dheat.spectral.kernel.smooth and hks:"


def test_parse_value_lists():
    assert flt.parse_value("0.01+0.05", tuple[float, ...]) == (0.01, 0.05)
    assert flt.parse_value("1e+3+2;1E+1", tuple[float, ...]) == (1000.0, 2.0, 10.0)
    assert flt.parse_value("none", tuple[float, ...] | None) is None


def test_a_chain_solves_the_eigenproblem_once(sphere, monkeypatch):
    import o3dheat.spectral.spectrum as spectrum

    o3dheat.spectral.spectrum.clear_cache()
    calls = []
    real = spectrum.eigensolve
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: calls.append(1) or real(*a, **k))
    chain = flt.Chain([("heat_smooth", {"k": 25}), ("hks", {"k": 25}), ("feature_approx", {"k": 25}),
                       ("colorize", {"attribute": "height_smooth", "column": 4})])
    out = chain(sphere)
    assert len(calls) == 1
    assert {"height_smooth", "hks", "height_glob", "height_loc", "colors"} <= {k for k in out.vertex}


def test_chain_toml_round_trip(sphere, tmp_path):
    chain = flt.Chain().append("scalar", kind="noise", attribute="height", sigma=0.1)
    chain.append(flt.get("heat_smooth", attribute="height_noisy", times=[0.01, 0.02], k=20))
    chain.append(("colorize", {"attribute": "height_noisy_smooth", "column": -1, "range": [-1.0, 1.0]}))
    path = tmp_path / "chain.toml"
    chain.save(path)
    again = flt.Chain.load(path)
    assert [repr(s) for s in again] == [repr(s) for s in chain]
    a, b = chain(sphere), again(sphere)
    assert np.array_equal(a.vertex["colors"].numpy(), b.vertex["colors"].numpy())
    bad = tmp_path / "bad.toml"
    bad.write_text("[[filter]]\nname = 'hks'\nk = 'x'\n")
    with pytest.raises(o3dheat.MeshError, match="integer"):
        flt.Chain.load(bad)
    bad.write_text("this is not toml = =")
    with pytest.raises(o3dheat.MeshError, match="TOML"):
        flt.Chain.load(bad)
    with pytest.raises(o3dheat.MeshError, match="cannot read"):
        flt.Chain.load(tmp_path / "missing.toml")


def test_batch_runs_a_chain_over_files_and_filters_do_not_import_batch(sphere, tmp_path):
    """batch.run is the one way to run a chain over files (Chain.map went: filters imported batch,
    which imports filters, issue 23); the outputs are the chain's own results."""
    import ast
    from pathlib import Path

    from o3dheat.io import read_mesh, write_mesh

    for name in ("a", "b"):
        write_mesh(tmp_path / f"{name}.ply", sphere)
    chain = flt.Chain([("scalar", {"kind": "gaussian_curvature"})])
    table = o3dheat.pipelines.batch.run(chain, tmp_path / "*.ply", tmp_path / "out", scheduler="sequential", progress=False)
    assert table["status"].tolist() == ["done", "done"]
    np.testing.assert_array_equal(read_mesh(tmp_path / "out" / "b.ply").vertex["gaussian_curvature"].numpy(),
                                  chain(read_mesh(tmp_path / "b.ply")).vertex["gaussian_curvature"].numpy())
    tree = ast.parse(Path(flt.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert "batch" not in imported and not hasattr(flt.Chain, "map")


def test_a_third_party_plugin_is_found(tmp_path, monkeypatch):
    """A throw-away distribution, as a wheel made here (no build backend needed), installed by pip."""
    import zipfile

    module = textwrap.dedent('''
        from dataclasses import dataclass
        import numpy as np
        import open3d as o3d

        @dataclass(frozen=True)
        class Double:
            """Twice an attribute.

            Parameters
            ----------
            attribute : str
                The field.
            """
            attribute: str = "height"

            def __call__(self, mesh):
                out = mesh.clone()
                out.vertex["double"] = o3d.core.Tensor(2 * mesh.vertex[self.attribute].numpy())
                return out
    ''')
    info = "tiny_plugin-0.1.dist-info"
    files = {
        "tiny_plugin/__init__.py": module,
        f"{info}/METADATA": "Metadata-Version: 2.1\nName: tiny-plugin\nVersion: 0.1\n",
        f"{info}/WHEEL": "Wheel-Version: 1.0\nGenerator: o3dheat-tests\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
        f"{info}/entry_points.txt": "[o3dheat.filters]\ndouble = tiny_plugin:Double\n",
    }
    files[f"{info}/RECORD"] = "".join(f"{name},,\n" for name in files) + f"{info}/RECORD,,\n"
    wheel = tmp_path / "tiny_plugin-0.1-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w") as z:
        for name, text in files.items():
            z.writestr(name, text)
    target = tmp_path / "site"
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-index", "--target",
                        str(target), str(wheel)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    monkeypatch.syspath_prepend(str(target))
    flt.refresh()
    try:
        assert "double" in flt.names()
        assert flt.describe("double")["parameters"][0].help == "The field."
        V, F = icosphere(1)
        out = flt.apply(tmesh(V, F, height=V[:, 2].copy()), "double")
        assert np.allclose(out.vertex["double"].numpy(), 2 * V[:, 2])
    finally:
        monkeypatch.undo()
        flt.refresh()
    assert "double" not in flt.names()


# ------------------------------------------------------------------------------- point clouds
@pytest.mark.parametrize("operators, tol", [("reconstruct", 0.02), ("robust", 0.1)])
def test_point_cloud_spectrum_of_the_unit_sphere(operators, tol):
    pytest.importorskip("robust_laplacian") if operators == "robust" else None
    from o3dheat_filters._common import Site

    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(sphere_points()))
    lam = Site(pc, operators).spectrum(k=16).eigenvalues
    ref = np.array([2] * 3 + [6] * 5 + [12] * 7)
    assert abs(lam[0]) < 1e-6 and np.allclose(lam[1:], ref, rtol=tol)


@pytest.mark.parametrize("operators", ["reconstruct", "robust"])
def test_filters_on_point_clouds(operators):
    pytest.importorskip("robust_laplacian") if operators == "robust" else None
    P = sphere_points(3000, seed=1)
    for pc in (o3d.t.geometry.PointCloud(o3d.core.Tensor(P)),
               o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))):
        out = flt.Chain([("scalar", {"kind": "height", "operators": operators}),
                         ("heat_smooth", {"k": 20, "operators": operators, "times": [0.05]}),
                         ("heat_smooth", {"operators": operators, "times": [0.05], "method": "exact",
                                          "output": "height_exact"}),
                         ("hks", {"k": 20, "operators": operators, "scales": 3}),
                         ("colorize", {"attribute": "hks", "column": 0})])(pc)
        assert isinstance(out, o3d.t.geometry.PointCloud)
        s = out.point["height_smooth"].numpy()
        # Φ_t of the height on the unit sphere: exp(-2 t / 2) z (an l = 1 harmonic)
        assert np.corrcoef(s, P[:, 2])[0, 1] > 0.99
        assert np.allclose(s, np.exp(-0.05) * P[:, 2], atol=0.05)
        assert np.allclose(out.point["height_exact"].numpy(), np.exp(-0.05) * P[:, 2], atol=0.05)
        assert out.point["hks"].shape == (3000, 3)
    if operators == "robust":
        with pytest.raises(o3dheat.MeshError, match="surface"):
            flt.apply(out, "critical_points", attribute="height", operators="robust")
    else:
        lab = flt.apply(out, "critical_points", attribute="height").point["height_critical"].numpy()
        assert lab.shape == (3000,) and set(np.unique(lab)) <= {0, 1, 2, 3}


def test_disk_cache_skips_the_eigensolve(sphere, tmp_path):
    o3dheat.spectral.spectrum.clear_cache()
    flt.set_disk_cache(tmp_path)
    try:
        flt.apply(sphere, "hks", k=12)
        assert len(list(tmp_path.glob("spectrum-*.npz"))) == 1
        o3dheat.spectral.spectrum.clear_cache()  # a new session: the disk cache answers
        spec = flt.shared_spectrum(sphere.vertex.positions.numpy(), sphere.triangle.indices.numpy(), k=12)
        assert spec.timings["cache"] is True
    finally:
        flt.set_disk_cache(None)


def test_bad_attributes_and_outputs(sphere, tmp_path):
    m = sphere.clone()
    m.vertex["short"] = o3d.core.Tensor(np.zeros(5))
    with pytest.raises(o3dheat.MeshError, match="5 rows"):
        flt.apply(m, "heat_smooth", attribute="short", k=10)
    m.vertex["nan"] = o3d.core.Tensor(np.full(len(m.vertex.positions), np.nan))
    with pytest.raises(o3dheat.MeshError, match="NaN"):
        flt.apply(m, "critical_points", attribute="nan")
    with pytest.raises(o3dheat.MeshError, match="does not exist"):
        o3dheat.io.write_mesh(tmp_path / "no" / "such" / "dir.ply", sphere)
    with pytest.raises(o3dheat.MeshError, match="TriangleMesh or PointCloud"):
        flt.apply("mesh.ply", "hks")


def _filter_modules():
    import pkgutil

    import o3dheat_filters

    return sorted(f"o3dheat_filters.{m.name}" for m in pkgutil.iter_modules(o3dheat_filters.__path__))


@pytest.mark.parametrize("module", _filter_modules())
def test_filter_examples_run(module):
    """The built-in filters' Examples (filters/ is not under pytest's doctest paths)."""
    import doctest
    import importlib

    mod = importlib.import_module(module)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, report=True)
    assert result.failed == 0 and result.attempted > 0


def test_one_of_reads_its_choices_when_checking():
    import typing

    choices = ["a", "b"]
    Choice = typing.Annotated[str, flt.OneOf(lambda: choices)]
    assert flt._check(Choice, "b", "pick.which") == "b"
    with pytest.raises(o3dheat.MeshError, match="pick.which must be one of 'a', 'b', got 'c'"):
        flt._check(Choice, "c", "pick.which")
    choices.append("c")  # defined later: accepted, and described
    assert flt._check(Choice, "c", "pick.which") == "c"
    assert flt._type_text(Choice) == "Literal['a', 'b', 'c']"
    assert flt.parse_value("c", Choice) == "c"
    with pytest.raises(o3dheat.MeshError, match="must be text"):
        flt._check(Choice, 3, "pick.which")
    with pytest.raises(TypeError, match="callable"):
        flt.OneOf(("a", "b"))


def test_a_literal_choice_of_none_is_written_none():
    import typing

    from o3dheat.pipelines.filters import parse_value

    tp = typing.Literal[None, "lambda2"]
    assert parse_value("none", tp) is None and parse_value("None", tp) is None
    assert parse_value("lambda2", tp) == "lambda2"
    assert parse_value("none", typing.Literal["a", "b"]) == "none"  # refused later, with the choices
    out = o3dheat.pipelines.filters.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8), "hks",
                                **{"normalize": parse_value("none", tp), "k": 6, "scales": 2})
    assert out.vertex["hks"].shape[1] == 2


# ------------------------------------------------------------------ a chain checked before it runs
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from o3dheat.errors import MeshError  # noqa: E402

_ATTRS = ["height", "positions", "hks", "height_smooth", "nothing", "mean_curvature", "normals", "colors", "t4",
          "out"]
_COLUMNS = st.sampled_from([None, None, 0, -1, 2, 5])
_TIMES = st.sampled_from([None, (0.01,), (0.01, 0.1)])
_OUT = st.sampled_from([None, None, "out", "positions", "height", "colors", "normals", "x", "my out", "hks_1"])


def _with_output(name, params, out):
    return name, {**params, **({"output": out} if out else {})}


_STEP = st.one_of(
    st.builds(lambda kind, a, out: _with_output("scalar", {"kind": kind, **({"attribute": a} if kind == "noise" else {})},
                                                out),
              st.sampled_from(["height", "mean_curvature", "gaussian_curvature", "noise"]), st.sampled_from(_ATTRS),
              _OUT),
    st.builds(lambda s, t, out: _with_output("hks", {"k": 8, "scales": s, **({"times": t} if t else {})}, out),
              st.integers(1, 3), _TIMES, _OUT),
    st.builds(lambda a, c, s, t, out: _with_output("heat_smooth", {"attribute": a, "column": c, "k": 8, "scales": s,
                                                                   **({"times": t} if t else {})}, out),
              st.sampled_from(_ATTRS), _COLUMNS, st.integers(1, 3), _TIMES, _OUT),
    st.builds(lambda a, c, cmap, out: _with_output("colorize", {"attribute": a, "column": c, "colormap": cmap}, out),
              st.sampled_from(_ATTRS), _COLUMNS, st.sampled_from(["coolwarm", "viridis", "no-such-map"]), _OUT),
    st.builds(lambda a, c, out: _with_output("critical_points", {"attribute": a, "column": c}, out),
              st.sampled_from(_ATTRS), _COLUMNS, _OUT),
    st.builds(lambda a, c: ("feature_approx", {"attribute": a, "column": c, "k": 8}),
              st.sampled_from(_ATTRS), _COLUMNS),
)


def _input(kind):
    """A small mesh: tensor with a height and an (n, 2, 2) attribute, or legacy with normals and
    colours (what Open3D's readers give)."""
    sphere = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    if kind == "legacy":
        legacy = sphere.to_legacy()
        legacy.compute_vertex_normals()
        legacy.vertex_colors = o3d.utility.Vector3dVector(np.asarray(legacy.vertices) * 0.5 + 0.5)
        return legacy
    mesh = flt.apply(sphere, "scalar", kind="height")
    n = len(mesh.vertex.positions)
    mesh.vertex["t4"] = o3d.core.Tensor(np.arange(4.0 * n).reshape(n, 2, 2) % 7)
    return mesh


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["tensor", "legacy"]), steps=st.lists(_STEP, min_size=1, max_size=4))
def test_chain_check_predicts_every_run(kind, steps):
    """Chain.check refuses exactly the chains whose run raises a MeshError, with the run's message,
    and otherwise predicts every attribute's column count."""
    mesh = _input(kind)
    chain = flt.Chain(steps)
    try:
        planned = chain.check(mesh)
        planned_error = None
    except MeshError as e:
        planned_error = str(e)
    run_error, out = None, mesh
    for i, step in enumerate(chain):
        try:
            out = step(out)
        except MeshError as e:
            run_error = f"step {i + 1} ({flt._name_of(step)}): {e}"
            break
    assert planned_error == run_error
    if run_error is None:
        assert planned == flt.attribute_columns(out)


def test_chain_check_on_point_clouds():
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.random.default_rng(1).standard_normal((200, 3))))
    chain = flt.Chain([("scalar", {"kind": "height"}), ("scalar", {"kind": "noise", "attribute": "height"}),
                       ("colorize", {"attribute": "height_noisy"})])
    assert chain.check(pc) == flt.attribute_columns(chain(pc)) == {"positions": 3, "height": 1, "height_noisy": 1,
                                                                   "colors": 3}
    legacy = pc.to_legacy()
    legacy.estimate_normals()
    assert flt.attribute_columns(legacy) == {"positions": 3, "normals": 3}
    with pytest.raises(MeshError, match=r"step 1 \(colorize\): attribute 'normals' has 3 columns"):
        flt.Chain([("colorize", {"attribute": "normals"})]).check(legacy)


def test_chain_check_stops_at_a_filter_without_a_plan():
    import dataclasses

    @dataclasses.dataclass(frozen=True)
    class Plugin:  # a third-party filter of the simplest kind: no plan
        def __call__(self, geometry):
            return geometry

    Hks = type(flt.get("hks"))

    @dataclasses.dataclass(frozen=True)
    class HksPlus(Hks):  # a plugin that runs differently from the filter it extends: no inherited plan
        def __call__(self, geometry):
            out = super().__call__(geometry)
            out.vertex["made_by_the_plugin"] = out.vertex["hks"]
            return out

    @dataclasses.dataclass(frozen=True)
    class Planless:  # a field named plan is not a plan
        plan: str = "none"

        def __call__(self, geometry):
            return geometry

    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    grown = flt.Chain([("hks", {"k": 8, "scales": 2})])
    grown.steps.append(HksPlus(k=8, scales=2))
    grown.append("colorize", attribute="made_by_the_plugin", column=0)
    assert grown.check(mesh) == {"positions": 3, "hks": 2}
    assert "colors" in grown(mesh).vertex
    assert flt.Chain([Planless(), ("colorize", {"attribute": "x"})]).check(mesh) == {"positions": 3}
    chain = flt.Chain([("hks", {"k": 8, "scales": 2})])
    chain.steps.append(Plugin())
    chain.append("colorize", attribute="made_by_the_plugin")  # not checkable: left to its run
    assert chain.check(mesh) == {"positions": 3, "hks": 2}
    with pytest.raises(MeshError, match="no vertex attribute 'made_by_the_plugin'"):
        chain(mesh)


def test_a_chain_refuses_before_any_work(monkeypatch):
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    chain = flt.Chain([("hks", {"k": 8}), ("colorize", {"attribute": "hks"})])
    with pytest.raises(MeshError, match=r"step 2 \(colorize\): attribute 'hks' has 10 columns"):
        chain(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6))
    with pytest.raises(MeshError, match=r"step 1 \(colorize\): unknown colormap 'nope'"):
        flt.Chain([("colorize", {"attribute": "positions", "column": 0, "colormap": "nope"})]).check(
            o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6))


def test_batch_needs_an_output_folder(tmp_path):
    chain = flt.Chain([("scalar", {"kind": "height"})])
    for bad in (None, 3, ""):
        with pytest.raises(MeshError, match=r"out_dir must be the output folder.*got " + re.escape(repr(bad))):
            o3dheat.pipelines.batch.run(chain, tmp_path / "*.ply", bad, scheduler="sequential")


def test_parameters_are_checked_before_any_work(monkeypatch):
    """critical_points' delta/keep_fraction were checked by the persistence code, after the
    eigensolve of the steps before it: a batch computed every file, then failed each."""
    import dataclasses

    from o3dheat.spectral import spectrum
    from o3dheat_filters.critical_points import CriticalPointsFilter

    calls = []
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: calls.append(1) or pytest.fail("eigensolve ran"))
    smooth = [("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 10, "scales": 2})]
    for bad, match in (({"delta": -1}, r"critical_points.delta must be >= 0, got -1.0"),
                       ({"delta": float("inf")}, r"critical_points.delta must be a finite number"),
                       ({"keep_fraction": 1.5}, r"critical_points.keep_fraction must be in \[0, 1\], got 1.5"),
                       ({"keep_fraction": "half"}, r"critical_points.keep_fraction must be a number")):
        with pytest.raises(MeshError, match=match):  # by name: at construction
            flt.Chain([*smooth, ("critical_points", {"attribute": "height_smooth", "column": 0, **bad})])
        with pytest.raises(MeshError, match=match):  # made directly: at construction too
            CriticalPointsFilter(attribute="height_smooth", column=0, **bad)

    @dataclasses.dataclass(frozen=True)
    class Blur:  # a plugin declaring its bounds with flt.param, made directly
        sigma: float = flt.param(1.0, gt=0)

        def __call__(self, geometry):
            return geometry

    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    with pytest.raises(MeshError, match=r"Blur.sigma must be > 0, got -1.0"):
        flt.Chain([*smooth, Blur(sigma=-1.0)])
    chain = flt.Chain(smooth)
    chain.steps.append(Blur(sigma=0.0))  # past append: Chain.check (run first by every chain) refuses it
    with pytest.raises(MeshError, match=r"step 3 \(Blur\): Blur.sigma must be > 0, got 0.0"):
        chain(mesh)
    assert calls == []
    assert "in [0, 1]" in str(next(p for p in flt.describe("critical_points")["parameters"]
                                    if p.name == "keep_fraction"))


@pytest.mark.parametrize("name, params, match", [
    ("hks", {"k": "20"}, r"hks.k must be an integer, got '20'"),
    ("hks", {"k": 0}, r"hks.k must be >= 1, got 0"),
    ("hks", {"scales": 0}, r"hks.scales must be in \[1, 100000\], got 0"),
    ("hks", {"times": []}, r"hks.times must have at least 1 value \(None for the default\), got \(\)"),
    ("hks", {"times": "0.1"}, r"hks.times must be a list, got '0.1'"),
    ("hks", {"times": ["0.1"]}, r"hks.times must be a number, got '0.1'"),
    ("heat_smooth", {"times": (0.1, -1.0)}, r"heat_smooth.times must be >= 0 \(every value\), got \(0.1, -1.0\)"),
    ("heat_smooth", {"tol": -1e-3}, r"heat_smooth.tol must be in \(0, 1\), got -0.001"),
    ("heat_smooth", {"tol": "1e-8"}, r"heat_smooth.tol must be a number, got '1e-8'"),
    ("heat_smooth", {"scales": 2.5}, r"heat_smooth.scales must be an integer, got 2.5"),
    ("feature_approx", {"t": -0.5}, r"feature_approx.t must be >= 0, got -0.5"),
    ("feature_approx", {"scale": 11}, r"feature_approx.scale must be in \[1, 10\], got 11"),
    ("feature_approx", {"k": -3}, r"feature_approx.k must be >= 1, got -3"),
    ("scalar", {"sigma": -0.1}, r"scalar.sigma must be >= 0, got -0.1"),
    ("scalar", {"seed": -1}, r"scalar.seed must be >= 0, got -1"),
    ("scalar", {"axis": "z"}, r"scalar.axis must be an integer, got 'z'"),
    ("colorize", {"range": [1.0]}, r"colorize.range must have exactly 2 values, got \(1.0,\)"),
    ("colorize", {"range": ["a", "b"]}, r"colorize.range must be a number, got 'a'"),
])
def test_bad_parameters_are_refused_by_name_and_directly(name, params, match):
    with pytest.raises(MeshError, match=match):
        flt.get(name, **params)
    with pytest.raises(MeshError, match=match):  # made directly: the same check, the same message
        type(flt.get(name))(**params)


@pytest.mark.parametrize("name, params", [("hks", {}), ("heat_smooth", {"attribute": "positions", "column": 2}),
                                          ("feature_approx", {"attribute": "positions", "column": 2})])
def test_a_capped_k_is_a_warning(name, params, caplog):
    """A tetrahedron has 4 vertices: k=100 eigenpairs were silently 4."""
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with caplog.at_level("WARNING", logger="o3dheat"):
        flt.apply(tmesh(V, F), name, k=100, **params)
    capped = [r for r in caplog.records if "k=100 eigenpairs asked for" in r.getMessage()]
    assert capped and capped[0].name == "o3dheat" and capped[0].levelname == "WARNING"
    assert "this surface allows 4: using k=4" in capped[0].getMessage()
    caplog.clear()
    with caplog.at_level("WARNING", logger="o3dheat"):
        flt.apply(tmesh(V, F), name, k=4, **params)
    assert not [r for r in caplog.records if "asked for" in r.getMessage()]


@pytest.mark.parametrize("step, match", [
    (("scalar", {"kind": "height", "output": "colors"}),
     r"output 'colors' must have shape \(n, 3\) \(Open3D's colors\), got 1 column"),
    (("hks", {"k": 8, "output": "normals"}), r"output 'normals' must have shape \(n, 3\) \(Open3D's normals\), got 10 columns"),
    (("heat_smooth", {"attribute": "height", "k": 8, "times": [0.1], "output": "x"}),
     r"output 'x' is a reserved PLY property \(x y z nx ny nz red green blue"),
    (("colorize", {"attribute": "height", "output": "red"}), r"output 'red' is a reserved PLY property"),
    (("critical_points", {"attribute": "height", "output": "o3dheat_colors_1"}), r"output 'o3dheat_colors_1' is a reserved"),
    (("hks", {"k": 8, "output": "alpha"}), r"output 'alpha' has 10 columns"),
    (("scalar", {"kind": "height", "output": "my field"}), r"output 'my field' is not a name a PLY property can hold"),
    (("heat_smooth", {"attribute": "height", "k": 8, "output": "hauteur_lissée"}), r"output 'hauteur_lissée' is not a name"),
])
def test_outputs_that_cannot_be_written_are_refused_before_any_work(step, match, monkeypatch):
    """Chain.check took a scalar named colors, a field named x or "my field": the run (or the PLY
    writer, after every file's eigensolve) failed."""
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    mesh = flt.apply(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6), "scalar", kind="height")
    with pytest.raises(MeshError, match=r"step 2 \(" + step[0] + r"\): " + match):
        flt.Chain([("scalar", {"kind": "height", "axis": 0, "output": "h0"}), step]).check(mesh)
    with pytest.raises(MeshError, match=match):  # apply, a filter called directly: the same check
        flt.apply(mesh, step[0], **step[1])
    with pytest.raises(MeshError, match=match):
        flt.get(step[0], **step[1])(mesh)


def test_writable_outputs_still_written(tmp_path):
    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    chain = flt.Chain([("scalar", {"kind": "noise", "attribute": "positions", "output": "colors", "sigma": 0.0}),
                       ("scalar", {"kind": "height", "output": "alpha"}),
                       ("scalar", {"kind": "height", "output": "h-2.v1"})])
    assert chain.check(mesh) == {"positions": 3, "colors": 3, "alpha": 1, "h-2.v1": 1}
    o3dheat.io.write_mesh(tmp_path / "out.ply", chain(mesh))
    back = o3dheat.io.read_mesh(tmp_path / "out.ply")
    assert {"colors", "alpha", "h-2.v1"} <= set(back.vertex)


def test_outputs_whose_ply_properties_collide_are_refused(monkeypatch):
    """PLY stores a 3-column attribute a as a_0 a_1 a_2: an attribute a_1 beside it cannot be written."""
    from o3dheat.spectral import spectrum

    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    mesh = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 6)
    grown = flt.apply(mesh, "scalar", kind="noise", attribute="positions", output="p")  # (n, 3): p_0 p_1 p_2
    with pytest.raises(MeshError, match=r"step 2 \(scalar\): output 'p_1' \(1 column\) would be stored as PLY "
                                        r"property 'p_1', which attribute 'p' has: rename it"):
        flt.Chain([("scalar", {"kind": "noise", "attribute": "positions", "output": "p"}),
                   ("scalar", {"kind": "height", "output": "p_1"})]).check(mesh)
    with pytest.raises(MeshError, match=r"output 'p_1' \(1 column\) would be stored as PLY property 'p_1'"):
        flt.apply(grown, "scalar", kind="height", output="p_1")
    with pytest.raises(MeshError, match=r"output 'h' \(2 columns\) would be stored as PLY property 'h_1', "
                                        r"which attribute 'h_1' has"):
        flt.apply(flt.apply(mesh, "scalar", output="h_1"), "hks", k=8, scales=2, output="h")
    again = flt.apply(grown, "scalar", kind="height", output="p")  # the same name: replaced, not a collision
    assert again.vertex["p"].shape == (len(mesh.vertex.positions),)


def test_filters_take_every_mesh_like():
    """Issue 22: a resampling result (Resampled) and a repair result (Repaired) were refused by the
    filters; they take any mesh-like, and (V, F) arrays, as the rest of o3dheat does."""
    import o3dheat.geometry.sampling as sampling

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    chain = flt.Chain([flt.get("scalar", kind="height"), flt.get("heat_smooth", attribute="height")])
    direct = chain(m)
    ref = direct.vertex["height_smooth"].numpy()
    for like in (o3dheat.repair(m), (V, F)):
        out = chain(like)
        np.testing.assert_allclose(out.vertex["height_smooth"].numpy(), ref, atol=1e-8)
    r = sampling.jitter(m, 0.1, seed=1)
    out = chain(r)
    assert out.vertex["height_smooth"].shape[0] == r.mesh.vertex.positions.shape[0]
    with pytest.raises(o3dheat.MeshError, match="mesh-like"):
        flt.apply(object(), "scalar", kind="height")


def test_a_point_cloud_is_reconstructed_once_per_chain_and_degenerate_clouds_are_named(monkeypatch, caplog):
    """Issue 22: each step of a chain reconstructed the cloud again (and its repairs were reported
    at every step: "dropping 24 duplicate faces" twice); degenerate clouds (collinear, coincident,
    three points, flat for a reconstruction) ended in raw Qhull or geometry-central errors."""
    import logging

    import o3dheat.geometry.sampling as sampling
    import o3dheat.spectral.spectrum as S

    S.clear_cache()
    calls = []
    real = sampling.reconstruct
    monkeypatch.setattr(sampling, "reconstruct", lambda *a, **kw: calls.append(1) or real(*a, **kw))
    pc = o3d.t.geometry.PointCloud(o3d.core.Tensor(sphere_points()))
    chain = flt.Chain([flt.get("scalar", kind="height"), flt.get("heat_smooth", attribute="height"),
                       flt.get("hks", times=[0.1])])
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        chain(pc)
    assert len(calls) == 1
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == len(set(messages))  # no repair reported twice
    rng = np.random.default_rng(0)
    line = np.c_[np.linspace(0, 1, 50), np.zeros(50), np.zeros(50)]
    flat = np.c_[rng.random((200, 2)), np.zeros(200)]
    cases = {"all coincide": np.ones((50, 3)), "one line": line, "distinct points": rng.random((3, 3)),
             "one plane": flat}
    for operators in ("reconstruct", "robust"):
        for msg, P in cases.items():
            if operators == "robust" and msg == "one plane":
                continue  # a flat patch is a surface for point-cloud operators
            with pytest.raises(o3dheat.MeshError, match=msg):
                flt.apply(o3d.t.geometry.PointCloud(o3d.core.Tensor(P)), "hks", times=[0.1], operators=operators)


def test_k_is_capped_at_the_welded_vertices_of_a_triangle_soup(caplog):
    """Issue 22 (found in review): a filter capped k at the soup's vertex count before welding,
    then eigensolve refused k > the welded count; the cap is now the vertices it solves on."""
    import logging

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 4)
    V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
    soup = o3d.t.geometry.TriangleMesh()
    soup.vertex.positions = o3d.core.Tensor(V[F.reshape(-1)])
    soup.triangle.indices = o3d.core.Tensor(np.arange(3 * len(F)).reshape(-1, 3))
    with caplog.at_level(logging.WARNING, logger="o3dheat"):
        out = flt.apply(soup, "hks", times=[0.1], k=100)
    assert out.vertex["hks"].shape[0] == 3 * len(F) and f"this surface allows {len(V)}" in caplog.text


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
    from o3dheat_filters._common import Site
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
