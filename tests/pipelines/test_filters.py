"""Filters: registry, built-in filters, chains, plugins, point clouds (issue 5)."""

import re
import subprocess
import sys
import textwrap

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere, tmesh

import o3dheat
import o3dheat.pipelines.filters as flt

BUILTIN = ["colorize", "critical_points", "feature_approx", "heat_smooth", "hks", "scalar"]


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

    o3dheat.spectral.cache.clear_cache()
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


def test_a_chain_solves_the_eigenproblem_once(sphere, monkeypatch):
    import o3dheat.spectral.spectrum as spectrum

    o3dheat.spectral.cache.clear_cache()
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


