#!/usr/bin/env python
"""Benchmark: PL critical points and persistence, o3dheat against gudhi's lower-star persistence,
measured in one run on the same meshes and fields.

What is timed (best of ``--repeat`` runs each, in seconds):

* **Surface build**: ``topology.Surface((V, F))`` from arrays: welding check, edges, boundary,
  manifoldness, vertex adjacency. Built once per mesh, reused by every field.
* **critical**: ``critical_points(surface, f)``, field to result, Surface prebuilt;
  **critical (V, F)**: ``critical_points((V, F), f)``, the Surface built inside (a one-off call).
* **persistence**: ``persistence(surface, f)``, field to diagram, Surface prebuilt.
* **gudhi**: ``SimplexTree`` + ``insert_batch`` of the vertices, edges and triangles with their
  lower-star values + ``compute_persistence`` (Z/2) + reading the intervals of dimensions 0 and
  1. The edge list is made once per mesh outside the timing, as the Surface is; computing the
  lower-star values from f is inside (field-dependent work, as in o3dheat).

Both diagrams are compared (finite pairs of positive persistence, dimensions 0 and 1; o3dheat's
dimension 1 read as sublevel (saddle, maximum) pairs) and the table says whether they agree. The
ratio ``gudhi / o3dheat`` divides gudhi by o3dheat's persistence with the Surface prebuilt;
``gudhi / (build + o3dheat)`` charges the whole Surface build to that one field.

Memory (``--memory``, on by default): peak bytes allocated during one call (tracemalloc, which
sees numpy's and numba's allocations), beyond what the mesh and Surface already hold, per vertex;
the Surface's own size is given per vertex too. At 10M vertices gudhi is skipped (``--gudhi-max``).

The compiled loops (numba) are compiled once and cached beside the module: the first table
reports, in fresh processes, the first call with an empty cache (compiling) and with the cache
(loading).

**Tracking** (the last table, ``--tracking-size``, 200k vertices by default, 0 skips it): the bunny
at that size, a noisy height smoothed by ``heat_flow`` at 100 times ``np.geomspace(1e-4, 1, 100)``;
on one prebuilt Surface, the 100 critical-point sets alone (``critical_points(surface, F[:, i])``)
against ``track_critical_points(surface, F, t)`` (which computes them too), best of ``--repeat``,
and the ratio (the target: at most 3x); then the first read of ``Tracks.persistence`` (the
diagrams the tracking did not need, computed then) and the tracking's peak memory per n T.

**End to end** (``--end-to-end``, its own table instead of the others): one field from the arrays,
``persistence((V, F), f)`` (the checks of the arrays, the search for duplicate vertices, the
Surface and the persistence) against gudhi's simplex tree and persistence, single-threaded
(``OMP_NUM_THREADS``, ``NUMBA_NUM_THREADS`` and ``o3dheat.parallel.threads`` at 1), measured
interleaved (each round times gudhi once, then o3dheat three times; best over ``--repeat``
rounds), so that a busy machine slows both alike; the 1-minute load average is printed with
each row. gudhi's edge list is made outside its timing, as in the main table (in gudhi's favour).

    .venv/bin/python scripts/bench_topology.py                        # 100k and 1M vertices
    .venv/bin/python scripts/bench_topology.py --sizes 100000 --repeat 3
    .venv/bin/python scripts/bench_topology.py --sizes 10000000 --meshes torus --repeat 1  # slow
    .venv/bin/python scripts/bench_topology.py --only-tracking                  # the tracking table alone
    .venv/bin/python scripts/bench_topology.py --end-to-end --sizes 200000,1000000 --meshes bunny,torus

Needs gudhi (``pip install -e .[dev]`` or ``.[bench]``). Prints Markdown tables.
"""

from __future__ import annotations

import argparse
import gc
import os
import subprocess
import sys

if "--end-to-end" in sys.argv:  # single-threaded, before numpy and numba are imported
    for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ[_var] = "1"
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_spectrum import bunny, torus  # noqa: E402  (the same meshes as the spectrum benchmark)

import o3dheat  # noqa: E402
from o3dheat.topology import Surface  # noqa: E402


def fields(V, seed=0):
    """A smooth field with a few dozen critical points, and the same with noise (very many)."""
    x, y, z = (V - V.mean(0)).T / np.ptp(V, axis=0).max()
    smooth = z + 0.3 * np.sin(7 * x) * np.cos(5 * y)
    noise = 0.05 * np.random.default_rng(seed).standard_normal(len(V))
    return {"smooth": smooth, "noisy": smooth + noise}


def gudhi_edges(F):
    """The mesh's edges for gudhi, listed once per mesh (outside gudhi's timing)."""
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [0, 2]]]), axis=1)
    return np.unique(E, axis=0), np.unique(F)


def gudhi_persistence(F, E, used, f):
    import gudhi

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


def peak_bytes(fn):
    """Peak bytes allocated while ``fn`` runs, beyond what was allocated before (tracemalloc)."""
    gc.collect()
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        fn()
        return tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def surface_bytes(S):
    return sum(a.nbytes for a in vars(S).values() if isinstance(a, np.ndarray) and a is not S.V)


FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np, o3dheat
t1 = time.perf_counter()
V, F = np.random.default_rng(0).random((4, 3)), np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]])
o3dheat.persistence((V, F), V[:, 0]); o3dheat.critical_points((V, F), V[:, 0])
print(t1 - t0, time.perf_counter() - t1)
"""


def first_call():
    """(import s, first call s) in fresh processes: empty numba cache, then the filled cache."""
    out = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for _ in range(2):
            r = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True,
                               check=True)
            out.append(tuple(float(x) for x in r.stdout.split()))
    r = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True)
    out.append(tuple(float(x) for x in r.stdout.split()))
    return out


def tracking(n, repeat, memory=True):
    """The tracking table (see the module docstring): one row."""
    V, F = bunny(n)
    x, y, z = (V - V.mean(0)).T / np.ptp(V, axis=0).max()
    f = z + 0.05 * np.random.default_rng(0).standard_normal(len(V))
    t = np.geomspace(1e-4, 1.0, 100)
    Ft = o3dheat.heat_flow((V, F), f, t)
    S = Surface((V, F))
    o3dheat.track_critical_points(S, Ft[:, :2], t[:2])  # compiled loops loaded, scipy imported
    t_cp, cps = best_of(lambda: [o3dheat.critical_points(S, Ft[:, i]) for i in range(len(t))], repeat)
    t_tr, tr = best_of(lambda: o3dheat.track_critical_points(S, Ft, t), repeat)
    t0 = time.perf_counter()
    tr.persistence  # noqa: B018 - computed on first read
    t_p = time.perf_counter() - t0
    peak = peak_bytes(lambda: o3dheat.track_critical_points(S, Ft, t)) / Ft.size if memory else np.nan
    kinds = ", ".join(f"{e}: {sum(x['kind'] == e for x in tr.events)}" for e in
                      ("cancel", "creation", "death", "birth", "split", "merge"))
    print("| mesh | vertices | scales | critical points (first, last scale) | tracks | events | "
          "100 critical-point sets s | tracking s | tracking / critical points | first read of "
          "persistence s | tracking peak B / (n T) |")
    print("|" + "---|" * 11)
    print(f"| bunny | {len(V)} | {len(t)} | {cps[0].counts}, {cps[-1].counts} | {len(tr)} | {kinds} | "
          f"{t_cp:.3f} | {t_tr:.3f} | {t_tr / t_cp:.2f}x | {t_p:.3f} | {peak:.1f} |", flush=True)


def end_to_end(meshes, sizes, repeat, gudhi_max):
    """The end-to-end table (see the module docstring): one row per mesh, size and field."""
    from o3dheat.parallel import threads

    print("| vertices | mesh | field | pairs | o3dheat end to end s | µs per vertex | of which Surface s | "
          "of which persistence s | gudhi s | gudhi / o3dheat | diagrams agree | load (1 min) |")
    print("|" + "---|" * 12)
    for name in meshes:
        for n in sizes:
            V, F = {"torus": torus, "bunny": bunny}[name](n)
            gudhi = len(V) <= gudhi_max
            if gudhi:
                E, used = gudhi_edges(F)
            for label, f in fields(V).items():
                with threads(1):
                    d = o3dheat.persistence((V, F), f)  # compiled loops loaded
                    t_o = t_g = t_s = t_p = np.inf
                    for _ in range(repeat):  # interleaved: gudhi once, then o3dheat three times
                        if gudhi:
                            t0 = time.perf_counter()
                            g = gudhi_persistence(F, E, used, f)
                            t_g = min(t_g, time.perf_counter() - t0)
                        for _ in range(3):
                            t0 = time.perf_counter()
                            d = o3dheat.persistence((V, F), f)
                            t1 = time.perf_counter()
                            S = Surface((V, F))
                            t2 = time.perf_counter()
                            o3dheat.persistence(S, f)
                            t3 = time.perf_counter()
                            t_o, t_s, t_p = min(t_o, t1 - t0), min(t_s, t2 - t1), min(t_p, t3 - t2)
                if gudhi:
                    ours = [finite(d.intervals(0)), finite(d.intervals(1)[:, ::-1])]
                    agree = "yes" if all(np.array_equal(a, finite(b)) for a, b in zip(ours, g, strict=True)) else "NO"
                    cmp = f"{t_g:.2f} | {t_g / t_o:.1f}x | {agree}"
                else:
                    cmp = "- | - | -"
                print(f"| {len(V):,} | {name} | {label} | {len(d):,} | {t_o:.3f} | {t_o / len(V) * 1e6:.2f} | "
                      f"{t_s:.3f} | {t_p:.3f} | {cmp} | {os.getloadavg()[0]:.1f} |", flush=True)
                S = None
            gc.collect()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="100000,1000000", help="comma-separated vertex counts (10000000: slow)")
    ap.add_argument("--meshes", default="torus,bunny")
    ap.add_argument("--repeat", type=int, default=3, help="best of this many runs per timing")
    ap.add_argument("--no-gudhi", action="store_true")
    ap.add_argument("--gudhi-max", type=int, default=2_000_000, help="skip gudhi above this many vertices")
    ap.add_argument("--no-memory", action="store_true", help="skip the tracemalloc peak measurements")
    ap.add_argument("--no-first-call", action="store_true", help="skip the compile / cache-load table")
    ap.add_argument("--tracking-size", type=int, default=200_000, help="vertices of the tracking case (0: skip)")
    ap.add_argument("--only-tracking", action="store_true", help="the tracking table alone")
    ap.add_argument("--end-to-end", action="store_true",
                    help="the end-to-end table alone: persistence((V, F), f) against gudhi, single-threaded, interleaved")
    args = ap.parse_args(argv)
    if args.end_to_end:
        end_to_end(args.meshes.split(","), [int(s) for s in args.sizes.split(",")], args.repeat, args.gudhi_max)
        return 0
    if args.only_tracking:
        tracking(args.tracking_size, args.repeat, not args.no_memory)
        return 0
    makers = {"torus": torus, "bunny": bunny}
    if not args.no_first_call:
        (i0, c0), (i1, c1), (i2, c2) = first_call()
        print("| first call in a fresh process (4-vertex mesh: Surface, persistence, critical points) | "
              "import o3dheat s | first call s |")
        print("|---|---|---|")
        print(f"| empty numba cache (compiles every loop) | {i0:.2f} | {c0:.2f} |")
        print(f"| numba cache filled by the previous run | {i1:.2f} | {c1:.2f} |")
        print(f"| the installation's cache (o3dheat/__pycache__) | {i2:.2f} | {c2:.2f} |")
        print(flush=True)
    cols = ["mesh", "vertices", "field", "critical points (min, saddle, max)", "Surface build s",
            "critical s", "critical (V, F) s", "persistence s", "gudhi s", "gudhi / o3dheat",
            "gudhi / (build + o3dheat)", "diagrams agree"]
    if not args.no_memory:
        cols += ["Surface B/vertex", "build peak B/vertex", "critical peak B/vertex", "persistence peak B/vertex"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for name in args.meshes.split(","):
        for n in (int(s) for s in args.sizes.split(",")):
            V, F = makers[name](n)
            t_s, S = best_of(lambda: Surface((V, F)), args.repeat)  # noqa: B023 - best_of calls it at once
            gudhi = not args.no_gudhi and len(V) <= args.gudhi_max
            if gudhi:
                E, used = gudhi_edges(F)
            mem = []
            if not args.no_memory:
                S = None  # freed before the peak is measured
                b_build = peak_bytes(lambda: Surface((V, F)))  # noqa: B023 - peak_bytes calls it at once
                S = Surface((V, F))
                mem = [surface_bytes(S) / len(V), b_build / len(V)]
            for label, f in fields(V).items():
                t_cp, cp = best_of(lambda: o3dheat.critical_points(S, f), args.repeat)  # noqa: B023 - best_of calls it at once
                t_cpv, _ = best_of(lambda: o3dheat.critical_points((V, F), f), min(args.repeat, 2))  # noqa: B023 - best_of calls it at once
                t_p, d = best_of(lambda: o3dheat.persistence(S, f), args.repeat)  # noqa: B023 - best_of calls it at once
                if gudhi:
                    t_g, g = best_of(lambda: gudhi_persistence(F, E, used, f), min(args.repeat, 2))  # noqa: B023 - best_of calls it at once
                    ours = [finite(d.intervals(0)), finite(d.intervals(1)[:, ::-1])]
                    agree = "yes" if all(np.array_equal(a, finite(b)) for a, b in zip(ours, g, strict=True)) else "NO"
                    ratios = f"{t_g:.2f} | {t_g / t_p:.1f}x | {t_g / (t_s + t_p):.1f}x | {agree}"
                else:
                    ratios = "- | - | - | -"
                extra = ""
                if not args.no_memory:
                    m_cp = peak_bytes(lambda: o3dheat.critical_points(S, f)) / len(V)  # noqa: B023 - peak_bytes calls it at once
                    m_p = peak_bytes(lambda: o3dheat.persistence(S, f)) / len(V)  # noqa: B023 - peak_bytes calls it at once
                    extra = " | " + " | ".join(f"{x:.0f}" for x in mem + [m_cp, m_p])
                print(f"| {name} | {len(V)} | {label} | {cp.counts} | {t_s:.3f} | {t_cp:.3f} | {t_cpv:.3f} | "
                      f"{t_p:.3f} | {ratios}{extra} |", flush=True)
            S = None
            gc.collect()
    if args.tracking_size:
        print()
        tracking(args.tracking_size, args.repeat, not args.no_memory)
    return 0


if __name__ == "__main__":
    sys.exit(main())
