"""o3dheat.geometry.sampling: the resamplings (decimate, remesh, anisotropic, jitter, subdivide)."""

import numpy as np
import open3d as o3d
import pytest
from conftest import icosphere
from hypothesis import given, settings
from hypothesis import strategies as st

import o3dheat
from o3dheat.geometry.sampling import decimate
from o3dheat.topology import Surface


def test_decimate_gives_an_irregular_2_manifold():
    from o3dheat.io import default_mesh

    bunny, _ = default_mesh()
    for r in (0.5, 0.8, 0.95):
        V, F = decimate(bunny, reduction=r).arrays
        S = Surface((V, F))  # raises if not a 2-manifold
        assert S.used.all() and abs(len(F) - (1 - r) * len(bunny.triangle.indices)) < 0.02 * len(F) + 10
    V, F = decimate(bunny, target_faces=4000).arrays
    assert len(F) <= 4000
    edge = np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1)
    assert edge.max() / np.median(edge) > 2  # non-uniform
    with pytest.raises(o3dheat.MeshError):
        decimate(bunny, reduction=1.0)


def test_decimation_map():
    from o3dheat.io import default_mesh

    bunny, _ = default_mesh()
    V, _ = o3dheat.as_arrays(bunny)
    r = decimate(bunny, reduction=0.9)
    m = r.vertex_map
    assert m.shape == (len(V),) and m.max() < len(r.V)
    kept = m >= 0
    assert kept.mean() > 0.99  # only vertices of removed non-manifold faces may be lost
    assert np.array_equal(np.unique(m[kept]), np.arange(len(r.V)))  # every new vertex has a source
    edge = np.linalg.norm(r.V[r.F[:, 0]] - r.V[r.F[:, 1]], axis=1)
    assert np.linalg.norm(V[kept] - r.V[m[kept]], axis=1).max() < 3 * edge.max()  # collapsed nearby
    assert np.array_equal(decimate(bunny, reduction=0.9).V, r.V)  # deterministic


def test_remesh_anisotropic_jitter_subdivide():
    from o3dheat.geometry.sampling import anisotropic, jitter, remesh, resample, subdivide

    V, F = icosphere(3)
    r = remesh((V, F), 0.08)
    e = np.linalg.norm(r.V[r.F[:, 0]] - r.V[r.F[:, 1]], axis=1)
    assert abs(np.median(e) / 0.08 - 1) < 0.3 and r.vertex_map is None
    assert Surface(r.arrays).euler_characteristic == 2
    with pytest.raises(o3dheat.MeshError, match="target_edge_length"):
        remesh((V, F), 10.0)
    h = np.mean(np.linalg.norm(V[F[:, 0]] - V[F[:, 1]], axis=1))
    r2 = remesh((V, F), edge_factor=0.8)
    e2 = np.linalg.norm(r2.V[r2.F[:, 0]] - r2.V[r2.F[:, 1]], axis=1)
    assert abs(np.median(e2) / (0.8 * h) - 1) < 0.3 and r2.params["edge_factor"] == 0.8
    with pytest.raises(o3dheat.MeshError, match="not both"):
        remesh((V, F), 0.1, edge_factor=1.0)
    np.testing.assert_array_equal(remesh((V, F)).V, remesh((V, F), edge_factor=1.0).V)  # the default
    with pytest.raises(o3dheat.MeshError):
        remesh((V, F), -1)
    a = anisotropic((V, F), coarse=6.0, fine=0.5)
    left = a.V[:, 0] < np.median(V[:, 0])
    assert np.sum(~left) > 8 * np.sum(left) and Surface(a.arrays).euler_characteristic == 2
    j1, j2 = jitter((V, F), 0.3, seed=5), jitter((V, F), 0.3, seed=5)
    assert np.array_equal(j1.V, j2.V) and not np.array_equal(j1.V, jitter((V, F), 0.3, seed=6).V)
    assert np.array_equal(j1.F, F) and np.abs(np.linalg.norm(j1.V, axis=1) - 1).max() < 0.02
    s = subdivide((V, F), 1)
    assert len(s.F) == 4 * len(F) and np.array_equal(s.V[: len(V)], V)
    assert resample((V, F), "subdivide", iterations=1).F.shape == s.F.shape
    with pytest.raises(o3dheat.MeshError, match="unknown resampling"):
        resample((V, F), "shuffle")
    with pytest.raises(o3dheat.MeshError, match="resampling 'jitter'"):
        resample((V, F), "jitter", bogus=1)
    assert isinstance(s.mesh, o3d.t.geometry.TriangleMesh)


# ------------------------------------------------------------------------ jitter never folds a face
def _jitter_report(V0, F, r):
    """Independent check of a jittered mesh: (flipped faces, least area ratio, least projected-area
    ratio, largest and mean move in mean edge lengths), over the faces of positive original area."""
    n0 = np.cross(V0[F[:, 1]] - V0[F[:, 0]], V0[F[:, 2]] - V0[F[:, 0]])
    n1 = np.cross(r.V[F[:, 1]] - r.V[F[:, 0]], r.V[F[:, 2]] - r.V[F[:, 0]])
    a0, a1 = np.linalg.norm(n0, axis=1), np.linalg.norm(n1, axis=1)
    h = np.mean(np.linalg.norm(V0[F[:, 0]] - V0[F[:, 1]], axis=1))
    ok = a0 > 1e-12 * h * h
    dot = np.einsum("ij,ij->i", n1, n0)[ok]
    moved = np.linalg.norm(r.V - V0, axis=1) / h
    flips = int(np.sum(dot <= 0))
    return flips, (a1[ok] / a0[ok]).min(), (dot / a0[ok] ** 2).min(), moved.max(), moved.mean()


@pytest.fixture(scope="module")
def jitter_meshes():
    from o3dheat.io import sample_mesh

    return {"bunny": decimate(sample_mesh("bunny"), target_faces=20000).arrays,
            "airplane": o3dheat.as_arrays(sample_mesh("airplane")),
            "torus": o3dheat.as_arrays(sample_mesh("torus"))}


@pytest.mark.parametrize("name", ["bunny", "airplane", "torus"])
def test_jitter_never_folds_the_sample_meshes(jitter_meshes, name):
    import json

    from o3dheat.geometry.sampling import jitter

    V, F = jitter_meshes[name]
    for amount in (0.1, 0.3, 1.0, 3.0):
        for seed in (0, 1):
            r = jitter((V, F), amount, seed)
            flips, area, projected, moved_max, moved_mean = _jitter_report(V, F, r)
            p = r.params
            assert flips == 0, (name, amount, seed)
            assert area >= 0.1 * (1 - 1e-9) and projected >= 0.1 * (1 - 1e-9), (name, amount, seed)
            assert p["moved_max"] == pytest.approx(moved_max, rel=1e-12)
            assert p["moved_mean"] == pytest.approx(moved_mean, rel=1e-12)
            assert p["moved_max"] > 0.05 * amount  # the limiter shrinks, it does not stop everything
            assert p["amount"] == amount and p["seed"] == seed and p["degenerate"] == 0
            assert 0 <= p["frozen"] <= p["limited"] <= len(V)
            assert json.loads(json.dumps(p)) == p and all(type(v) in (int, float) for v in p.values())
            assert np.array_equal(r.F, F) and np.array_equal(r.vertex_map, np.arange(len(V)))
    assert np.array_equal(jitter((V, F), 3.0, 1).V, r.V)  # deterministic, bit for bit


def test_jitter_limiter_is_exercised(jitter_meshes, monkeypatch):
    import o3dheat.geometry.sampling as sampling

    V, F = jitter_meshes["torus"]
    free = sampling.jitter((V, F), 0.1, 0)  # a regular mesh and a small amount: nothing to limit
    assert free.params["limited"] == 0  # mean length of a 2D Gaussian move: amount * sqrt(pi / 2)
    assert free.params["moved_mean"] == pytest.approx(0.1 * np.sqrt(np.pi / 2), rel=0.03)
    big = sampling.jitter((V, F), 3.0, 0)  # unlimited, the mean move would be 3.76 edge lengths
    assert big.params["limited"] > 0.9 * len(V) and big.params["moved_mean"] < 1.0
    mid = sampling.jitter((V, F), 0.3, 0)
    assert 0 < mid.params["limited"] < len(V)
    # without the safeguard the same proposals fold faces: the checks above would catch it
    monkeypatch.setattr(sampling, "_limit_moves", lambda V, F, d, s: s)
    raw = sampling.jitter((V, F), 0.3, 0)
    assert _jitter_report(V, F, raw)[0] > 100
    same = np.all(mid.V == raw.V, axis=1)  # the vertices not limited move exactly as proposed
    assert same.sum() == len(V) - mid.params["limited"]


def test_jitter_degenerate_and_unreferenced_input():
    from conftest import grid

    from o3dheat.geometry.sampling import jitter

    V, F = grid(1.0, 1.0, 8, 8)
    V = np.concatenate([V, [[5.0, 5.0, 5.0]]])  # an unreferenced vertex
    F = np.concatenate([F, [[0, 1, 2]]])  # a zero-area face (three grid points on a line)
    with np.errstate(all="raise"):
        r = jitter((V, F), 2.0, 3)
    assert r.params["degenerate"] == 1 and r.params["frozen"] >= 3
    assert np.array_equal(r.V[[0, 1, 2, len(V) - 1]], V[[0, 1, 2, len(V) - 1]])
    flips, area, _, moved_max, _ = _jitter_report(V, F, r)
    assert flips == 0 and area >= 0.1 * (1 - 1e-9) and moved_max > 0
    z = jitter((V, F), 0.0, 0)
    assert np.array_equal(z.V, V) and z.params["moved_max"] == 0.0 and z.params["limited"] == 0
    with pytest.raises(o3dheat.MeshError):
        jitter((V, F), -0.1)
    with pytest.raises(o3dheat.MeshError, match="overflow"):
        jitter((V, F), 1e308)


def _random_disk(seed, n, lift):
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    r, t = np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * np.pi, n)
    P = np.stack([r * np.cos(t), r * np.sin(t)], 1)
    F = Delaunay(P).simplices.astype(np.int64)
    if lift == "flat":
        z = np.zeros(n)
    elif lift == "smooth":
        z = rng.uniform(-1, 1) * np.sin(3 * P[:, 0] + rng.uniform(0, 6)) * np.cos(2 * P[:, 1])
    else:
        z = 0.3 * rng.standard_normal(n)  # rough: vertex normals far from the face normals
    return np.column_stack([P, z]), F


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16), n=st.integers(4, 60), lift=st.sampled_from(["flat", "smooth", "rough"]),
       amount=st.floats(0, 10), jseed=st.integers(0, 2**16))
def test_jitter_random_disks_never_fold(seed, n, lift, amount, jseed):
    from o3dheat.geometry.sampling import jitter

    V, F = _random_disk(seed, n, lift)
    r = jitter((V, F), amount, jseed)
    flips, area, projected, moved_max, _ = _jitter_report(V, F, r)
    assert flips == 0 and area >= 0.1 * (1 - 1e-9) and projected >= 0.1 * (1 - 1e-9)
    assert r.params["moved_max"] == pytest.approx(moved_max, rel=1e-12, abs=1e-15)
    assert np.array_equal(jitter((V, F), amount, jseed).V, r.V)


def test_a_remeshing_too_fine_is_refused_at_once_with_its_estimate():
    import subprocess
    import sys

    import open3d as o3d

    from o3dheat.geometry import sampling
    from o3dheat.geometry.sampling import anisotropic, remesh

    # in a process of its own: pymeshlab, once started, cannot be interrupted (minutes of work)
    script = ("import open3d as o3d, o3dheat\n"
              "from o3dheat.geometry.sampling import remesh\n"
              "try:\n"
              "    remesh(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20), target_edge_length=1e-3)\n"
              "except o3dheat.MeshError as e:\n"
              "    print(e)\n")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    # 4 pi / (sqrt(3)/4 1e-6) faces
    assert "would make about 2.89e+07 faces" in run.stdout and "max_faces=1000000" in run.stdout, run.stderr
    sphere = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    with pytest.raises(o3dheat.MeshError, match="anisotropic .* more than max_faces"):
        anisotropic(sphere, fine=0.001)
    assert sampling.REMESH_MAX_FACES == 1_000_000
    with pytest.raises(o3dheat.MeshError, match="max_faces"):
        remesh(sphere, 0.1, max_faces=100)  # about 2,900 faces
    assert len(remesh(sphere, 0.1, max_faces=5000).F) > 2000  # the bound raised
    with pytest.raises(o3dheat.MeshError, match="max_faces must be"):
        remesh(sphere, 0.1, max_faces=-1)


def test_decimating_to_fewer_than_4_faces_is_a_clear_error():
    import open3d as o3d

    sphere = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)  # 1520 faces
    with pytest.raises(o3dheat.MeshError, match="would leave 0, fewer than 4: use a reduction of at most 0.9974"):
        decimate(sphere, reduction=0.9999)
    assert len(decimate(sphere, target_faces=4).F) == 4
    for bad in ({"target_faces": 3}, {"target_faces": -5}, {"target_faces": 2.5}, {"reduction": "0.5"},
                {"reduction": True}, {"reduction": -0.1}):
        with pytest.raises(o3dheat.MeshError, match="target_faces must be|reduction must be"):
            decimate(sphere, **bad)




def test_decimations_in_threads_at_once_are_those_made_one_by_one():
    """fast-simplification keeps its mesh in module-wide state between calls: two threads decimating
    at once read each other's mesh (before the lock: an IndexError in its replay, or a wrong mesh).
    Decimations made from four threads at once equal those made one after the other."""
    from concurrent.futures import ThreadPoolExecutor

    meshes = [o3d.t.geometry.TriangleMesh.create_sphere(1.0, 150),
              o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.3, 200, 100)]
    one_by_one = [decimate(m, 0.6) for m in meshes] + [decimate(m, 0.6, vertex_map=False) for m in meshes]
    jobs = [(i % 2, i // 2 % 2 == 1) for i in range(12)]
    with ThreadPoolExecutor(4) as ex:
        at_once = list(ex.map(lambda job: decimate(meshes[job[0]], 0.6, vertex_map=not job[1]), jobs))
    for (i, plain), r in zip(jobs, at_once, strict=True):
        ref = one_by_one[i + 2 * plain]
        assert np.array_equal(r.F, ref.F) and np.array_equal(r.V, ref.V)
        assert (r.vertex_map is None) == plain and (plain or np.array_equal(r.vertex_map, ref.vertex_map))


def test_decimate_without_the_map_has_the_same_faces():
    m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.3, 60, 30)
    a, b = decimate(m, 0.5), decimate(m, 0.5, vertex_map=False)
    assert b.vertex_map is None and a.vertex_map is not None
    assert np.array_equal(np.sort(np.sort(a.F, axis=1), axis=0), np.sort(np.sort(b.F, axis=1), axis=0))
    assert np.abs(a.V - b.V).max() < 1e-2 * np.ptp(a.V)
    with pytest.raises(o3dheat.MeshError, match="vertex_map"):
        decimate(m, 0.5, vertex_map="no")
    with pytest.raises(o3dheat.MeshError, match="vertex_map"):  # checked on the paths that remove nothing too
        decimate(m, target_faces=10**6, vertex_map="no")
    assert decimate(m, 0.0, vertex_map=False).vertex_map is None  # no map asked for: none, even of nothing removed
    assert decimate(m, target_faces=10**6, vertex_map=False).vertex_map is None
    assert decimate(m, 0.0).vertex_map.tolist() == list(range(len(m.vertex.positions)))


def test_decimation_that_would_not_fit_in_memory_is_refused_before_it_starts(monkeypatch):
    """Issue 35: fast-simplification takes about 400 bytes per face (680 with the vertex map) and
    aborts the process when it runs out; the estimate is checked first."""
    import fast_simplification

    import o3dheat.memory as mm
    from o3dheat.errors import OutOfMemory
    from o3dheat.geometry.sampling import decimate, decimate_bytes

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    need = decimate_bytes(len(m.triangle.indices), vertex_map=False)
    assert decimate_bytes(10**6, vertex_map=True) > decimate_bytes(10**6, vertex_map=False) > 400 * 10**6
    monkeypatch.setattr(mm, "memory_limits", lambda: {"system": need - 1})
    monkeypatch.setattr(fast_simplification, "simplify", lambda *a, **k: pytest.fail("fast-simplification started"))
    with pytest.raises(OutOfMemory, match=r"decimating 6,240 faces needs about 0\.\d\d GiB"):
        decimate(m, 0.5, vertex_map=False)


def test_a_large_decimation_runs_in_a_child_with_the_same_result_and_leaves_no_memory(monkeypatch):
    """Issue 35: fast-simplification's C++ vectors keep their capacity after a call (about 300
    bytes per input face until exit: 6 GB after a 20M-face scan). Above CHILD_FACES the call runs
    in a forked child: the same vertices, faces and map, bit for bit, and a fresh process's resident
    size does not keep the decimation's memory."""
    import os
    import subprocess
    import sys

    import o3dheat.geometry._simplify as simp

    if not hasattr(os, "fork"):
        pytest.skip("no fork here")
    m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.3, 400, 200)  # 160k faces
    inside = [decimate(m, 0.9), decimate(m, 0.9, vertex_map=False)]
    monkeypatch.setattr(simp, "CHILD_FACES", 1000)
    child = [decimate(m, 0.9), decimate(m, 0.9, vertex_map=False)]
    for a, b in zip(inside, child, strict=True):
        assert np.array_equal(a.V, b.V) and np.array_equal(a.F, b.F)
        assert (a.vertex_map is None and b.vertex_map is None) or np.array_equal(a.vertex_map, b.vertex_map)
    script = """
import os, numpy as np, open3d as o3d
import o3dheat.geometry._simplify as simp
from o3dheat.geometry.sampling import decimate
simp.CHILD_FACES = 1000
m = o3d.t.geometry.TriangleMesh.create_torus(1.0, 0.3, 800, 400)
V, F = m.vertex.positions.numpy(), m.triangle.indices.numpy()
decimate(o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10), 0.5)  # the modules warmed up
def resident():
    return int(open("/proc/self/statm").read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
before = resident()
decimate((V, F), 0.9)
print((resident() - before) / len(F))
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert float(out.stdout.split()[-1]) < 60, out.stdout  # in the process itself: about 300 bytes per face


def test_a_decimation_child_that_dies_is_said(monkeypatch):
    """The child killed (the system's out-of-memory killer) or failing: a clear error, no hang."""
    import os
    import signal

    import o3dheat.geometry._simplify as simp
    from o3dheat.errors import OutOfMemory, SolverError

    if not hasattr(os, "fork"):
        pytest.skip("no fork here")
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    monkeypatch.setattr(simp, "CHILD_FACES", 1000)
    monkeypatch.setattr(simp, "_simplify", lambda *a: os.kill(os.getpid(), signal.SIGKILL))
    with pytest.raises(OutOfMemory, match="decimation of 6,240 faces was killed"):
        decimate(m, 0.5)

    def broken(*a):
        raise ValueError("no such thing")

    monkeypatch.setattr(simp, "_simplify", broken)
    with pytest.raises(SolverError, match="fast-simplification failed on 6,240 faces: ValueError: no such thing"):
        decimate(m, 0.5)
