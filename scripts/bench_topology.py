#!/usr/bin/env python
"""Benchmark: PL critical points and persistence, o3dheat against gudhi's lower-star persistence,
measured in one run on the same meshes and fields.

o3dheat times start from ``(V, F)`` arrays and include checking the mesh (edges, boundary,
manifoldness). gudhi's time includes listing the edges (numpy), inserting vertices, edges and
triangles with their lower-star values (``SimplexTree.insert_batch``) and ``compute_persistence``.
Both diagrams are compared (finite pairs of positive persistence, dimensions 0 and 1) and the
table says whether they agree.

    .venv/bin/python scripts/bench_topology.py                       # 100k and 1M vertices
    .venv/bin/python scripts/bench_topology.py --sizes 100000 --repeat 3

Needs gudhi (``pip install -e .[dev]`` or ``.[bench]``). Prints a Markdown table; the ratio is
gudhi time / o3dheat persistence time (higher = o3dheat faster).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_spectrum import bunny, torus  # noqa: E402  (the same meshes as the spectrum benchmark)

import o3dheat  # noqa: E402


def fields(V, seed=0):
    """A smooth field with a few dozen critical points, and the same with noise (very many)."""
    x, y, z = (V - V.mean(0)).T / np.ptp(V, axis=0).max()
    smooth = z + 0.3 * np.sin(7 * x) * np.cos(5 * y)
    noise = 0.05 * np.random.default_rng(seed).standard_normal(len(V))
    return {"smooth": smooth, "noisy": smooth + noise}


def gudhi_persistence(F, f):
    import gudhi

    used = np.unique(F)
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [0, 2]]]), axis=1), axis=0)
    st = gudhi.SimplexTree()
    st.insert_batch(used[None, :], f[used])
    st.insert_batch(E.T, f[E].max(axis=1))
    st.insert_batch(F.T, f[F].max(axis=1))
    st.compute_persistence(homology_coeff_field=2, min_persistence=-1)
    return [st.persistence_intervals_in_dimension(k) for k in (0, 1)]


def finite(D):
    D = np.asarray(D).reshape(-1, 2)
    D = D[np.isfinite(D[:, 1]) & (D[:, 1] > D[:, 0])]
    return D[np.lexsort((D[:, 1], D[:, 0]))]


def best_of(fn, repeat):
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="100000,1000000", help="comma-separated vertex counts")
    ap.add_argument("--meshes", default="torus,bunny")
    ap.add_argument("--repeat", type=int, default=1, help="best of this many runs per timing")
    ap.add_argument("--no-gudhi", action="store_true")
    args = ap.parse_args(argv)
    makers = {"torus": torus, "bunny": bunny}
    rows = []
    print("| mesh | vertices | field | critical points (min, saddle, max) | o3dheat critical s | "
          "o3dheat persistence s | gudhi s | gudhi / o3dheat | diagrams agree |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.meshes.split(","):
        for n in (int(s) for s in args.sizes.split(",")):
            V, F = makers[name](n)
            for label, f in fields(V).items():
                t_cp, cp = best_of(lambda: o3dheat.critical_points((V, F), f), args.repeat)
                t_p, d = best_of(lambda: o3dheat.persistence((V, F), f), args.repeat)
                if args.no_gudhi:
                    t_g, agree = float("nan"), "-"
                else:
                    t_g, g = best_of(lambda: gudhi_persistence(F, f), args.repeat)
                    ours = [finite(d.intervals(0)), finite(d.intervals(1)[:, ::-1])]
                    agree = "yes" if all(np.array_equal(a, finite(b)) for a, b in zip(ours, g)) else "NO"
                row = (f"| {name} | {len(V)} | {label} | {cp.counts} | {t_cp:.2f} | {t_p:.2f} | "
                       f"{t_g:.2f} | {t_g / t_p:.1f}x | {agree} |")
                print(row, flush=True)
                rows.append(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
