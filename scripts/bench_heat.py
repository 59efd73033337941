#!/usr/bin/env python
"""Benchmark: the full heat kernel without eigenpairs (``o3dheat.heat_flow``) against the spectral
pipelines (o3dheat's ``eigensolve`` + ``HeatKernel.smooth``, LaPy 1.7 with CHOLMOD), measured in
one run on the same meshes, fields and times.

Meshes: the bunny of scripts/bench_spectrum.py at each size. Field: the height along the longest
axis plus Gaussian noise of 0.1 x its range (seed 0); "c fields" (``--fields``, default 1 and 8): the
height plus c independent draws (seeds 0..c-1). Times: the paper's grid ``K.scales(10)`` and the log grid
``K.scales(10, grid="log")`` of ``K = HeatKernel(eigensolve(mesh, k=100))``, computed once per
mesh in this process (untimed) and passed to every case; grid "paper+log" is both (20 times).

Each case runs in a fresh subprocess, timed from the (V, F) arrays in memory to the smoothed
fields in memory: set-up is counted on both sides (assembly, factorization, and the eigensolve of
the spectral pipelines). Outside the timing: imports, ``o3dheat.spectral.linalg.available_backends()``
(loads CHOLMOD and cholespy) and one run of the same pipeline on a 762-vertex sphere (loads
numba's cached loops and SciPy's lazy modules). Peak memory is the largest resident set size,
sampled every 10 ms, minus the resident size just before the work. With ``--repeat N`` the cases
run N times, interleaved, and each keeps its fastest run and its smallest peak (on a busy machine
OpenBLAS's threads make LaPy's ARPACK phase erratic, 0.8-16 s at 20k vertices: use --repeat).

    .venv/bin/python scripts/bench_heat.py                        # 20k and 200k vertices
    .venv/bin/python scripts/bench_heat.py --sizes 20000 --accuracy
    .venv/bin/python scripts/bench_heat.py --cases exact,lapy --repeat 2
    .venv/bin/python scripts/bench_heat.py --cases exact/paper/1,spectral/paper/1
    .venv/bin/python scripts/bench_heat.py --sizes 1000000 --cases exact,lapy   # minutes

Needs LaPy (``pip install -e .[dev]``). Prints Markdown tables; ratios are seconds of a method /
seconds of "exact" (higher = the full kernel faster).
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

sys.path.insert(0, str(Path(__file__).parent))
from bench_spectrum import PeakMemory, bunny  # noqa: E402

K_EIG = 100  # eigenpairs of the spectral pipelines (and of the reference defining the times)
TOL = 1e-8  # tolerance of the exact case
METHODS = ["spectral", "exact", "lapy"]
GRIDS = ["paper", "paper+log"]


def make_fields(V, count):
    """(n, count): the height along the longest axis plus noise of 0.1 x its range, seeds 0..count-1."""
    h = V[:, int(np.argmax(np.ptp(V, axis=0)))]
    return np.column_stack([h + 0.1 * np.ptp(h) * np.random.default_rng(s).standard_normal(len(V))
                            for s in range(count)])


def pipeline(method, V, F, f, t):
    """The timed work: ``(fields (n, T) or (n, c, T), info)`` with the stage seconds."""
    import o3dheat

    if method == "spectral":
        spec = o3dheat.eigensolve((V, F), k=K_EIG)
        t0 = time.perf_counter()
        out = o3dheat.HeatKernel(spec).smooth(f, t)
        tm = spec.timings
        return out, {"stages": {"asm": tm["assemble"], "fac": tm["factorize"], "eig": tm["solve"],
                                "smooth": time.perf_counter() - t0}}
    if method == "exact":
        out, rep = o3dheat.heat_flow((V, F), f, t, tol=TOL, return_report=True)
        tm = rep.timings
        return out, {"stages": {"asm": tm["assemble"], "fac": tm["factorize"], "sol": tm["solve"]},
                     "solves": int(rep.solves), "columns": int(len(rep.steps)), "shifts": len(rep.shifts),
                     "estimate": float(rep.estimate.max()), "backend": rep.backend}
    from lapy import Solver, TriaMesh

    t0 = time.perf_counter()
    solver = Solver(TriaMesh(V, F), lump=False, use_cholmod=True)
    t1 = time.perf_counter()
    lam, X = solver.eigs(k=K_EIG)
    t2 = time.perf_counter()
    D = np.exp(-np.multiply.outer(lam, t / 2))  # LaPy's exp(-λ τ) at τ = t/2: the paper's exp(-λ t/2)
    c = X.T @ (solver.mass @ f)
    if c.ndim == 1:
        out = X @ (c[:, None] * D)
    else:
        out = (X @ (c[:, :, None] * D[:, None, :]).reshape(K_EIG, -1)).reshape(len(V), c.shape[1], len(t))
    return out, {"stages": {"fem": t1 - t0, "eigs": t2 - t1, "smooth": time.perf_counter() - t2}}


def child(method, path, nfields, grid, out):
    """Run one case; print JSON with seconds, peak memory above the starting point and the stages."""
    z = np.load(path)
    V, F = z["V"], z["F"]
    f = np.ascontiguousarray(z["f"][:, 0] if nfields == 1 else z["f"][:, :nfields])
    t = z["paper"] if grid == "paper" else np.concatenate([z["paper"], z["log"]])
    import open3d as o3d
    from lapy import Solver, TriaMesh  # noqa: F401

    import o3dheat  # noqa: F401 - import cost outside the timing
    from o3dheat.spectral.linalg import available_backends

    available_backends()  # loads CHOLMOD and cholespy: library loading is not part of the timing
    s = o3d.geometry.TriangleMesh.create_sphere(1.0, 20)  # warm-up: numba's cached loops, lazy imports
    Vs, Fs = np.asarray(s.vertices, np.float64), np.asarray(s.triangles, np.int64)
    fs = make_fields(Vs, nfields)
    pipeline(method, Vs, Fs, fs[:, 0] if nfields == 1 else fs, np.geomspace(1e-3, 1.0, len(t)))
    peak = PeakMemory()
    t0 = time.perf_counter()
    res, info = pipeline(method, V, F, f, t)
    dt = time.perf_counter() - t0
    peak_bytes = peak.stop()
    if out != "-":
        np.save(out, res)
    print(json.dumps({"seconds": dt, "peak_mb": peak_bytes / 2**20} | info))


def accuracy(K, V, F, f, paper, log):
    """Lines on the exact result's accuracy, and ``err(a, b)``: the max over times of
    ‖a − b‖_B / ‖f − mean‖_B (B the consistent mass, mean the B-weighted mean)."""
    import o3dheat
    from o3dheat.errors import ConvergenceError

    B = o3dheat.mass_matrix((V, F))
    one = np.ones(len(f))
    g = f - (one @ (B @ f)) / (one @ (B @ one))
    nf = np.sqrt(g @ (B @ g))

    def err(a, b):
        d = np.asarray(a - b).reshape(len(f), -1)
        return float(np.sqrt(np.max(np.einsum("it,it->t", d, B @ d)))) / nf

    t = np.concatenate([paper, log])
    a, rep = o3dheat.heat_flow((V, F), f, t, tol=TOL, return_report=True)
    lines = [f"- exact (tol {TOL:g}, paper+log, 1 field): {rep.solves} solves, {len(rep.shifts)} shift(s), "
             f"largest FlowReport estimate {rep.estimate.max():.1e}"
             + ("  **> tol**" if rep.estimate.max() > TOL else "")]
    try:
        b, rep13 = o3dheat.heat_flow((V, F), f, t, tol=1e-13, return_report=True)
        lines.append(f"- (a) vs exact at tol 1e-13 (20 times): error {err(a, b):.1e} (the 1e-13 run: "
                     f"{rep13.solves} solves, largest estimate {rep13.estimate.max():.1e})")
    except ConvergenceError as e:
        lines.append(f"- (a) exact at tol 1e-13 did not converge: {e}")
    bound = K.truncation_bound(f, log)
    sel = np.flatnonzero(bound <= 1e-10)
    if len(sel):
        e = err(a[:, 10 + sel], K.smooth(f, log[sel]))
        lines.append(f"- (b) vs spectral k={K_EIG} at the {len(sel)} of 10 log-grid times with truncation bound "
                     f"<= 1e-10 (t >= {log[sel[0]]:.3g}): error {e:.1e}")
    else:
        lines.append(f"- (b) no log-grid time has truncation bound <= 1e-10 (smallest {bound.min():.1e})")
    bp = K.truncation_bound(f, paper)
    e = err(a[:, :10], K.smooth(f, paper))
    lines.append(f"- for scale: spectral k={K_EIG} vs exact on the paper grid: error {e:.1e} "
                 f"(truncation bound {bp.min():.2f}..{bp.max():.2f})")
    return lines, err


def stages(v):
    return " / ".join(f"{k} {s:.2f}" for k, s in v["stages"].items())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="20000,200000", help="vertex counts (1000000 is opt-in: minutes)")
    ap.add_argument("--cases", default=",".join(METHODS),
                    help="methods (spectral, exact, lapy) and/or cases method/grid/fields, e.g. exact/paper/8")
    ap.add_argument("--repeat", type=int, default=1, help="runs per case (the fastest is shown)")
    ap.add_argument("--accuracy", action="store_true", help="also check the exact result's accuracy")
    ap.add_argument("--fields", default="1,8", help="numbers of fields of the cases (e.g. 1,8,32)")
    ap.add_argument("--child", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        method, path, nfields, grid, out = args.child
        child(method, path, int(nfields), grid, out)
        return
    import o3dheat
    from o3dheat.spectral.cache import clear_cache

    wanted = set(args.cases.split(","))
    counts = sorted({int(c) for c in args.fields.split(",")} | {1})
    cases = [(m, g, c) for g in GRIDS for c in counts for m in METHODS
             if m in wanted or f"{m}/{g}/{c}" in wanted]
    if not cases:
        sys.exit(f"--cases {args.cases!r} selects nothing: use {', '.join(METHODS)} or e.g. exact/paper/8")
    tmp = Path(tempfile.mkdtemp(prefix="o3dheat-bench-heat-"))
    repeat = max(1, args.repeat)
    cost = []
    wall0 = time.perf_counter()
    for size in [int(s) for s in args.sizes.split(",")]:
        V, F = bunny(size)
        n = len(V)
        f8 = make_fields(V, max(counts))
        t0 = time.perf_counter()
        K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=K_EIG))
        t_ref = time.perf_counter() - t0
        paper, log = K.scales(10), K.scales(10, grid="log")
        path = tmp / f"bunny-{n}.npz"
        np.savez(path, V=V, F=F, f=f8, paper=paper, log=log)
        acc, err = accuracy(K, V, F, f8[:, 0], paper, log) if args.accuracy else ([], None)
        del K
        clear_cache()  # the accuracy runs' operators and factors: not kept while the cases run
        res, failed = {}, {}
        for _ in range(repeat):
            for case in cases:
                if case in failed:
                    continue
                m, g, c = case
                keep = args.accuracy and m != "exact" and c == 1 and g == "paper+log"  # lapy vs spectral
                out = tmp / f"{n}-{m}-{g}-{c}.npy" if keep else "-"
                r = subprocess.run([sys.executable, __file__, "--child", m, str(path), str(c), g, str(out)],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    failed[case] = (r.stderr.strip().splitlines() or ["no message"])[-1][:100]
                    continue
                run = json.loads(r.stdout.strip().splitlines()[-1])
                if case in res:
                    run["peak_mb"] = min(run["peak_mb"], res[case]["peak_mb"])
                    if res[case]["seconds"] <= run["seconds"]:
                        run = res[case] | {"peak_mb": run["peak_mb"]}
                res[case] = run
        backend = next((v["backend"] for (m, _, _), v in res.items() if m == "exact"), "CHOLMOD")
        print(f"\n### bunny, {n} vertices, {len(F)} faces\n")
        print(f"Times: from (V, F) arrays to fields in memory; set-up counted on both sides (spectral, lapy: "
              f"FEM assembly + eigensolve k={K_EIG} + X D_t Xᵀ B f; exact: assembly + factorization ({backend}) "
              f"+ Lanczos solves, tol {TOL:g}). Fastest of {repeat} run(s), peak = resident memory above the "
              f"start. The times (untimed reference eigensolve, {t_ref:.1f} s): paper {paper[0]:.3g}..{paper[-1]:.3g}, "
              f"log {log[0]:.3g}..{log[-1]:.3g}.\n")
        print("| case | grid | times | fields | seconds | peak MiB | solves | stages (s) | ÷ exact | ÷ 1 field |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for case in cases:
            m, g, c = case
            T = 10 if g == "paper" else 20
            if case in failed:
                print(f"| {m} | {g} | {T} | {c} | failed: {failed[case]} | | | | | |")
                continue
            v = res[case]
            ex, one = res.get(("exact", g, c)), res.get((m, g, 1))
            ratio = f"{v['seconds'] / ex['seconds']:.2f}x" if ex and m != "exact" else ""
            per = f"{v['seconds'] / one['seconds']:.2f}" if one and c > 1 else ""
            print(f"| {m} | {g} | {T} | {c} | {v['seconds']:.2f} | {v['peak_mb']:.0f} | {v.get('solves', '')} | "
                  f"{stages(v)} | {ratio} | {per} |", flush=True)
            if m == "exact":
                cost.append((n, g, c, v))
        if acc:
            print("\nAccuracy (1 field; error = max over times of ‖a − b‖_B / ‖f − mean‖_B, B consistent):")
            print()
            print("\n".join(acc))
            outs = {m: tmp / f"{n}-{m}-paper+log-1.npy" for m in ("spectral", "lapy")}
            if outs["spectral"].exists() and outs["lapy"].exists():
                print(f"- lapy vs o3dheat spectral (both k={K_EIG}, paper+log): error "
                      f"{err(np.load(outs['lapy']), np.load(outs['spectral'])):.1e} (checks LaPy's time convention)")
            for p in outs.values():
                p.unlink(missing_ok=True)
        path.unlink()
    if cost:
        print("\n### Cost per size (exact, tol 1e-8)\n")
        print("| n | grid | fields | solves | solves / field | shifts | assemble s | factorize s | solve s | "
              "total s | total µs / vertex | solve ns / (vertex · solve) | largest estimate |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for n, g, c, v in sorted(cost, key=lambda r: (r[1], r[2], r[0])):
            s = v["stages"]
            print(f"| {n} | {g} | {c} | {v['solves']} | {v['solves'] / c:.1f} | {v['shifts']} | {s['asm']:.2f} | "
                  f"{s['fac']:.2f} | {s['sol']:.2f} | {v['seconds']:.2f} | {1e6 * v['seconds'] / n:.1f} | "
                  f"{1e9 * s['sol'] / (n * v['solves']):.0f} | {v['estimate']:.1e} |")
    shutil.rmtree(tmp, ignore_errors=True)
    print(f"\nmachine: {os.cpu_count()} cores; python {sys.version.split()[0]}; date {time.strftime('%Y-%m-%d')}; "
          f"fastest of {repeat} run(s) per case; whole run {time.perf_counter() - wall0:.0f} s")


if __name__ == "__main__":
    main()
