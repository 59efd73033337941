"""A chain over many files: resume, failures, name checks, sequential = Dask bit for bit, the command."""

import os
import shutil

import numpy as np
import open3d as o3d
import pytest
from conftest import torus

import o3dheat
from o3dheat.cli import main
from o3dheat.io import read_mesh, write_mesh
from o3dheat.pipelines.batch import COLUMNS, MANIFEST, expand, outputs, run
from o3dheat.pipelines.filters import Chain

STEPS = [("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 20, "scales": 3}),
         ("colorize", {"attribute": "height_smooth", "column": 1})]
FLAGS = ["-f", "scalar:kind=height", "-f", "heat_smooth:attribute=height,k=20,scales=3",
         "-f", "colorize:attribute=height_smooth,column=1"]


def _mesh(i):
    if i == 2:
        V, F = torus(1.0, 0.4, 20, 10)
        m = o3d.t.geometry.TriangleMesh(o3d.core.Tensor(V), o3d.core.Tensor(F))
    else:
        m = o3d.t.geometry.TriangleMesh.create_sphere(1.0 + i, 10 + 2 * i)
    V = m.vertex.positions.numpy().astype(np.float64)
    m.vertex.positions = o3d.core.Tensor(V * [1.2, 1.0, 0.9] + 0.03 * np.sin(3 * V[:, [1, 2, 0]]))
    return m


@pytest.fixture
def scans(tmp_path):
    d = tmp_path / "scans"
    d.mkdir()
    for i in range(3):
        write_mesh(d / f"m{i}.ply", _mesh(i))
    return d


def _bad(folder):
    """A truncated PLY (its header promises more than the file holds) and a text file."""
    good = (folder / "m0.ply").read_bytes()
    (folder / "cut.ply").write_bytes(good[: len(good) // 2])
    (folder / "text.ply").write_text("not a mesh\n")


def _attributes(path):
    m = read_mesh(path)
    return {k: m.vertex[k].numpy() for k in m.vertex}, m.triangle.indices.numpy()


def _same_outputs(a, b):
    names = sorted(p.name for p in a.glob("*.ply"))
    assert names and names == sorted(p.name for p in b.glob("*.ply"))
    for name in names:
        (va, fa), (vb, fb) = _attributes(a / name), _attributes(b / name)
        assert va.keys() == vb.keys() and np.array_equal(fa, fb)
        for k in va:
            assert va[k].dtype == vb[k].dtype and np.array_equal(va[k], vb[k]), (name, k)


# --------------------------------------------------------------------------------- sequential
def test_sequential_table_outputs_and_resume(scans, tmp_path):
    out = tmp_path / "out"
    t = run(Chain(STEPS), str(scans / "*.ply"), out, scheduler="sequential", progress=False)
    assert list(t.columns) == COLUMNS and t["status"].tolist() == ["done"] * 3
    assert t["input"].tolist() == [str(scans / f"m{i}.ply") for i in range(3)]
    assert t["output"].tolist() == [str(out / f"m{i}.ply") for i in range(3)]
    assert (t["seconds"] > 0).all() and (t["error"] == "").all()
    import o3dheat.spectral.spectrum

    assert len(o3dheat.spectral.cache.SPECTRA.entries) == 0  # a file's spectra are freed before the next file
    direct = Chain(STEPS)(read_mesh(scans / "m1.ply"))
    got, _ = _attributes(out / "m1.ply")
    assert set(got) == {"positions", "height", "height_smooth", "colors"}
    np.testing.assert_allclose(got["height_smooth"], direct.vertex["height_smooth"].numpy(), rtol=0, atol=1e-12)
    assert Chain.load(out / MANIFEST).to_dict() == Chain(STEPS).to_dict()  # a chain file: replayable

    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in out.glob("*.ply")}
    (out / "m2.ply").unlink()  # an interrupted run: m2 never written
    t = run(Chain(STEPS), [scans / "m*.ply"], out, scheduler="sequential", progress=False)
    assert t["status"].tolist() == ["skipped", "skipped", "done"] and t["seconds"].iloc[0] == 0
    for name in ("m0.ply", "m1.ply"):
        assert (out / name).stat().st_mtime_ns == before[name][0]
    assert (out / "m2.ply").read_bytes() == before["m2.ply"][1]
    t = run(STEPS, scans / "m0.ply", out, scheduler="sequential", overwrite=True, progress=False)
    assert t["status"].tolist() == ["done"] and (out / "m0.ply").read_bytes() == before["m0.ply"][1]


def test_a_bad_file_fails_alone_and_is_retried(scans, tmp_path, capsys):
    _bad(scans)
    out = tmp_path / "out"
    t = run(STEPS, scans / "*.ply", out, scheduler="sequential", progress=False)
    status = dict(zip((os.path.basename(p) for p in t["input"]), t["status"], strict=True))
    assert status == {"cut.ply": "failed", "m0.ply": "done", "m1.ply": "done", "m2.ply": "done", "text.ply": "failed"}
    errors = t.set_index("status").loc["failed", "error"].tolist()
    assert any("truncated" in e for e in errors) and all(str(scans) in e for e in errors)  # the paths as given
    assert not (out / "cut.ply").exists() and not (out / "text.ply").exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # no temporary file left
    # the command: exit status 1, one line per failure naming the file, no traceback
    rc = main(["batch", str(scans / "*.ply"), "--out", str(out), "--scheduler", "sequential"] + FLAGS)
    assert rc == 1
    cap = capsys.readouterr()
    assert "5 files: 0 done, 3 skipped" in cap.out and "2 failed" in cap.out
    assert f"  {scans / 'cut.ply'}: " in cap.err and "Traceback" not in cap.err
    # a filter that fails on every file: reported, nothing written
    rc = main(["batch", str(scans / "m*.ply"), "--out", str(tmp_path / "o2"), "--scheduler", "sequential",
               "-f", "heat_smooth:attribute=missing,k=10"])
    cap = capsys.readouterr()
    assert rc == 1 and cap.err.count("no vertex attribute 'missing'") >= 3
    assert not list((tmp_path / "o2").glob("*.ply"))


# --------------------------------------------------------------------------------- refused
def test_names_are_checked_before_any_work(scans, tmp_path):
    other = tmp_path / "other"
    other.mkdir()
    write_mesh(other / "M1.npz", _mesh(0))
    out = tmp_path / "out"
    with pytest.raises(o3dheat.MeshError, match="would both be written to"):
        run(STEPS, [scans / "*.ply", other / "*.npz"], out, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="no file matches"):
        run(STEPS, [scans / "*.ply", tmp_path / "none" / "*.ply"], out, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="no such file"):
        run(STEPS, [scans / "missing.ply"], out, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="empty chain"):
        run([], scans / "*.ply", out, scheduler="sequential")
    with pytest.raises(o3dheat.MeshError, match="suffix"):
        run(STEPS, scans / "*.ply", out, suffix=".obj", scheduler="sequential")
    assert not out.exists()
    # the input folder as the output folder: an output would replace its input
    before = {p.name: p.read_bytes() for p in scans.iterdir()}
    with pytest.raises(o3dheat.MeshError, match="refusing to overwrite the input"):
        run(STEPS, scans / "*.ply", scans, scheduler="sequential", overwrite=True)
    assert {p.name: p.read_bytes() for p in scans.iterdir()} == before
    # ... which is fine when the outputs get other names
    t = run(STEPS[:1], scans / "m0.ply", scans, suffix=".npz", scheduler="sequential", progress=False)
    assert t["status"].tolist() == ["done"] and (scans / "m0.npz").exists()
    assert (scans / "m0.ply").read_bytes() == before["m0.ply"]


def test_an_unreachable_scheduler_leaves_no_folder(scans, tmp_path):
    import dask
    import distributed  # noqa: F401  (its config defaults first: set() must not shadow them)

    out = tmp_path / "out"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(o3dheat.MeshError, match="cannot connect to the Dask scheduler"):
            run(STEPS, scans / "*.ply", out, scheduler="tcp://127.0.0.1:9")
    assert not out.exists()  # nothing written, not even the chain record
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(o3dheat.MeshError, match="not a writable folder"):
        run(STEPS, scans / "*.ply", blocker / "out", scheduler="sequential")


def test_another_chain_or_foreign_files_are_refused(scans, tmp_path):
    out = tmp_path / "out"
    run(STEPS, scans / "*.ply", out, scheduler="sequential", progress=False)
    other = STEPS[:1] + [("hks", {"k": 20, "scales": 2})]
    with pytest.raises(o3dheat.MeshError, match="another chain"):
        run(other, scans / "*.ply", out, scheduler="sequential")
    _bad(scans)
    shutil.copy(out / "m0.ply", out / "cut.ply")  # an earlier result for a file that fails now
    t = run(other, scans / "*.ply", out, scheduler="sequential", overwrite=True, progress=False)
    assert (t["status"] == "done").sum() == 3 and "hks" in read_mesh(out / "m0.ply").vertex
    assert not (out / "cut.ply").exists()  # not passed off as a result of this run
    assert Chain.load(out / MANIFEST).to_dict() == Chain(other).to_dict()
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "m0.ply").write_text("someone's file")
    with pytest.raises(o3dheat.MeshError, match="not written by a batch"):
        run(STEPS, scans / "m0.ply", foreign, scheduler="sequential")
    assert (foreign / "m0.ply").read_text() == "someone's file"


def test_expand_and_outputs(tmp_path):
    (tmp_path / "a" / "deep").mkdir(parents=True)
    for p in ("a/x.ply", "a/y.ply", "a/deep/z.ply", "a/.hidden.ply"):
        (tmp_path / p).write_text("")
    got = expand([str(tmp_path / "a" / "**" / "*.ply"), tmp_path / "a" / "x.ply"])
    assert [p.name for p in got] == ["z.ply", "x.ply", "y.ply"]
    with pytest.raises(o3dheat.MeshError, match="is a folder"):
        expand(tmp_path / "a")
    with pytest.raises(o3dheat.MeshError, match="no input"):
        expand([])
    assert [p.name for p in outputs(got, tmp_path / "o", ".npz")] == ["z.npz", "x.npz", "y.npz"]


# --------------------------------------------------------------------------------- Dask
def test_dask_gives_the_same_files_bit_for_bit(scans, tmp_path):
    pytest.importorskip("distributed")
    from distributed import Client

    from o3dheat.pipelines.cluster import local_cluster

    _bad(scans)
    big = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 100)  # 19802 vertices: more than one row part
    V = big.vertex.positions.numpy().astype(np.float64)  # of o3dheat.parallel, on 2 threads in-process
    big.vertex.positions = o3d.core.Tensor(V * [1.3, 1.0, 0.8] + 0.05 * np.sin(3 * V[:, [1, 2, 0]]))
    write_mesh(scans / "big.ply", big)
    seq = run(STEPS, scans / "*.ply", tmp_path / "seq", scheduler="sequential", progress=False)
    with local_cluster(2) as cluster, Client(cluster) as client:  # real worker processes
        dist = run(STEPS, scans / "*.ply", tmp_path / "dask", scheduler=client, progress=False)
        assert client.status == "running"  # a given client is left open
    assert dist["status"].tolist() == seq["status"].tolist() and (dist["status"] == "failed").sum() == 2
    assert dist["error"].tolist() == seq["error"].tolist()
    _same_outputs(tmp_path / "seq", tmp_path / "dask")
    for p in (tmp_path / "seq").glob("*.ply"):
        assert p.read_bytes() == (tmp_path / "dask" / p.name).read_bytes()


def test_a_file_too_big_for_a_dask_worker_fails_at_once_naming_the_limit(scans, tmp_path):
    """Not four workers restarted by their nannies one after the other, then a KilledWorker."""
    pytest.importorskip("distributed")
    from distributed import Client, LocalCluster

    big = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 300)  # 179,402 vertices: ~1.2 GiB for k = 300
    write_mesh(scans / "big.ply", big)
    steps = [("hks", {"k": 300})]
    with LocalCluster(n_workers=1, threads_per_worker=1, memory_limit="1GB", dashboard_address=None) as cluster, \
            Client(cluster) as client:
        pids = client.run(os.getpid)
        table = run(steps, [scans / "big.ply", scans / "m0.ply"], tmp_path / "out", scheduler=client, progress=False)
        assert client.run(os.getpid) == pids  # no worker was restarted
    assert table["status"].tolist() == ["failed", "done"]
    assert "needs about" in table["error"][0] and "under the Dask worker's memory limit" in table["error"][0]
    assert not (tmp_path / "out" / "big.ply").exists()


# --------------------------------------------------------------------------------- the command
def test_cli_batch_with_filters_and_chain_file(scans, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["batch", str(scans / "m0.ply"), str(scans / "m[12].ply"), "--out", str(out),
                 "--scheduler", "sequential", "--no-progress"] + FLAGS) == 0
    assert "3 files: 3 done" in capsys.readouterr().out
    chain = tmp_path / "chain.toml"
    Chain(STEPS).save(chain)
    assert main(["batch", str(scans / "*.ply"), "--out", str(tmp_path / "npz"), "--chain", str(chain),
                 "--format", "npz", "--scheduler", "sequential"]) == 0
    for i in range(3):
        a, b = read_mesh(out / f"m{i}.ply"), read_mesh(tmp_path / "npz" / f"m{i}.npz")
        assert np.array_equal(a.vertex["height_smooth"].numpy(), b.vertex["height_smooth"].numpy())
    capsys.readouterr()
    assert main(["batch", str(scans / "*.ply"), "--out", str(out), "--chain", str(chain)]) == 0  # resumed
    assert "3 skipped" in capsys.readouterr().out
    for args, message in (([str(tmp_path / "no" / "*.ply")] + FLAGS, "no file matches"),
                          ([str(scans / "*.ply")], "no filter given"),
                          ([str(scans / "*.ply"), "-f", "hks:kk=1"], "no parameter 'kk'"),
                          ([str(scans / "*.ply"), "-f", "scalar"], "another chain")):
        assert main(["batch", *args, "--out", str(out), "--scheduler", "sequential"]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err and err.count("\n") == 1


def test_cli_batch_on_its_own_local_cluster(scans, tmp_path, capsys, monkeypatch):
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    assert main(["batch", str(scans / "*.ply"), "--out", str(out)] + FLAGS) == 0  # no --scheduler: Dask
    assert "3 files: 3 done" in capsys.readouterr().out
    assert main(["batch", str(scans / "*.ply"), "--out", str(tmp_path / "seq"), "--scheduler", "sequential"]
                + FLAGS) == 0
    _same_outputs(out, tmp_path / "seq")

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(o3dheat.pipelines.batch, "run", interrupted)
    assert main(["batch", str(scans / "*.ply"), "--out", str(out)] + FLAGS) == 130
    assert "run the same command again to resume" in capsys.readouterr().err


def test_progress_bar_on_request(scans, tmp_path, capsys):
    run(STEPS[:1], scans / "*.ply", tmp_path / "o", scheduler="sequential", progress=True)
    assert "3/3" in capsys.readouterr().err


def test_warnings_of_a_file_name_the_file(tmp_path, caplog):
    from o3dheat.io import write_mesh

    V, F = torus()
    V = np.concatenate([V, [[9.0, 9.0, 9.0]]])  # an unreferenced vertex: a warning while solving
    m = o3d.t.geometry.TriangleMesh()
    m.vertex.positions = o3d.core.Tensor(V)
    m.triangle.indices = o3d.core.Tensor(F)
    src = tmp_path / "lonely.ply"
    write_mesh(src, m)
    with caplog.at_level("WARNING", logger="o3dheat"):
        t = run([("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": 10})], src,
                tmp_path / "out", scheduler="sequential", progress=False)
    assert t["status"].tolist() == ["done"]
    msgs = [r.getMessage() for r in caplog.records if "unreferenced" in r.getMessage()]
    assert msgs and all("lonely.ply: " in msg for msg in msgs)
    import logging

    assert not logging.getLogger("o3dheat").filters  # removed after the file


# --------------------------------------------------------------------------------- links, --out inside
class _TooLong(Exception):
    pass


class _Deadline:
    """``with _Deadline(s):`` fails the test (_TooLong) when the block runs longer than s seconds."""

    def __init__(self, seconds):
        self.seconds = seconds

    def __enter__(self):
        import signal

        def fire(*_):  # not a TimeoutError: that is an OSError, which glob swallows
            raise _TooLong(f"still running after {self.seconds} s")

        self.old = signal.signal(signal.SIGALRM, fire)
        signal.alarm(self.seconds)

    def __exit__(self, *exc):
        import signal

        signal.alarm(0)
        signal.signal(signal.SIGALRM, self.old)


def _loops(scans):
    """Two link loops in the scans folder (``ln -s . self``, and a sub-folder's link to its parent)."""
    os.symlink(".", scans / "self")
    (scans / "deep").mkdir()
    write_mesh(scans / "deep" / "d.ply", _mesh(0))
    os.symlink("..", scans / "deep" / "up")
    os.symlink("deep", scans / "alias")  # a second name of a folder: its files once, by their own names


def test_link_loops_end_and_each_file_is_run_once(scans, tmp_path, capsys):
    _loops(scans)
    with _Deadline(20):
        got = expand(str(scans / "**" / "*.ply"))
    assert [os.path.relpath(p, scans) for p in got] == ["deep/d.ply", "m0.ply", "m1.ply", "m2.ply"]
    with _Deadline(60):
        t = run(Chain(STEPS[:1]), str(scans / "**" / "*.ply"), tmp_path / "out", scheduler="sequential",
                                 progress=False)
        assert t["status"].tolist() == ["done"] * 4
        assert main(["batch", str(scans / "**" / "*.ply"), "--out", str(tmp_path / "cli"), "--scheduler",
                     "sequential", "-f", "scalar:kind=height"]) == 0
    assert "4 files: 4 done" in capsys.readouterr().out


def test_an_output_folder_inside_the_inputs_tree_resumes(scans):
    out = scans / "results"
    pattern = str(scans / "**" / "*.ply")
    first = run(STEPS[:1], pattern, out, scheduler="sequential", progress=False)
    assert first["status"].tolist() == ["done"] * 3 and sorted(p.name for p in out.glob("*.ply")) == \
        ["m0.ply", "m1.ply", "m2.ply"]
    again = run(STEPS[:1], pattern, out, scheduler="sequential", progress=False)  # the outputs are no inputs
    assert again["status"].tolist() == ["skipped"] * 3
    assert again["input"].tolist() == first["input"].tolist()
    assert [p.name for p in expand(pattern, exclude=out)] == ["m0.ply", "m1.ply", "m2.ply"]
    with pytest.raises(o3dheat.MeshError, match="output folder .* is not searched"):
        expand(str(scans / "*" / "*.ply"), exclude=out)


def test_flags_that_are_not_bools_are_refused(scans, tmp_path):
    out = tmp_path / "out"
    for kw in (dict(overwrite="no"), dict(binary=0), dict(progress="yes")):
        with pytest.raises(o3dheat.MeshError, match=f"{next(iter(kw))} must be True or False"):
            run(STEPS, scans / "*.ply", out, scheduler="sequential", **kw)
    assert not out.exists()


DESCRIPTOR_FLAGS = ["-f", "hks:k=20,scales=4", "-f", "wks:k=20,energies=6", "-f", "si_hks:k=20,frequencies=5"]


def test_descriptors_over_a_dataset_one_spectrum_per_mesh_npz_resumed_after_kill(scans, tmp_path, monkeypatch):
    """Issue 31: HKS, WKS and SI-HKS of every mesh of a folder, one .npz each (arrays named by
    descriptor), one eigensolve per mesh for all three; a batch killed with SIGKILL and run again
    gives the same files as one uninterrupted run."""
    import signal
    import subprocess
    import sys
    import time

    import o3dheat.spectral.spectrum as spectrum

    solves = []
    real = spectrum.solve_eigenproblem
    monkeypatch.setattr(spectrum, "solve_eigenproblem", lambda *a, **k: (solves.append(1), real(*a, **k))[1])
    steps = [("hks", {"k": 20, "scales": 4}), ("wks", {"k": 20, "energies": 6}), ("si_hks", {"k": 20, "frequencies": 5})]
    whole = tmp_path / "whole"
    t = run(Chain(steps), str(scans / "*.ply"), whole, scheduler="sequential", suffix=".npz", progress=False)
    assert t["status"].tolist() == ["done"] * 3 and len(solves) == 3  # one spectrum per mesh
    with np.load(whole / "m1.npz") as z:
        assert {"vertex_hks", "vertex_wks", "vertex_si_hks"} <= set(z.files)
        assert z["vertex_wks"].shape[1] == 6 and z["vertex_si_hks"].shape[1] == 5
        K = o3dheat.HeatKernel(o3dheat.eigensolve(read_mesh(scans / "m1.ply"), k=20))
        np.testing.assert_allclose(z["vertex_wks"], K.wks(6), rtol=1e-10, atol=0)
    for i in range(3, 8):  # more files: the kill lands in the middle
        write_mesh(scans / f"m{i}.ply", _mesh(i % 3))
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "o3dheat.cli", "batch", str(scans / "*.ply"), "--out", str(out), "--format", "npz",
           "--scheduler", "sequential", *DESCRIPTOR_FLAGS]
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    deadline = time.time() + 120
    while time.time() < deadline and len(list(out.glob("*.npz"))) < 2:
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait()
    done_before = len(list(out.glob("*.npz")))
    assert 2 <= done_before < 8
    for path in out.glob("*.npz"):  # atomic writes: every output is whole (a kill inside a write can
        with np.load(path) as z:    # leave its hidden temporary file, never a half output)
            assert all(z[k].size for k in z.files), path
    assert subprocess.run(cmd, capture_output=True).returncode == 0
    full = tmp_path / "full"
    assert subprocess.run(cmd[:6] + [str(full)] + cmd[7:], capture_output=True).returncode == 0
    names = sorted(p.name for p in full.glob("*.npz"))
    assert len(names) == 8 and names == sorted(p.name for p in out.glob("*.npz"))
    for name in names:
        with np.load(out / name) as a, np.load(full / name) as b:
            assert a.files == b.files and all(np.array_equal(a[k], b[k]) for k in a.files), name
