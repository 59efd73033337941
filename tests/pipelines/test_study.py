"""Robustness studies: tables, Dask execution, resume, failures (issue 6)."""

import numpy as np
import pandas as pd
import pytest
from conftest import icosphere, torus

import o3dheat
from o3dheat.pipelines.study import COLUMNS, DESCRIPTORS, robustness_study

KERNELS = tuple(o3dheat.VARIANTS)  # the default of robustness_study: every variant

MESHES = {"sphere": icosphere(2), "torus": torus(1.0, 0.4, 24, 12)}
RES = {"dec": {"kind": "decimate", "reduction": 0.5}, "jit": {"kind": "jitter", "amount": 0.3},
       "sub": ("subdivide", {"iterations": 1})}
SMALL = dict(k=20, scales=3, up="x")  # the height along x, the longest axis of both meshes


@pytest.fixture(scope="module")
def sequential(tmp_path_factory):
    out = tmp_path_factory.mktemp("seq")
    return out, robustness_study(MESHES, RES, out=out, scheduler="sequential", progress=False, **SMALL)


def test_table_shape_and_values(sequential):
    out, t = sequential
    assert list(t.columns) == COLUMNS and (t["error"] == "").all()
    from o3dheat.pipelines._descriptors import SI_HKS_FREQUENCIES

    per_scale = [d for d in DESCRIPTORS if d not in ("eigenvalues", "si_hks")]  # si_hks: one row per frequency
    assert len(t) == len(MESHES) * len(RES) * len(KERNELS) * (len(per_scale) * 3 + 1 + SI_HKS_FREQUENCIES)
    assert set(t["kernel"]) == set(KERNELS) and set(t["kind"]) == {"decimate", "jitter", "subdivide"}
    assert np.all(t["rel_l2"] >= 0) and np.all(np.isfinite(t["rel_l2"]))
    # midpoint subdivision keeps the surface: smoothed fields move little
    sub = t[(t["kind"] == "subdivide") & (t["descriptor"] == "smooth_height") & (t["kernel"] == "weighted")]
    assert sub["rel_l2"].max() < 0.02
    # each kernel has its own spectrum and its own times (its scales on the reference sampling)
    for kern in KERNELS:
        K = o3dheat.heat_kernel(MESHES["sphere"], k=20, variant=kern)
        rows = t[(t["mesh"] == "sphere") & (t["kernel"] == kern) & (t["descriptor"] == "smooth_height")]
        for _, g in rows.groupby("resampling"):
            np.testing.assert_allclose(g["t"].to_numpy(), K.scales(3), rtol=1e-12)
    ev = t[t["descriptor"] == "eigenvalues"].set_index(["mesh", "resampling", "kernel"])["rel_l2"]
    assert not ev.xs("weighted", level="kernel").equals(ev.xs("linear", level="kernel"))
    back = pd.read_csv(out / "study.csv", keep_default_na=False)
    assert len(back) == len(t) and np.allclose(back["rel_l2"].astype(float), t["rel_l2"], rtol=0, atol=0)
    assert (out / "study.parquet").exists()


def test_discrepancy_is_zero_for_an_identical_resampling():
    t = robustness_study({"s": icosphere(2)}, {"same": {"kind": "jitter", "amount": 0.0}},
                         scheduler="sequential", progress=False, **SMALL)
    assert t["rel_l2"].max() < 1e-9 and t["rel_linf"].max() < 1e-8


def test_dask_gives_the_same_table(sequential, tmp_path):
    pytest.importorskip("distributed")
    from distributed import Client

    from o3dheat.pipelines.cluster import local_cluster

    _, ref = sequential
    with local_cluster(2) as cluster, Client(cluster) as client:
        t = robustness_study(MESHES, RES, out=tmp_path, scheduler=client, progress=False, **SMALL)
    pd.testing.assert_frame_equal(t, ref, check_exact=True)


def test_resume_computes_only_missing_tasks(sequential, tmp_path, monkeypatch):
    out, ref = sequential
    import shutil

    shutil.copytree(out, tmp_path / "s")
    (tmp_path / "s" / "tasks" / "torus__jit.csv").unlink()  # an interrupted run
    calls = []
    real = o3dheat.pipelines.study.task
    monkeypatch.setattr(o3dheat.pipelines.study, "task", lambda *a: calls.append(a[:2]) or real(*a))
    t = robustness_study(MESHES, RES, out=tmp_path / "s", scheduler="sequential", progress=False, **SMALL)
    assert calls == [("torus", "jit")]
    pd.testing.assert_frame_equal(t, ref, check_exact=True)
    with pytest.raises(o3dheat.MeshError, match="other settings"):
        robustness_study(MESHES, RES, out=tmp_path / "s", scheduler="sequential", progress=False, k=21, scales=3)


def test_a_failing_task_is_reported_not_fatal(tmp_path):
    res = {"ok": {"kind": "jitter", "amount": 0.2}, "bad": {"kind": "remesh", "target_edge_length": 1e3}}
    t = robustness_study({"s": icosphere(2)}, res, kernels=["weighted"], descriptors=["hks_density"],
                         out=tmp_path, scheduler="sequential", progress=False, **SMALL)
    bad = t[t["resampling"] == "bad"]
    assert len(bad) == 1 and "target_edge_length" in bad["error"].iloc[0]
    assert (t[t["resampling"] == "ok"]["error"] == "").all() and len(t) == 4
    assert not (tmp_path / "tasks" / "s__bad.csv").exists()  # retried on the next run


def test_bad_arguments():
    for kw in (dict(kernels=["nope"]), dict(descriptors=["nope"]), dict(k=1), dict(scales=0)):
        with pytest.raises(o3dheat.MeshError):
            robustness_study(MESHES, RES, scheduler="sequential", **kw)
    with pytest.raises(o3dheat.MeshError, match="kind"):
        robustness_study(MESHES, {"x": {"kind": "shuffle"}}, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError):
        robustness_study({}, RES, scheduler="sequential")


def test_config_cli_and_plot(tmp_path, capsys):
    from o3dheat.cli import main

    cfg = tmp_path / "study.toml"
    cfg.write_text('k = 20\nscales = 3\nkernels = ["weighted", "linear"]\n'
                   'descriptors = ["hks_density", "smooth_height", "eigenvalues"]\n'
                   '[meshes]\nbunny = "builtin:bunny@1500"\n'
                   '[[resampling]]\nname = "dec"\nkind = "decimate"\nreduction = 0.5\n')
    assert main(["study", str(cfg), "--out", str(tmp_path / "out"), "--scheduler", "sequential"]) == 0
    text = capsys.readouterr().out
    assert "median relative L2" in text and "smooth_height" in text
    for d in ("hks_density", "smooth_height", "eigenvalues"):
        assert (tmp_path / "out" / f"study_{d}.png").stat().st_size > 5000
    cfg.write_text("k = 20\n[meshes]\n")
    assert main(["study", str(cfg), "--out", str(tmp_path / "o2")]) == 2
    assert "resampling" in capsys.readouterr().err


def test_linear_kernel_discrepancy_is_not_the_vertex_ratio(sequential):
    """The old study's "linear" kernel (X D_t Xᵀ on B-orthonormal eigenvectors) did not keep
    constants: its discrepancy under decimation was |1 - n_resampled / n_reference|. The real
    B := I kernel keeps constants, so its discrepancy is something else, and the smoothed height
    of an unchanged sampling does not move."""
    _, t = sequential
    n_ref = {name: len(V) for name, (V, F) in MESHES.items()}
    for kern in KERNELS:
        rows = t[(t["kind"] == "decimate") & (t["descriptor"] == "smooth_height") & (t["kernel"] == kern)]
        ratio = np.abs(1 - rows["vertices"].to_numpy() / rows["mesh"].map(n_ref).to_numpy())
        assert np.abs(rows["rel_l2"].to_numpy() - ratio).max() > 0.05 * ratio.max()
        assert rows["rel_l2"].max() < 0.5 * ratio.min()


def test_study_kernels_keep_constants():
    from o3dheat.pipelines._descriptors import compute as _descriptors

    V, F = icosphere(2)
    V = V * [1.3, 1.0, 0.8]
    desc, times = _descriptors(V, F, KERNELS, ["smooth_height"], 20, None, axis=0, scales=3)
    shifted, _ = _descriptors(V + [5.0, 0, 0], F, KERNELS, ["smooth_height"], 20, times, axis=0)
    for kern in KERNELS:  # the height along x shifted by 5: every kernel's Φ_t shifts by exactly 5 (K_t 1 = 1)
        np.testing.assert_allclose(shifted[kern, "smooth_height"], desc[kern, "smooth_height"] + 5.0, atol=1e-9)


def test_kind_names_use_documented_defaults_and_colliding_names_are_refused():
    t = robustness_study({"s": icosphere(2)}, ["jitter", "remesh"], kernels=["weighted"],
                         descriptors=["smooth_height"], scheduler="sequential", progress=False, **SMALL)
    assert set(t["resampling"]) == {"jitter", "remesh"} and (t["error"] == "").all()
    t2 = robustness_study({"s": icosphere(2)}, {"r": "remesh"}, kernels=["weighted"],
                          descriptors=["smooth_height"], scheduler="sequential", progress=False, **SMALL)
    np.testing.assert_array_equal(t2["rel_l2"], t[t["resampling"] == "remesh"]["rel_l2"])
    with pytest.raises(o3dheat.MeshError, match="same once made file names"):
        robustness_study({"s": icosphere(1)}, {"a b": "jitter", "a_b": "jitter"}, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="same once made file names"):
        robustness_study({"m/1": icosphere(1), "m 1": icosphere(1)}, ["jitter"], scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="kind name or a table"):
        robustness_study({"s": icosphere(1)}, [3], scheduler="sequential")


def test_cli_study_every_task_failed_exits_1_without_plots(tmp_path, capsys):
    import open3d as o3d

    from o3dheat.cli import main

    V, F = icosphere(2)
    o3dheat.io.write_mesh(tmp_path / "s.ply", o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F)))
    cfg = tmp_path / "study.toml"
    cfg.write_text('k = 10\nscales = 2\nkernels = ["weighted"]\ndescriptors = ["smooth_height"]\n'
                   '[meshes]\ns = "s.ply"\n[[resampling]]\nname = "bad"\nkind = "remesh"\n'
                   'target_edge_length = 1000.0\n')
    out = tmp_path / "out"
    assert main(["study", str(cfg), "--out", str(out), "--scheduler", "sequential"]) == 1
    captured = capsys.readouterr()
    assert "no plot" in captured.out
    assert "all 1 task(s) failed; first error: MeshError: target_edge_length" in captured.err
    assert "target_edge_length" in captured.err and not list(out.glob("*.png"))


@pytest.mark.parametrize("text, message", [
    ('k = "ten"\n[meshes]\nb = "builtin:torus"\n[[resampling]]\nkind = "jitter"\n', "k must be an integer"),
    ('[meshes]\nb = 3\n[[resampling]]\nkind = "jitter"\n', "each mesh is a file path"),
    ('kernels = "weighted"\n[meshes]\nb = "builtin:torus"\n[[resampling]]\nkind = "jitter"\n',
     "kernels must be a list of names"),
    ('resampling = 5\n[meshes]\nb = "builtin:torus"\n', "resampling must be [[resampling]] tables"),
    ('descriptors = [1]\n[meshes]\nb = "builtin:torus"\n[[resampling]]\nkind = "jitter"\n', "list of names"),
    ('resampling = [3]\n[meshes]\nb = "builtin:torus"\n', "each [[resampling]] is a table"),
])
def test_cli_study_config_mistakes_are_one_line(tmp_path, capsys, text, message):
    from o3dheat.cli import main

    cfg = tmp_path / "s.toml"
    cfg.write_text(text)
    assert main(["study", str(cfg), "--out", str(tmp_path / "o"), "--scheduler", "sequential"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_one_kernel_name_is_a_list_of_one():
    t = robustness_study({"s": icosphere(1)}, ["jitter"], kernels="weighted", descriptors="smooth_height",
                         scheduler="sequential", progress=False, k=8, scales=2)
    assert set(t["kernel"]) == {"weighted"} and set(t["descriptor"]) == {"smooth_height"}


def test_dask_starts_the_largest_resamplings_first():
    from o3dheat.pipelines.study import _cost

    specs = {"sub": {"kind": "subdivide"}, "aniso": {"kind": "anisotropic"}, "jit": {"kind": "jitter"},
             "rem": {"kind": "remesh", "edge_factor": 1.5}, "dec": {"kind": "decimate", "reduction": 0.8},
             "bad": {"kind": "subdivide", "iterations": "x"}}
    order = sorted(specs, key=lambda name: -_cost(specs[name], 1000))
    assert order == ["sub", "aniso", "jit", "bad", "rem", "dec"]


def test_exact_method_smooths_with_the_full_kernel(monkeypatch):
    from o3dheat.geometry import sampling
    from o3dheat.pipelines._descriptors import compute as _descriptors
    from o3dheat.spectral import spectrum

    V, F = icosphere(2)
    table = robustness_study({"s": (V, F)}, {"dec": {"kind": "decimate", "reduction": 0.5}}, kernels=["weighted"],
                             descriptors=["smooth_height", "critical_points"], scheduler="sequential",
                             progress=False, method="exact", **SMALL)
    K = o3dheat.heat_kernel((V, F), k=20)
    t = K.scales(3)  # the scales stay those of the reference spectrum
    rows = table[table["descriptor"] == "smooth_height"]
    np.testing.assert_allclose(rows["t"].to_numpy(), t, rtol=1e-12)
    # the reference's smoothed height is the full kernel's
    desc, _ = _descriptors(V, F, ["weighted"], ["smooth_height"], 20, {"weighted": t}, 2, method="exact")
    ref = o3dheat.heat_flow((V, F), V[:, 2], t)
    assert np.allclose(desc["weighted", "smooth_height"], ref, atol=1e-9)
    assert not np.allclose(desc["weighted", "smooth_height"], K.smooth(V[:, 2], t), atol=1e-6)
    # a resampling needs no eigensolve for these descriptors
    r = sampling.decimate((V, F), reduction=0.5)
    monkeypatch.setattr(spectrum, "eigensolve", lambda *a, **k: pytest.fail("an eigensolve ran"))
    _descriptors(r.V, r.F, ["weighted"], ["smooth_height", "critical_points"], 20, {"weighted": t}, 2,
                 method="exact")
    with pytest.raises(o3dheat.MeshError, match="unknown method 'fast'"):
        robustness_study({"s": (V, F)}, ["jitter"], method="fast", scheduler="sequential")


FAILING = '''import sys
import o3dheat.pipelines._descriptors


def failing(*args, **kwargs):
    raise o3dheat.SolverError("no spectrum here")


o3dheat.pipelines._descriptors.compute = failing  # at the top level: in the workers too (they run this script again)

if __name__ == "__main__":
    from o3dheat.cli import main
    sys.exit(main(["study", "study.toml", "--out", "out"]))
'''


def test_a_study_whose_every_task_fails_on_a_local_cluster_is_a_clean_summary(tmp_path):
    pytest.importorskip("distributed")
    import subprocess
    import sys

    import open3d as o3d

    for name, r in (("s", 1.0), ("t", 2.0)):
        o3dheat.io.write_mesh(tmp_path / f"{name}.ply", o3d.t.geometry.TriangleMesh.create_sphere(r, 8))
    (tmp_path / "study.toml").write_text(
        'k = 10\nscales = 2\nkernels = ["weighted"]\ndescriptors = ["hks_density"]\n[meshes]\ns = "s.ply"\n'
        't = "t.ply"\n[[resampling]]\nkind = "jitter"\n[[resampling]]\nkind = "subdivide"\n'
        '[[resampling]]\nkind = "decimate"\n')
    (tmp_path / "run.py").write_text(FAILING)
    run = subprocess.run([sys.executable, "run.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    assert "all 6 task(s) failed; first error: the reference sampling failed: SolverError: no spectrum here" \
        in run.stderr
    for noise in ("Traceback", "Compute Failed", "Stream is closed", "still alive", "CommClosedError"):
        assert noise not in run.stderr, run.stderr
    assert len(run.stderr.strip().splitlines()) == 6 + 1 + 6  # a warning per task, the summary, the list


def test_an_unreachable_scheduler_leaves_no_study_folder(tmp_path, capsys):
    import dask
    import distributed  # noqa: F401  (its config defaults first)

    from o3dheat.cli import main

    out = tmp_path / "out"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(o3dheat.MeshError, match="cannot connect to the Dask scheduler"):
            robustness_study(MESHES, RES, out=out, scheduler="tcp://127.0.0.1:9", progress=False, **SMALL)
        assert not out.exists()
        cfg = tmp_path / "study.toml"
        cfg.write_text('k = 10\nscales = 2\nkernels = ["weighted"]\n[meshes]\nb = "builtin:torus"\n'
                       '[[resampling]]\nkind = "jitter"\n')
        assert main(["study", str(cfg), "--out", str(out), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert "cannot connect to the Dask scheduler" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_bools_strings_and_negatives_are_refused_before_any_work():
    for kw, message in ((dict(scales=True), "scales must be an integer >= 1, got True"),
                        (dict(scales=-3), "scales must be an integer >= 1, got -3"),
                        (dict(k="20"), "k must be an integer >= 2, got '20'"),
                        (dict(progress="no"), "progress must be True, False or None")):
        with pytest.raises(o3dheat.MeshError, match=message):
            robustness_study(MESHES, RES, scheduler="sequential", **{**SMALL, **kw})
    # a resampling's own parameters: refused by its function, a row that names them
    t = robustness_study({"s": icosphere(1)}, {"neg": {"kind": "jitter", "amount": -1}, "seed": {"kind": "jitter",
                         "seed": -1}, "text": {"kind": "decimate", "reduction": "half"}}, kernels=["weighted"],
                         descriptors=["hks_density"], scheduler="sequential", progress=False, k=8, scales=2)
    errors = dict(zip(t["resampling"], t["error"], strict=True))
    assert "amount must be a number >= 0, got -1" in errors["neg"]
    assert "seed must be an integer from 0" in errors["seed"]
    assert "reduction must be a number in [0, 1), got 'half'" in errors["text"]


def _tracks(last, positions, times=(1.0, 10.0, 100.0)):
    """Maximum tracks born at scale 0 on vertices 0, 1, ... living to ``last``."""
    from o3dheat.topology.tracking import Tracks

    p, T = len(last), len(times)
    vertex = np.where(np.arange(T)[None, :] <= np.asarray(last)[:, None], np.arange(p)[:, None], -1)
    pers = np.where(vertex >= 0, 1.0, np.nan)
    return Tracks(np.array(["maximum"] * p, dtype=object), vertex, (vertex >= 0).astype(np.int64),
                  np.array(times), [], np.asarray(positions, float), _persistence=pers)


def test_track_lifetime_errors_by_hand():
    """Issue 24: the track_lifetime error on hand-made tracks, times 1, 10, 100. Reference: A lives
    to the end, B dies after scale 0, far from A; resampling: A' dies after scale 1, B' lives on."""
    from o3dheat.pipelines._descriptors import lifetime_errors as _lifetime_errors

    P = [[0.0, 0, 0], [1.0, 0, 0]]
    ref, res = _tracks([2, 0], P), _tracks([1, 2], P)
    l2, inf = _lifetime_errors(res, ref, np.ptp(np.array(P), axis=0))
    # scale 0: A |log(10/100)| / log(100) = 0.5, B |log(100/1)| / log(100) = 1; scale 1: A
    # |log(10/100)| / log(10) = 1; scale 2: A alive, nothing within 5% of the diagonal: 1
    np.testing.assert_allclose(l2, [np.sqrt((0.25 + 1) / 2), 1.0, 1.0])
    np.testing.assert_allclose(inf, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(_lifetime_errors(ref, ref, np.ones(3)), (np.zeros(3), np.zeros(3)))


def test_track_lifetime_on_a_bunny():
    """The extrema of the bunny's smoothed height live about as long on its resamplings: errors in
    [0, 1], one row per scale, zero for an identical resampling."""
    import o3dheat.geometry.sampling
    import o3dheat.io

    m = o3dheat.geometry.sampling.decimate(o3dheat.io.sample_mesh("bunny"), target_faces=6000).mesh
    res = {"same": {"kind": "jitter", "amount": 0.0}, "sub": "subdivide", "dec": {"kind": "decimate", "reduction": 0.5}}
    t = robustness_study({"b": m}, res, kernels=["weighted"], descriptors=["track_lifetime"], scales=6, k=30,
                         scheduler="sequential", progress=False)
    assert (t["error"] == "").all() and len(t) == 3 * 6 and set(t["scale"]) == set(range(1, 7))
    assert t["rel_l2"].between(0, 1).all() and (t["rel_l2"] <= t["rel_linf"] + 1e-12).all()
    assert t.loc[t["resampling"] == "same", "rel_linf"].max() == 0
    assert t.loc[t["resampling"] != "same", "rel_l2"].mean() < 0.5


def test_diagram_descriptor_is_gudhis_distance_on_the_lower_star_diagrams():
    """Issue 31: the "diagram" descriptor compares persistence diagrams, no transfer: its pairs are
    gudhi's own lower-star persistence of the field (an independent computation), and its distances
    gudhi's bottleneck and Hera Wasserstein on them, over the reference field's range."""
    pytest.importorskip("gudhi")
    import gudhi
    import gudhi.hera

    from o3dheat.geometry import resample
    from o3dheat.pipelines._descriptors import diagram_distances, finite_diagram

    def lower_star(V, F, f):
        st = gudhi.SimplexTree()
        for i, v in enumerate(f):
            st.insert([i], filtration=float(v))
        for a, b in {tuple(sorted(e)) for tri in F for e in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[0], tri[2]))}:
            st.insert([int(a), int(b)], filtration=float(max(f[a], f[b])))  # before the triangles: their own value
        for tri in F:
            st.insert([int(x) for x in tri], filtration=float(f[tri].max()))
        st.make_filtration_non_decreasing()
        st.compute_persistence()
        return [st.persistence_intervals_in_dimension(d) for d in (0, 1)]

    V, F = torus(1.0, 0.4, 24, 12)
    r = resample((V, F), "jitter", amount=0.3)
    rng = np.random.default_rng(0)
    f = V[:, 0] + 0.3 * V[:, 2] + 0.05 * rng.standard_normal(len(V))
    g = r.V[:, 0] + 0.3 * r.V[:, 2] + 0.05 * rng.standard_normal(len(r.V))
    ours = [finite_diagram(o3dheat.persistence((V, F), f)) + (float(np.ptp(f)),),
            finite_diagram(o3dheat.persistence((r.V, r.F), g)) + (float(np.ptp(g)),)]
    for (d0, d1, _), (W, FF, h) in zip(ours, [(V, F, f), (r.V, r.F, g)], strict=True):
        ref0, ref1 = (x[np.isfinite(x[:, 1])] for x in lower_star(W, FF, h))
        assert gudhi.bottleneck_distance(d0, ref0, 0.0) < 1e-12 and gudhi.bottleneck_distance(d1, ref1, 0.0) < 1e-12
    w, b = diagram_distances(ours[1], ours[0])
    span = np.ptp(f)
    assert np.isclose(b, max(gudhi.bottleneck_distance(ours[1][i], ours[0][i], 0.0) for i in (0, 1)) / span)
    assert np.isclose(w, max(gudhi.hera.wasserstein_distance(ours[1][i], ours[0][i], order=1.0, delta=1e-6)
                             for i in (0, 1)) / span, rtol=1e-5)
    assert 0 < b <= w


def test_the_new_descriptors_in_a_study():
    t = robustness_study({"sphere": icosphere(2)}, {"dec": {"kind": "decimate", "reduction": 0.5}}, kernels="weighted",
                         descriptors=["wks", "si_hks", "diagram"], scheduler="sequential", progress=False, **SMALL)
    assert (t["error"] == "").all() and set(t["descriptor"]) == {"wks", "si_hks", "diagram"}
    assert np.all(np.isfinite(t["rel_l2"])) and np.all(t["rel_l2"] >= 0)
    wks = t[t["descriptor"] == "wks"]
    K = o3dheat.heat_kernel(icosphere(2), k=20)
    from o3dheat.spectral.signatures import wks_energies

    assert np.allclose(wks["t"], wks_energies(K, 3)[0])  # the reference's log-energies, in the t column
