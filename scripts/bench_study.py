#!/usr/bin/env python
"""Benchmark: one robustness study run sequentially and on a local Dask cluster of 2 workers.

Prints a Markdown table: wall time, CPU time (this process, or the workers and this process),
the speed-up over the sequential run and the per-task overhead of the distributed run
(``(T_dask − T_sequential / workers) / tasks``), and checks that every run gives the same table,
bit for bit. One-time costs are measured apart, as in a long session: the sequential run follows
a small study that imports everything; each cluster is started (``cluster start``) and its workers
then run the same small study (``workers' warm-up``: imports, pymeshlab's first call); the last
column gives the speed-up with both counted. ``--dask-defaults`` adds a run on a cluster with
Dask's default worker environment (``MALLOC_TRIM_THRESHOLD_=65536``, which
:func:`o3dheat.pipelines.cluster.local_cluster` does not set) to show what it costs. Runs alternate and the
fastest of ``--repeat`` is shown; the machine should be otherwise idle (with 2 cores, anything
else running takes a worker's core).

    .venv/bin/python scripts/bench_study.py                 # 3 meshes x 6 resamplings = 18 tasks
    .venv/bin/python scripts/bench_study.py --dask-defaults --repeat 3
    .venv/bin/python scripts/bench_study.py --faces 4000 -k 40 --meshes bunny,torus
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time

RESAMPLINGS = {"decimate-50": {"kind": "decimate", "reduction": 0.5},
               "decimate-80": {"kind": "decimate", "reduction": 0.8},
               "anisotropic": {"kind": "anisotropic"},
               "jitter": {"kind": "jitter", "amount": 0.3},
               "subdivide": {"kind": "subdivide", "iterations": 1},
               "remesh": {"kind": "remesh", "edge_factor": 1.5}}


def _cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _worker_cpu():
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--faces", type=int, default=10000, help="faces of each reference mesh (default: %(default)s)")
    ap.add_argument("-k", type=int, default=60, help="eigenpairs (default: %(default)s)")
    ap.add_argument("--meshes", default="bunny,torus,bone", help="built-in meshes (default: %(default)s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each kind; the fastest is shown")
    ap.add_argument("--dask-defaults", action="store_true",
                    help="also run on a LocalCluster with Dask's default worker environment")
    args = ap.parse_args(argv)

    import open3d as o3d
    from distributed import Client, LocalCluster

    from o3dheat.pipelines.cluster import local_cluster
    from o3dheat.pipelines.study import _builtin, robustness_study

    meshes = {name: _builtin(f"builtin:{name}@{args.faces}") for name in args.meshes.split(",")}
    kw = dict(k=args.k, scales=10, progress=False)
    tasks = len(meshes) * len(RESAMPLINGS)
    small = ({"warm-up": o3d.t.geometry.TriangleMesh.create_sphere(1.0, 12)}, {"warm": {"kind": "remesh"}})
    small_kw = dict(kernels=["weighted"], descriptors=["hks_density"], k=10, scales=2, progress=False)
    labels = ["sequential", f"Dask, {args.workers} workers (o3dheat.pipelines.cluster.local_cluster)"]
    makers = [None, lambda: local_cluster(args.workers)]
    if args.dask_defaults:
        labels.append(f"Dask, {args.workers} workers (LocalCluster, Dask's default worker environment)")
        makers.append(lambda: LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None))
    best, tables = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        robustness_study(*small, scheduler="sequential", **small_kw)  # imports, first calls
        for i in range(args.repeat):
            for label, make in zip(labels, makers, strict=True):
                if make is None:
                    c0, t0 = _cpu(), time.perf_counter()
                    tables.append(robustness_study(meshes, RESAMPLINGS, out=f"{tmp}/s{i}", scheduler="sequential",
                                                   **kw))
                    run = (time.perf_counter() - t0, _cpu() - c0, 0.0, 0.0)
                else:
                    t0 = time.perf_counter()
                    cluster = make()
                    client = Client(cluster)
                    start = time.perf_counter() - t0
                    t0 = time.perf_counter()
                    robustness_study(*small, scheduler=client, **small_kw)
                    warm = time.perf_counter() - t0
                    w0, c0, t0 = sum(client.run(_worker_cpu).values()), _cpu(), time.perf_counter()
                    tables.append(robustness_study(meshes, RESAMPLINGS, out=f"{tmp}/{len(tables)}", scheduler=client,
                                                   **kw))
                    t = time.perf_counter() - t0
                    run = (t, sum(client.run(_worker_cpu).values()) - w0 + _cpu() - c0, start, warm)
                    client.close()
                    cluster.close()
                if label not in best or run[0] < best[label][0]:
                    best[label] = run
    same = all(t.equals(tables[0]) for t in tables[1:])
    t_seq = best["sequential"][0]
    print(f"{tasks} tasks ({len(meshes)} meshes x {len(RESAMPLINGS)} resamplings, {args.faces} faces, k={args.k}); "
          f"fastest of {args.repeat}\n")
    print("| run | wall s | CPU s | speed-up | overhead per task | cluster start + workers' warm-up | "
          "speed-up, start-up counted |\n|---|---|---|---|---|---|---|")
    for label in labels:
        t, c, start, warm = best[label]
        if label == "sequential":
            print(f"| {label} | {t:.1f} | {c:.1f} | 1.00x | | | |")
            continue
        print(f"| {label} | {t:.1f} | {c:.1f} | {t_seq / t:.2f}x | {(t - t_seq / args.workers) / tasks:+.2f} s | "
              f"{start:.1f} + {warm:.1f} s | {t_seq / (t + start + warm):.2f}x |")
    print(f"\ntables identical: {same}; failed tasks: {sum(int((t['error'] != '').sum()) for t in tables)}")
    for i, t in enumerate(tables[1:], 1):  # what differs, to find out why
        if not t.equals(tables[0]):
            diff = t.ne(tables[0]) & ~(t.isna() & tables[0].isna())
            rows = diff.any(axis=1)
            print(f"run {i} differs from run 0 in {int(rows.sum())} rows, columns "
                  f"{[c for c in t.columns if diff[c].any()]}:\n{t[rows].head(5).to_string()}\n"
                  f"{tables[0][rows].head(5).to_string()}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
