#!/usr/bin/env python
"""Benchmark: one robustness study run sequentially and on a local Dask cluster with 2 workers.

Prints the wall times, the speed-up and the per-task overhead of the distributed run
(``(T_dask − T_sequential / workers) / tasks``, cluster start-up excluded and reported apart),
and checks that both tables are identical.

    .venv/bin/python scripts/bench_study.py                 # 2 meshes x 6 resamplings
    .venv/bin/python scripts/bench_study.py --faces 4000 -k 40
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--faces", type=int, default=10000, help="faces of each reference mesh (default: %(default)s)")
    ap.add_argument("-k", type=int, default=60, help="eigenpairs (default: %(default)s)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args(argv)

    import pandas as pd
    from distributed import Client, LocalCluster

    from o3dheat.study import _builtin, robustness_study

    meshes = {name: _builtin(f"builtin:{name}@{args.faces}") for name in ("bunny", "torus")}
    resamplings = {"decimate-50": {"kind": "decimate", "reduction": 0.5},
                   "decimate-80": {"kind": "decimate", "reduction": 0.8},
                   "anisotropic": {"kind": "anisotropic"},
                   "jitter": {"kind": "jitter", "amount": 0.3},
                   "subdivide": {"kind": "subdivide", "iterations": 1},
                   "remesh": {"kind": "remesh", "edge_factor": 1.5}}
    kw = dict(k=args.k, scales=10, progress=False)
    tasks = len(meshes) * len(resamplings)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        seq = robustness_study(meshes, resamplings, out=f"{tmp}/seq", scheduler="sequential", **kw)
        t_seq = time.perf_counter() - t0
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
        t_start = time.perf_counter() - t0
        t0 = time.perf_counter()
        dist = robustness_study(meshes, resamplings, out=f"{tmp}/dask", scheduler=client, **kw)
        t_dask = time.perf_counter() - t0
        client.close()
        cluster.close()
    same = seq.equals(dist)
    overhead = (t_dask - t_seq / args.workers) / tasks
    print(f"| run | tasks | wall s | speed-up |\n|---|---|---|---|")
    print(f"| sequential | {tasks} | {t_seq:.1f} | 1.00x |")
    print(f"| Dask, {args.workers} workers (cluster start {t_start:.1f} s apart) | {tasks} | {t_dask:.1f} | "
          f"{t_seq / t_dask:.2f}x |")
    print(f"\nper-task overhead of the distributed run: {overhead:+.2f} s; tables identical: {same}; "
          f"failed tasks: {int((seq['error'] != '').sum())}")
    pd.set_option("display.width", 160)
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
