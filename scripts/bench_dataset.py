#!/usr/bin/env python
"""Benchmark: a dataset's spectral precompute (k = 128 eigenpairs, HKS, WKS per mesh), o3dheat
against DiffusionNet's own precompute, sequentially, and o3dheat's batch on a local Dask cluster.

The dataset (made once, untimed, seeded; PLY files written by ``o3dheat.io.write_mesh``): 57
meshes of 5k-30k vertices: pymeshlab's bunny as it is, at 12 resolutions
(``bench_spectrum.bunny(n)``: Loop-subdivided then quadric-decimated), decimated, jittered,
remeshed and anisotropically remeshed; pymeshlab's airplane, bone and cow subdivided (midpoint and
Loop), Loop-subdivided twice then decimated, jittered, remeshed, anisotropically remeshed
(:func:`o3dheat.geometry.sampling.resample`). Each is checked to be a clean closed connected
2-manifold of 5k-30k vertices (no zero-area face, which o3dheat would drop and robust-laplacian
keep), else left out with a message. ``--meshes N`` takes the first N (the sources interleaved,
so a short run has them all).

What is timed, each in a fresh subprocess, over the whole dataset, one mesh after the other:

* ``o3dheat``: per mesh, ``o3dheat.io.read_mesh``, ``o3dheat.eigensolve(mesh, k=128, cache=False)``
  (consistent FEM mass, block Lanczos on CHOLMOD), ``K = HeatKernel(spectrum)``,
  ``K.hks(K.scales(16, grid="log"))`` and ``K.wks(100)``, written with ``np.savez`` (eigenvalues,
  HKS, WKS). o3dheat's threads and BLAS as they come (2 cores: 2 threads).
* ``diffusionnet``: per mesh, the same reader, then what DiffusionNet's
  ``diffusion_net/geometry.py::compute_operators`` does for the eigenbasis, with the Laplacian
  and mass of robust-laplacian (the line commented out there; its current default for meshes is
  potpourri3d's cotan Laplacian and vertex areas): ``L, M = robust_laplacian.mesh_laplacian(V, F)``,
  ``massvec = M.diagonal()``, ``L_eigsh = (L + eps I).tocsc()``, ``Mmat = diags(massvec)``,
  ``eigsh(L_eigsh, k=128, M=Mmat, sigma=eps)`` with ``eps = 1e-8`` in its retry loop (eps
  raised on failure), eigenvalues clipped at 0; then, in numpy from these eigenpairs, the HKS at
  16 times and the WKS at 100 energies by the same formulas as o3dheat's (density HKS
  ``Σ e^{-λ t/2} x(i)²`` on the same log grid, ``1/λ_k .. 2 ln 100 / λ_2``; Aubry's WKS with
  σ = 6 x the spacing of the log-energies), written the same way. Not done: DiffusionNet's tangent
  frames and gradient matrices (o3dheat has no counterpart). SciPy's SuperLU and ARPACK, BLAS
  on one thread (below).
* ``batch seq``: ``o3dheat.pipelines.batch.run(chain, pattern, out, scheduler="sequential",
  suffix=".npz")`` with the chain ``hks`` (k=128, 16 scales, log grid) + ``wks`` (k=128, 100
  energies): the files one after the other in the subprocess (o3dheat's threads, BLAS on one
  thread, as ``batch.run`` sets), reading and writing the ``.npz`` (positions, indices,
  ``vertex_hks``, ``vertex_wks``) included. The eigensolver calls are counted: one per mesh.
* ``batch dask``: the same on ``o3dheat.pipelines.cluster.local_cluster(2)`` (what
  ``scheduler=None`` starts on 2 cores: 2 single-threaded worker processes, one file per task).
* ``batch seq 1t``: ``batch seq`` with ``O3DHEAT_NUM_THREADS=1`` (one thread, as each Dask
  worker runs): the reference for what two worker processes gain over one.
* on request (``--cases``): ``o3dheat-1t`` (``o3dheat`` on one thread) and ``batch-dask-nopin``
  (``local_cluster(2, pin=False)``: the kernel places the workers, better on a shared machine).

The DiffusionNet side runs with BLAS on one thread (``--peer-blas 1``, threadpoolctl): on a busy
2-core machine OpenBLAS's 2 spinning threads made its ``eigsh`` 2-3x slower and erratic (8 s with
1 thread, 15-27 s with 2, on the 28k-vertex bunny), so the default is its faster setting.

Outside the timing, equally for every case: imports, and one run of the case's own per-mesh work
on a 2,000-vertex sphere (loads CHOLMOD, numba's cached loops, SciPy's lazy modules; for Dask: the
cluster's start and a one-file batch on its workers). Those are shown apart ("start-up"), and a
second ratio counts them. The cases run ``--repeat`` times interleaved (o3dheat, DiffusionNet,
batch seq, batch dask, batch seq 1t, o3dheat, ...): each repetition's ratios are shown (same
moment, same load) and the ratio of the fastest runs. The load average is read before each run,
and CPU seconds are counted (the subprocess's, or the Dask workers' and the client's): CPU / wall
says how many cores a run actually got, and the ratio of CPU seconds is less sensitive to other
jobs than the wall-clock one.

Accuracy (untimed, from the files of the first repetition): the relative difference of
λ_2..λ_128 between the two sides, which solve different discretisations (o3dheat: the linear FEM
cotan stiffness with the consistent mass; robust-laplacian: the cotan Laplacian of the intrinsic
Delaunay triangulation with a lumped mass; plus DiffusionNet's 1e-8 shift), and, to separate
discretisation from solver, o3dheat's solver (``eigensolve_operators``) on DiffusionNet's own
matrices against its ``eigsh``; the batch outputs against the direct o3dheat run.

    .venv/bin/python scripts/bench_dataset.py                       # 57 meshes, 2 repetitions (15-25 min)
    .venv/bin/python scripts/bench_dataset.py --meshes 8 --repeat 1 # quick
    .venv/bin/python scripts/bench_dataset.py --data /tmp/ds         # keep the dataset for the next run
    .venv/bin/python scripts/bench_dataset.py --profile              # + cProfile of o3dheat on one mesh
    .venv/bin/python scripts/bench_dataset.py --cases batch-seq,batch-dask,batch-dask-nopin,batch-seq-1t

Prints Markdown tables; ratios are DiffusionNet seconds / o3dheat seconds (higher = o3dheat
faster) and sequential batch seconds / Dask batch seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

K_EIG = 128
SCALES = 16
ENERGIES = 100
EPS = 1e-8  # DiffusionNet's eps
CASES = ["o3dheat", "diffusionnet", "batch-seq", "batch-dask", "batch-seq-1t"]
EXTRA = ["o3dheat-1t", "batch-dask-nopin"]  # on request (--cases)
#: the ratios shown (numerator / denominator: higher = the denominator faster), and the targets
PAIRS = [("diffusionnet", "o3dheat"), ("diffusionnet", "batch-seq"), ("diffusionnet", "o3dheat-1t"),
         ("diffusionnet", "batch-seq-1t"),
         ("batch-seq", "batch-dask"), ("batch-seq", "batch-dask-nopin"), ("batch-seq-1t", "batch-dask"),
         ("batch-seq-1t", "batch-dask-nopin")]
TARGETS = {("diffusionnet", "o3dheat"): 3.0, ("diffusionnet", "batch-seq"): 3.0, ("batch-seq", "batch-dask"): 1.7}
MIN_V, MAX_V = 5000, 30000


# ------------------------------------------------------------------------------------ the dataset
LOOP2 = ("subdivide", {"iterations": 2, "method": "loop"})


def _recipes():
    """(name, source, steps) of every mesh, the four sources interleaved; a step is
    ("bunny", n) (bench_spectrum.bunny), or (kind, params) of o3dheat.geometry.sampling.resample."""
    bunny = [("bunny", "bunny", [])]
    bunny += [(f"bunny-res{n // 1000}k", "bunny", [("bunny", n)]) for n in range(5000, 28000, 2000)]
    bunny += [(f"bunny-dec{tf // 1000}kf", "bunny", [("decimate", {"target_faces": tf})])
              for tf in (14000, 22000, 34000, 46000)]
    bunny += [(f"bunny-jit{s}", "bunny", [("jitter", {"amount": 0.3, "seed": s})]) for s in (0, 1)]
    bunny += [(f"bunny-dec30kf-jit{s}", "bunny", [("decimate", {"target_faces": 30000}),
                                                  ("jitter", {"amount": 0.3, "seed": s})]) for s in (2, 3)]
    bunny += [(f"bunny-remesh{ef}", "bunny", [("remesh", {"edge_factor": ef})]) for ef in (1.3, 1.7)]
    bunny += [("bunny-aniso", "bunny", [("anisotropic", {"coarse": 4.0, "fine": 1.0})])]
    plane = [("airplane", "airplane", [])]
    plane += [(f"airplane-jit{s}", "airplane", [("jitter", {"amount": 0.3, "seed": s})]) for s in (0, 1, 2)]
    plane += [(f"airplane-sub-{m}", "airplane", [("subdivide", {"method": m})]) for m in ("midpoint", "loop")]
    plane += [(f"airplane-loop2-dec{tf // 1000}kf", "airplane", [LOOP2, ("decimate", {"target_faces": tf})])
              for tf in (14000, 24000, 34000)]
    plane += [(f"airplane-sub-jit{s}", "airplane", [("subdivide", {}), ("jitter", {"amount": 0.3, "seed": s})])
              for s in (3, 4)]
    plane += [("airplane-remesh0.6", "airplane", [("remesh", {"edge_factor": 0.6})])]
    plane += [("airplane-aniso", "airplane", [("anisotropic", {"coarse": 1.5, "fine": 0.4})])]
    bone = [(f"bone-sub{it}", "bone", [("subdivide", {"iterations": it})]) for it in (1, 2)]
    bone += [("bone-sub-loop", "bone", [("subdivide", {"method": "loop"})])]
    bone += [(f"bone-loop2-dec{tf // 1000}kf", "bone", [LOOP2, ("decimate", {"target_faces": tf})])
             for tf in (14000, 24000, 34000, 44000)]
    bone += [(f"bone-sub-jit{s}", "bone", [("subdivide", {}), ("jitter", {"amount": 0.3, "seed": s})]) for s in (5, 6)]
    bone += [(f"bone-remesh{ef}", "bone", [("remesh", {"edge_factor": ef})]) for ef in (0.45, 0.3)]
    bone += [("bone-aniso", "bone", [("anisotropic", {"coarse": 0.6, "fine": 0.2})])]
    cow = [("cow-sub-loop", "cow", [("subdivide", {"method": "loop"})])]
    cow += [(f"cow-loop2-dec{tf // 1000}kf", "cow", [LOOP2, ("decimate", {"target_faces": tf})])
            for tf in (14000, 24000, 34000, 44000)]
    cow += [(f"cow-sub-jit{s}", "cow", [("subdivide", {}), ("jitter", {"amount": 0.3, "seed": s})]) for s in (7, 8)]
    cow += [("cow-loop-jit9", "cow", [("subdivide", {"method": "loop"}), ("jitter", {"amount": 0.3, "seed": 9})])]
    lists, out = [bunny, plane, bone, cow], []
    while any(lists):
        for lst in lists:
            if lst:
                out.append(lst.pop(0))
    return out


def make_dataset(folder, count=None):
    """Write the meshes (``count`` first recipes, all by default) as ``folder/NN-name.ply``; reuse
    the files already there. Returns [(path, vertices)]; recipes landing outside 5k-30k vertices
    are left out (reported)."""
    import open3d as o3d
    from bench_spectrum import bunny

    from o3dheat.geometry.sampling import resample
    from o3dheat.io import read_mesh, sample_mesh, write_mesh

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    sources, out = {}, []
    for i, (name, source, steps) in enumerate(_recipes()[:count]):
        path = folder / f"{i:02d}-{name}.ply"
        if not path.exists():
            if source not in sources:
                sources[source] = sample_mesh(source)
            mesh = sources[source]
            V, F = mesh.vertex.positions.numpy().astype(np.float64), mesh.triangle.indices.numpy().astype(np.int64)
            for kind, params in steps:
                if kind == "bunny":
                    V, F = bunny(params)
                else:
                    r = resample((V, F), kind, **params)
                    V, F = r.V, r.F
            m = o3d.t.geometry.TriangleMesh()
            m.vertex.positions = o3d.core.Tensor(np.ascontiguousarray(V))
            m.triangle.indices = o3d.core.Tensor(np.ascontiguousarray(F))
            write_mesh(path, m)
        mesh = read_mesh(path)
        n = len(mesh.vertex.positions)
        bad = _unclean(mesh)
        if MIN_V <= n <= MAX_V and not bad:
            out.append((path, n))
        else:
            print(f"left out: {path.name}, {n} vertices{': ' + bad if bad else ''}", file=sys.stderr)
            path.unlink()
    return out


def _unclean(mesh):
    """What keeps a mesh from being a clean closed connected 2-manifold ("" when nothing): both
    sides must see the same surface (o3dheat drops zero-area faces, robust-laplacian keeps them)."""
    from o3dheat import check_mesh

    r = check_mesh(mesh)
    counts = {"components": r.components - 1, "boundary edges": r.boundary_edges,
              "degenerate faces": r.degenerate_faces, "zero-area faces": r.zero_area_faces,
              "duplicate faces": r.duplicate_faces, "duplicate vertices": r.duplicate_vertices,
              "unreferenced vertices": r.unreferenced_vertices, "non-manifold edges": r.non_manifold_edges,
              "non-manifold vertices": r.non_manifold_vertices}
    return ", ".join(f"{v} {k}" for k, v in counts.items() if v)


def _warm_mesh(folder):
    """A 2,000-vertex sphere: the first calls (library loading, JIT caches) before the timing."""
    import open3d as o3d

    from o3dheat.io import write_mesh

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 32)
    m.vertex.positions = o3d.core.Tensor(m.vertex.positions.numpy().astype(np.float64) * [1.0, 0.8, 0.6])
    write_mesh(folder / "warm.ply", m)
    return folder / "warm.ply"


# ------------------------------------------------------------------------------------ the two sides
def o3dheat_one(path, dst):
    """o3dheat: eigensolve, HKS on the log grid, WKS; written. Returns (λ, timings)."""
    import o3dheat

    mesh = o3dheat.io.read_mesh(path)
    s = o3dheat.eigensolve(mesh, k=K_EIG, cache=False)
    K = o3dheat.HeatKernel(s)
    h = K.hks(K.scales(SCALES, grid="log"))
    w = K.wks(ENERGIES)
    np.savez(dst, evals=s.eigenvalues, hks=h, wks=w)
    return s.eigenvalues, {k: s.timings.get(k, 0.0) for k in ("assemble", "factorize", "solve")}


def diffusionnet_eigs(V, F, k=K_EIG):
    """DiffusionNet's eigenbasis (compute_operators, meshes), on robust-laplacian's L and mass:
    returns (L, massvec, evals, evecs)."""
    import robust_laplacian
    import scipy.sparse
    import scipy.sparse.linalg as sla

    eps = EPS
    L, M = robust_laplacian.mesh_laplacian(V, F)
    massvec_np = M.diagonal()
    if np.isnan(L.data).any():
        raise RuntimeError("NaN Laplace matrix")
    if np.isnan(massvec_np).any():
        raise RuntimeError("NaN mass matrix")
    L_eigsh = (L + scipy.sparse.identity(L.shape[0]) * eps).tocsc()
    Mmat = scipy.sparse.diags(massvec_np)
    eigs_sigma = eps
    failcount = 0
    while True:
        try:
            evals_np, evecs_np = sla.eigsh(L_eigsh, k=k, M=Mmat, sigma=eigs_sigma)
            evals_np = np.clip(evals_np, a_min=0.0, a_max=float("inf"))
            break
        except Exception as e:
            print(e, file=sys.stderr)
            if failcount > 3:
                raise ValueError("failed to compute eigendecomp") from e
            failcount += 1
            L_eigsh = L_eigsh + scipy.sparse.identity(L.shape[0]) * (eps * 10**failcount)
    return L, massvec_np, evals_np, evecs_np


def numpy_hks_wks(evals, evecs, scales=SCALES, energies=ENERGIES):
    """HKS and WKS from eigenpairs, by o3dheat's formulas (kernel.HeatKernel.scales/hks,
    signatures.wks). The constant mode is dropped by a threshold of 1e-5 λ_k: DiffusionNet's
    shift eps lifts it to about eps n / (4π k) λ_k (2e-7 λ_k at 30k vertices)."""
    lam = np.asarray(evals, np.float64)
    nz = lam > 1e-5 * lam.max()
    lk, l2 = lam.max(), lam[nz].min()
    t = np.geomspace(1.0 / lk, 2.0 * np.log(100.0) / l2, scales)
    X2 = evecs * evecs
    hks = X2 @ np.exp(-0.5 * np.multiply.outer(lam, t))
    r = lam[nz]
    lo, hi = np.log(r.min()), np.log(r.max()) / 1.02
    e = np.linspace(lo, hi, energies)
    sigma = 6.0 * (e[1] - e[0])
    G = np.exp(-np.subtract.outer(e, np.log(r)) ** 2 / (2.0 * sigma**2))
    wks = X2[:, nz] @ (G / G.sum(axis=1)[:, None]).T
    return hks, wks


def diffusionnet_one(path, dst):
    from o3dheat.io import read_mesh

    t0 = time.perf_counter()
    mesh = read_mesh(path)
    V = mesh.vertex.positions.numpy().astype(np.float64)
    F = mesh.triangle.indices.numpy()
    t1 = time.perf_counter()
    _, _, evals, evecs = diffusionnet_eigs(V, F)
    t2 = time.perf_counter()
    hks, wks = numpy_hks_wks(evals, evecs)
    np.savez(dst, evals=evals, hks=hks, wks=wks)
    return evals, {"read": t1 - t0, "laplacian+eigsh": t2 - t1, "descriptors+write": time.perf_counter() - t2}


def chain():
    from o3dheat.pipelines.filters import Chain

    return Chain([("hks", {"k": K_EIG, "scales": SCALES, "grid": "log"}), ("wks", {"k": K_EIG, "energies": ENERGIES})])


# ------------------------------------------------------------------------------------ one case
def _cpu():
    """CPU seconds of this process (user + system, all its threads)."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def child(case, data, out, work, peer_blas):
    """Run one case over the files of ``data`` into ``out``: JSON on stdout."""
    t_start = time.perf_counter()
    if case == "diffusionnet" and int(peer_blas) > 0:
        import robust_laplacian  # noqa: F401 - the BLAS libraries loaded before they are limited
        import scipy.sparse.linalg  # noqa: F401
        from threadpoolctl import threadpool_limits

        import o3dheat.spectral.linalg

        o3dheat.spectral.linalg.available_backends()
        with threadpool_limits(int(peer_blas)):
            return child(case, data, out, work, 0)
    out, work = Path(out), Path(work)
    files = sorted(Path(data).glob("*.ply"))
    import robust_laplacian  # noqa: F401 - imports outside the timing, on both sides
    import scipy.sparse.linalg  # noqa: F401

    import o3dheat
    import o3dheat.spectral.spectrum as spectrum_module
    from o3dheat.spectral.cache import SPECTRA
    from o3dheat.spectral.linalg import available_backends

    assert SPECTRA.disk is None, "a disk cache of spectra is set: the benchmark needs it off"
    available_backends()
    warm = _warm_mesh(work / "warm")
    result = {"case": case}
    if case in ("o3dheat", "o3dheat-1t", "diffusionnet"):
        one = diffusionnet_one if case == "diffusionnet" else o3dheat_one
        one(warm, work / "warm.npz")  # first calls, untimed
        out.mkdir(parents=True, exist_ok=True)
        startup = time.perf_counter() - t_start
        parts, evals, per = {}, {}, {}
        c0, t0 = _cpu(), time.perf_counter()
        for p in files:
            t1 = time.perf_counter()
            lam, tm = one(p, out / f"{p.stem}.npz")
            per[p.stem] = time.perf_counter() - t1
            evals[p.stem] = lam
            for k, v in tm.items():
                parts[k] = parts.get(k, 0.0) + v
        result.update(seconds=time.perf_counter() - t0, cpu=_cpu() - c0, parts=parts, per_mesh=per)
        if case != "o3dheat-1t":
            np.savez(work / f"evals-{case}.npz", **evals)
    else:
        from o3dheat.pipelines.batch import run

        solves = [0]
        solve = spectrum_module.solve_eigenproblem

        def counted(*a, **kw):  # the eigensolves of this process (sequential batch)
            solves[0] += 1
            return solve(*a, **kw)

        spectrum_module.solve_eigenproblem = counted
        pattern = str(Path(data) / "*.ply")
        if case.startswith("batch-seq"):
            run(chain(), str(warm), work / "warm-out", scheduler="sequential", suffix=".npz", progress=False,
                overwrite=True)
            result["solves_warm"] = solves[0]  # one mesh, two filters
            solves[0] = 0
            startup = time.perf_counter() - t_start
            c0, t0 = _cpu(), time.perf_counter()
            table = run(chain(), pattern, out, scheduler="sequential", suffix=".npz", progress=False)
            result.update(seconds=time.perf_counter() - t0, cpu=_cpu() - c0, solves=solves[0])
        else:
            from distributed import Client

            from o3dheat.pipelines.cluster import local_cluster

            cluster = local_cluster(2, pin=case != "batch-dask-nopin")
            client = Client(cluster)
            run(chain(), str(warm), work / "warm-out", scheduler=client, suffix=".npz", progress=False,
                overwrite=True)
            client.run(lambda: __import__("o3dheat.pipelines.batch"))  # every worker
            startup = time.perf_counter() - t_start
            w0, c0, t0 = sum(client.run(_cpu).values()), _cpu(), time.perf_counter()
            table = run(chain(), pattern, out, scheduler=client, suffix=".npz", progress=False)
            result["seconds"] = time.perf_counter() - t0
            result["cpu"] = sum(client.run(_cpu).values()) - w0 + _cpu() - c0
            client.close()
            cluster.close()
        result["failed"] = int((table["status"] != "done").sum())
        result["file_seconds"] = float(table["seconds"].sum())
    result["startup"] = startup
    result["threads"] = o3dheat.parallel.get_threads()
    print(json.dumps(result))


def _profile(path):
    """cProfile of o3dheat's per-mesh work on one file (after a warm-up): the top of the profile."""
    import cProfile
    import io
    import pstats

    import o3dheat  # noqa: F401
    from o3dheat.spectral.linalg import available_backends

    available_backends()
    tmp = Path(tempfile.mkdtemp(prefix="o3dheat-prof-"))
    o3dheat_one(_warm_mesh(tmp), tmp / "w.npz")
    pr = cProfile.Profile()
    pr.enable()
    lam, tm = o3dheat_one(path, tmp / "p.npz")
    pr.disable()
    s = io.StringIO()
    pstats.Stats(pr, stream=s).sort_stats("cumulative").print_stats(25)
    shutil.rmtree(tmp, ignore_errors=True)
    return tm, s.getvalue()


# ------------------------------------------------------------------------------------ accuracy
def accuracy(tmp, files, n_solver=3):
    """Markdown lines: eigenvalues and descriptors of the two sides; the solvers on the same matrices."""
    import scipy.sparse

    from o3dheat.io import read_mesh
    from o3dheat.spectral.spectrum import eigensolve_operators

    a = np.load(tmp / "work" / "evals-o3dheat.npz")
    b = np.load(tmp / "work" / "evals-diffusionnet.npz")
    lam_rel, hks_rel, wks_rel, batch_rel = [], [], [], []
    for p, _ in files:
        la, lb = np.sort(a[p.stem]), np.sort(b[p.stem])
        lam_rel.append(np.abs(la[1:] - lb[1:]) / lb[1:])
        za, zb = np.load(tmp / "out-o3dheat" / f"{p.stem}.npz"), np.load(tmp / "out-diffusionnet" / f"{p.stem}.npz")
        hks_rel.append(np.median(np.abs(za["hks"] - zb["hks"]) / np.abs(zb["hks"])))
        wks_rel.append(np.median(np.abs(za["wks"] - zb["wks"]) / np.abs(zb["wks"])))
        zc = np.load(tmp / "out-batch-seq" / f"{p.stem}.npz")
        batch_rel.append(max(np.max(np.abs(zc["vertex_hks"] - za["hks"])) / np.max(np.abs(za["hks"])),
                             np.max(np.abs(zc["vertex_wks"] - za["wks"])) / np.max(np.abs(za["wks"]))))
    med = np.array([np.median(r) for r in lam_rel])
    mx = np.array([np.max(r) for r in lam_rel])
    worst = files[int(np.argmax(med))][0].stem

    def row(what, values, note=""):
        return f"| {what} | {np.median(values):.1e} | {np.max(values):.1e}{note} |"

    lines = ["| check | median over meshes | worst mesh |", "|---|---|---|",
             row("λ_2..λ_128, o3dheat vs DiffusionNet: median relative difference per mesh", med, f" ({worst})"),
             row("λ_2..λ_128, o3dheat vs DiffusionNet: largest relative difference per mesh", mx),
             row("HKS (16 times), median relative difference per mesh", hks_rel),
             row("WKS (100 energies), median relative difference per mesh", wks_rel),
             row("batch (hks + wks chain) vs direct o3dheat, max abs difference / max value", batch_rel)]
    same = []
    for p, _ in files[:n_solver]:  # the solvers on the same matrices: DiffusionNet's
        m = read_mesh(p)
        V, F = m.vertex.positions.numpy().astype(np.float64), m.triangle.indices.numpy()
        L, massvec, evals, _ = diffusionnet_eigs(V, F)
        s = eigensolve_operators(L + EPS * scipy.sparse.identity(L.shape[0]), scipy.sparse.diags(massvec), k=K_EIG)
        same.append(np.max(np.abs(s.eigenvalues[1:] - evals[1:]) / evals[1:]))
    lines.append(f"| λ_2..λ_128 on DiffusionNet's own matrices: o3dheat's solver (eigensolve_operators) vs "
                 f"its eigsh, largest relative difference ({len(same)} meshes) | {np.median(same):.1e} | "
                 f"{np.max(same):.1e} |")
    return lines


# ------------------------------------------------------------------------------------ main
def _load():
    with open("/proc/loadavg") as fh:
        return fh.read().split()[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--meshes", type=int, default=None, help="the first N meshes only (default: all 57)")
    ap.add_argument("--repeat", type=int, default=2, help="repetitions, interleaved (default: %(default)s)")
    ap.add_argument("--cases", default=",".join(CASES),
                    help=f"(default: %(default)s; also {', '.join(EXTRA)})")
    ap.add_argument("--data", help="dataset folder, kept and reused (default: a temporary one)")
    ap.add_argument("--json", help="also write every run's measurements to this file")
    ap.add_argument("--profile", action="store_true", help="cProfile o3dheat's work on the largest mesh")
    ap.add_argument("--peer-blas", type=int, default=1,
                    help="BLAS threads of the DiffusionNet side, 0: as it comes (default: %(default)s, its "
                         "faster setting on a busy 2-core machine)")
    ap.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0

    tmp = Path(tempfile.mkdtemp(prefix="o3dheat-bench-dataset-"))
    try:
        return _main(args, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _main(args, tmp):
    cases = args.cases.split(",")
    data = Path(args.data) if args.data else tmp / "data"
    t0 = time.perf_counter()
    files = make_dataset(data, args.meshes)
    for p in data.glob("*.ply"):  # a kept folder made for more meshes: only these
        if p not in {f for f, _ in files}:
            data = tmp / "subset"
            data.mkdir(exist_ok=True)
            for f, _ in files:
                os.link(f, data / f.name) if not (data / f.name).exists() else None
            files = [(data / f.name, n) for f, n in files]
            break
    nv = np.array([n for _, n in files])
    print(f"dataset: {len(files)} meshes, {nv.min()}-{nv.max()} vertices (median {int(np.median(nv))}, "
          f"{nv.sum()} in all), made in {time.perf_counter() - t0:.0f} s (untimed)\n", flush=True)

    runs = {c: [] for c in cases}
    log = []
    for rep in range(args.repeat):
        for case in cases:
            out = tmp / f"out-{case}"
            shutil.rmtree(out, ignore_errors=True)
            load = _load()
            t = time.perf_counter()
            env = os.environ | ({"O3DHEAT_NUM_THREADS": "1"} if case.endswith("-1t") else {})
            r = subprocess.run([sys.executable, __file__, "--child", case, str(data), str(out), str(tmp / "work"),
                                str(args.peer_blas)], capture_output=True, text=True, env=env)
            wall = time.perf_counter() - t
            if r.returncode != 0:
                print(f"{case} failed:\n{r.stderr[-3000:]}", file=sys.stderr)
                return 1
            res = json.loads(r.stdout.strip().splitlines()[-1]) | {"load": load, "wall": wall, "rep": rep}
            runs[case].append(res)
            log.append(res)
            print(f"  rep {rep + 1} {case}: {res['seconds']:.1f} s (+ start-up {res['startup']:.1f} s), "
                  f"load {load}", file=sys.stderr, flush=True)
        if rep == 0 and {"o3dheat", "diffusionnet", "batch-seq"} <= set(cases):
            acc = accuracy(tmp, files)
        for case in cases:  # the outputs are large: not kept past the first repetition's checks
            shutil.rmtree(tmp / f"out-{case}", ignore_errors=True)

    n = len(files)
    if args.json:
        Path(args.json).write_text(json.dumps(log, indent=1))
    print(f"{n} meshes; k = {K_EIG}, HKS at {SCALES} times (log grid), WKS at {ENERGIES} energies; "
          f"{args.repeat} repetition(s), interleaved\n")
    print("| repetition | case | load before | timed loop s | CPU s | cores used (CPU / wall) | s per mesh | "
          "start-up s (imports, first calls; Dask: cluster) |\n|---|---|---|---|---|---|---|---|")
    for res in log:
        print(f"| {res['rep'] + 1} | {res['case']} | {res['load']} | {res['seconds']:.1f} | {res['cpu']:.1f} | "
              f"{res['cpu'] / res['seconds']:.2f} | {res['seconds'] / n:.2f} | {res['startup']:.1f} |")
    ratios = [(num, den) for num, den in PAIRS if num in cases and den in cases]
    print("\n| ratio | target | " + " | ".join(f"rep. {r + 1}: wall (CPU; start-up counted)"
                                             for r in range(args.repeat))
          + " | fastest runs, wall (least CPU) |\n|---|---|" + "---|" * (args.repeat + 1))
    best = {c: min(runs[c], key=lambda x: x["seconds"]) for c in cases if runs[c]}
    least = {c: min(runs[c], key=lambda x: x["cpu"]) for c in cases if runs[c]}
    for num, den in ratios:
        cells = []
        for rep in range(args.repeat):
            x, y = runs[num][rep], runs[den][rep]
            cells.append(f"{x['seconds'] / y['seconds']:.2f}x ({x['cpu'] / y['cpu']:.2f}x; "
                         f"{(x['seconds'] + x['startup']) / (y['seconds'] + y['startup']):.2f}x)")
        r = best[num]["seconds"] / best[den]["seconds"]
        target = TARGETS.get((num, den))
        verdict = f"{target:g}x: {'met' if r >= target else 'missed'}" if target else ""
        cells.append(f"{r:.2f}x ({least[num]['cpu'] / least[den]['cpu']:.2f}x)")
        print(f"| {num} / {den} | {verdict} | " + " | ".join(cells) + " |")
    if "o3dheat" in best:
        parts = best["o3dheat"]["parts"]
        print(f"\no3dheat, fastest run: eigensolve {sum(parts.values()):.1f} s (assemble {parts['assemble']:.1f}, "
              f"factorize {parts['factorize']:.1f}, solve {parts['solve']:.1f}) of {best['o3dheat']['seconds']:.1f} s")
    if "diffusionnet" in best:
        parts = best["diffusionnet"]["parts"]
        print("DiffusionNet, fastest run: " + ", ".join(f"{k} {v:.1f} s" for k, v in parts.items()))
    if "batch-seq" in best:
        b = best["batch-seq"]
        print(f"batch sequential: {b['solves']} eigensolves for {n} meshes (hks + wks share one spectrum; "
              f"warm-up: {b['solves_warm']} for 1 mesh); failed files: {b['failed']}")
    if "batch-dask" in best:
        print(f"batch on Dask: failed files {best['batch-dask']['failed']}; per-file seconds summed over the "
              f"workers {best['batch-dask']['file_seconds']:.1f} (sequential: "
              f"{best.get('batch-seq', {}).get('file_seconds', float('nan')):.1f})")
    if "o3dheat" in best and "diffusionnet" in best and "batch-seq" in cases:
        print("\nAccuracy (first repetition's files):\n")
        print("\n".join(acc))
    if args.profile:
        big = max(files, key=lambda x: x[1])
        tm, text = _profile(big[0])
        print(f"\ncProfile of o3dheat on {big[0].name} ({big[1]} vertices): eigensolve timings "
              + ", ".join(f"{k} {v:.2f} s" for k, v in tm.items()) + "\n```\n" + text.strip() + "\n```")
    print(f"\nmachine: {os.cpu_count()} cores; python {sys.version.split()[0]}; date {time.strftime('%Y-%m-%d')}; "
          f"load average at the end {_load()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
