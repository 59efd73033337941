#!/usr/bin/env python
"""Benchmark: can one Cholesky factor serve both the truncated spectrum and the exact heat flow?

A chain, a study or ``o3dheat view`` that computes both a truncated spectrum
(``eigensolve``: shift-invert block Lanczos on ``L − σB``) and the exact flow (``heat_flow``:
rational Krylov on ``W + γL``, one factor per group of times) factorizes at least twice. With the
consistent mass (``B = W``) the two matrices are the same up to scale when ``σ = −1/γ``:
``W + γL = γ (L − σW)``. This script measures what sharing would gain, on the bunny of
``scripts/bench_spectrum.py`` at each size, for the two grids the tools use (the paper's 10 scales
``(i/10)/λ_k`` and 20 log-spaced scales ``1/λ_k .. 2 ln 100/λ_2``), in one run:

* ``factor``: the flow's factorization(s) of ``W + γL`` alone (what sharing could save): the
  flow's own report (``HeatFlow.apply(..., return_report=True).timings["factorize"]``);
* ``eigensolve``: ``eigensolve(mesh, k, cache=False)`` with its own shift (``σ = −0.01`` times a
  lower bound of ``λ_2``); its time and Lanczos solves;
* ``eigensolve at −1/γ``: the same with ``sigma = −1/γ`` for the flow's first shift γ (the
  factor the flow would then reuse), its time, and the eigenvalues' agreement;
* ``flow at −1/σ``: the converse, the flow's times propagated on the eigensolve's factor
  (``γ = −1/σ``), its solves against the flow's own (the flow's cost is its solves).

Sharing wins where ``eigensolve at −1/γ`` costs less than ``eigensolve + factor``, or ``flow at
−1/σ`` less than the flow with its own factor. Set-up (operators) is counted on neither side:
o3dheat's caches are warmed with the operators first, and factors are cleared before each solve.

    .venv/bin/python scripts/bench_one_factor.py                 # 20k and 100k vertices
    .venv/bin/python scripts/bench_one_factor.py --sizes 200000 --k 128

Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_spectrum import bunny  # noqa: E402


def grids(spectrum):
    from o3dheat import HeatKernel

    K = HeatKernel(spectrum)
    return {"paper (10)": K.scales(10, grid="paper"), "log (20)": K.scales(20, grid="log")}


def flow_with_gamma(V, F, f, t, gamma):
    """The flow of ``f`` at times ``t`` propagated on the factor of ``W + γL`` for the given γ
    (one group): (seconds, solves, result)."""
    from o3dheat.spectral import heatflow
    from o3dheat.spectral._flow_setup import Shifted

    flow = heatflow.HeatFlow((V, F))
    t0 = time.perf_counter()
    shifted = Shifted(flow._ops, gamma, flow.backend)
    t1 = time.perf_counter()
    taus, _, null_rate = flow._rates(np.asarray(t, dtype=np.float64))
    cols = f[flow._prep.keep][:, None] / np.abs(f).max()
    U = np.empty((len(cols), 1, len(taus)))
    info = flow._propagate(shifted, cols, taus, gamma, U, flow.tol, 3000, None, null_rate)
    return t1 - t0, time.perf_counter() - t1, int(info.solves), U[:, 0, :] * np.abs(f).max()


def case(n, k):
    import o3dheat
    from o3dheat.spectral.cache import clear_cache

    V, F = bunny(n)
    f = V[:, 1] + 0.1 * np.ptp(V[:, 1]) * np.random.default_rng(0).standard_normal(len(V))
    clear_cache()
    t0 = time.perf_counter()
    s = o3dheat.eigensolve((V, F), k=k, cache=False)
    eig = time.perf_counter() - t0
    sigma = s.sigma
    rows = []
    for name, t in grids(s).items():
        clear_cache()
        flow = o3dheat.HeatFlow((V, F))
        ref, report = flow.apply(f, t, return_report=True)
        gamma = report.shifts[0][0]
        own_solves = int(report.steps.sum())
        # the eigensolve on the flow's first factor (sigma = -1/gamma)
        t0 = time.perf_counter()
        s2 = o3dheat.eigensolve((V, F), k=k, cache=False, sigma=-1.0 / gamma)
        eig2 = time.perf_counter() - t0
        agree = float(np.max(np.abs(s2.eigenvalues - s.eigenvalues) / np.maximum(s.eigenvalues[-1], 1e-300)))
        # the flow on the eigensolve's factor (gamma = -1/sigma): all times on one factor
        fac3, sol3, solves3, U3 = flow_with_gamma(V, F, f, t, -1.0 / sigma)
        err3 = float(np.abs(U3 - ref).max() / np.abs(ref).max())
        rows.append({"n": len(V), "grid": name, "groups": len(report.shifts), "gamma": gamma,
                     "factor": report.timings["factorize"], "flow_solve": report.timings["solve"],
                     "flow_solves": own_solves, "eig": eig, "eig_fac": s.timings["factorize"],
                     "eig2": eig2, "eig2_fac": s2.timings["factorize"], "agree": agree,
                     "sol3": sol3, "solves3": solves3, "err3": err3, "sigma": sigma})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="20000,100000", help="vertices, comma-separated")
    ap.add_argument("--k", type=int, default=100, help="eigenpairs (default 100, as view's grids)")
    args = ap.parse_args()
    rows = []
    for n in (int(x) for x in args.sizes.split(",")):
        rows += case(n, args.k)
        print(f"  {n}: done", file=sys.stderr)
    print(f"| vertices | grid | flow: factors (s) / solves (s) | eigensolve k={args.k} (s; its factor s) | "
          "eigensolve at σ = −1/γ₁ (s; max |Δλ|/λ_k) | saving of sharing the flow's factor (s) | "
          "flow on the eigensolve's factor: solve s (solves, own) | its error |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        saving = r["eig"] + r["factor"] - (r["eig2"] + r["factor"] - r["factor"] / r["groups"])
        print(f"| {r['n']:,} | {r['grid']} | {r['factor']:.2f} ({r['groups']}) / {r['flow_solve']:.2f} | "
              f"{r['eig']:.2f}; {r['eig_fac']:.2f} | {r['eig2']:.2f}; {r['agree']:.0e} | {saving:+.2f} | "
              f"{r['sol3']:.2f} ({r['solves3']}, {r['flow_solves']}) | {r['err3']:.0e} |")


if __name__ == "__main__":
    main()
