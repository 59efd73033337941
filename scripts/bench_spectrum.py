#!/usr/bin/env python
"""Benchmark: the smallest k eigenpairs of the linear FEM Laplacian, o3dheat against its peers,
measured in one run on the same meshes.

Peers: SciPy's ``eigsh(L, k, M=B, sigma=σ)`` with its default SuperLU factorization, LaPy 1.7
``Solver(mesh).eigs(k)`` (SuperLU) and ``Solver(mesh, use_cholmod=True).eigs(k)`` (cholespy).
Each case runs in a fresh subprocess; its peak memory is the largest resident set size sampled
every 10 ms while solving, minus the resident size just before (mesh loaded, libraries imported). Times include assembling the matrices and the factorization.
With ``--repeat N`` every case runs N times, the methods interleaved (o3dheat, peers, o3dheat,
peers, ...), and the table shows each method's fastest run and its smallest peak memory: on a
shared machine, noise only ever adds time, so the minimum is the fairest single number.

    .venv/bin/python scripts/bench_spectrum.py                 # 10k, 50k, 200k; k = 100 (+ k = 300 at 50k)
    .venv/bin/python scripts/bench_spectrum.py --sizes 10000   # quick
    .venv/bin/python scripts/bench_spectrum.py --methods o3dheat,lapy-cholmod
    .venv/bin/python scripts/bench_spectrum.py --repeat 2       # the table of docs/details/eigensolver.md
    .venv/bin/python scripts/bench_spectrum.py --sizes 1000000 --meshes bunny --methods o3dheat,lapy-cholmod

Needs LaPy (``pip install -e .[dev]`` installs it). Prints a Markdown table; ratios are
peer time / o3dheat time (higher = o3dheat faster).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

METHODS = ["o3dheat", "o3dheat-arpack", "eigsh", "lapy", "lapy-cholmod"]


def torus(n):
    import open3d as o3d

    radial = int(round(np.sqrt(2 * n)))
    m = o3d.geometry.TriangleMesh.create_torus(1.0, 0.4, radial, max(3, n // radial))
    return np.asarray(m.vertices, np.float64), np.asarray(m.triangles, np.int64)


def bunny(n):
    """Irregular: the bunny Loop-subdivided, then quadric-decimated to n vertices (fast-simplification
    keeps detail where curvature is high: a curvature-adaptive, strongly non-uniform sampling)."""
    import fast_simplification

    from o3dheat.io import default_mesh

    leg = default_mesh()[0].to_legacy()
    while len(leg.vertices) < 1.5 * n:
        leg = leg.subdivide_loop(1)
    V, F = np.asarray(leg.vertices), np.asarray(leg.triangles)
    V2, F2 = fast_simplification.simplify(V, F.astype(np.int32), target_count=2 * n)
    return np.asarray(V2, np.float64), np.asarray(F2, np.int64)


class PeakMemory:
    """The largest resident set size of this process from now on, sampled every 10 ms, minus the
    resident size at the start: ``stop()`` ends the sampling and returns it (bytes)."""

    def __init__(self):
        import threading

        self._page = os.sysconf("SC_PAGE_SIZE")
        self._base = self._rss()
        self._peak = self._base
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()

    def _rss(self):
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * self._page

    def _sample(self):
        while not self._stop.is_set():
            self._peak = max(self._peak, self._rss())
            time.sleep(0.01)

    def stop(self):
        self._stop.set()
        self._thread.join()
        return max(self._peak, self._rss()) - self._base


def child(method, path, k, out):
    """Run one case; print JSON with seconds and peak memory above the starting point."""
    z = np.load(path)
    V, F = z["V"], z["F"]
    import scipy.sparse.linalg as spla
    from lapy import Solver, TriaMesh  # noqa: F401 - import cost outside the timing

    import o3dheat
    from o3dheat.spectral.linalg import available_backends

    available_backends()  # loads CHOLMOD and cholespy: library loading is not part of the timing
    peak = PeakMemory()
    t0 = time.perf_counter()
    if method.startswith("o3dheat"):
        s = o3dheat.eigensolve((V, F), k=k, method="arpack" if method == "o3dheat-arpack" else "auto")
        tm = s.timings  # where the time goes: assembly, factorization, Krylov phase (incl. residuals)
        lam, extra = s.eigenvalues, (f"{s.backend}; assemble {tm['assemble']:.1f} + factorize "
                                     f"{tm['factorize']:.1f} + solve {tm['solve']:.1f} s")
    elif method == "eigsh":
        L = o3dheat.stiffness_matrix((V, F))
        B = o3dheat.mass_matrix((V, F))
        sigma = -0.01 * 4 * np.pi / B.sum()
        lam, _ = spla.eigsh(L, k=k, M=B, sigma=sigma)
        extra = "SuperLU"
    else:
        s = Solver(TriaMesh(V, F), use_cholmod=(method == "lapy-cholmod"))
        lam, _ = s.eigs(k=k)
        extra = "cholespy" if method == "lapy-cholmod" else "SuperLU"
    dt = time.perf_counter() - t0
    np.save(out, np.sort(lam))
    print(json.dumps({"seconds": dt, "peak_mb": peak.stop() / 2**20, "extra": extra}))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="10000,50000,200000")
    ap.add_argument("--k", type=int, default=100)
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--meshes", default="torus,bunny")
    ap.add_argument("--repeat", type=int, default=1, help="runs per case and method (the fastest is shown)")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.child[0], args.child[1], int(args.child[2]), args.child[3])
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    methods = args.methods.split(",")
    tmp = Path(tempfile.mkdtemp(prefix="o3dheat-bench-"))
    cases = []
    for name in args.meshes.split(","):
        for n in sizes:
            ks = [args.k] + ([300] if n == 50000 and args.k == 100 else [])
            V, F = (torus if name == "torus" else bunny)(n)
            path = tmp / f"{name}-{n}.npz"
            np.savez(path, V=V, F=F)
            for k in ks:
                cases.append((name, len(V), k, path))
    print("| mesh | n | k | method | seconds | peak MB | o3dheat speed-up | max rel. eigenvalue diff |")
    print("|---|---|---|---|---|---|---|---|")
    for name, n, k, path in cases:
        res, failed = {}, set()
        for _ in range(max(1, args.repeat)):
            for method in methods:
                if method in failed:
                    continue
                out = tmp / f"{name}-{n}-{k}-{method}.npy"
                r = subprocess.run([sys.executable, __file__, "--child", method, str(path), str(k), str(out)],
                                   capture_output=True, text=True)
                if r.returncode != 0:
                    failed.add(method)
                    print(f"| {name} | {n} | {k} | {method} | failed: {r.stderr.strip().splitlines()[-1][:80]} | | | |")
                    continue
                run = json.loads(r.stdout.strip().splitlines()[-1]) | {"lam": np.load(out)}
                if method in res:
                    run["peak_mb"] = min(run["peak_mb"], res[method]["peak_mb"])
                    if res[method]["seconds"] <= run["seconds"]:
                        run = res[method] | {"peak_mb": run["peak_mb"]}
                res[method] = run
        ref = res.get("o3dheat")
        for method, v in res.items():
            ratio = f"{v['seconds'] / ref['seconds']:.2f}x" if ref and method != "o3dheat" else ""
            diff = ""
            if ref is not None and method != "o3dheat":
                a, b = ref["lam"], v["lam"]
                diff = f"{np.max(np.abs(a[1:] - b[1:]) / np.abs(b[1:])):.1e}"
            print(f"| {name} | {n} | {k} | {method} ({v['extra']}) | {v['seconds']:.2f} | {v['peak_mb']:.0f} | "
                  f"{ratio} | {diff} |", flush=True)
    print(f"\nmachine: {os.cpu_count()} cores; python {sys.version.split()[0]}; "
          f"date {time.strftime('%Y-%m-%d')}; fastest of {max(1, args.repeat)} run(s) per case and method")


if __name__ == "__main__":
    main()
