#!/usr/bin/env python
"""Benchmark: a chain over many files, sequentially and on a local Dask cluster of 2 workers.

Writes ``--files`` different meshes of about ``--vertices`` vertices (deformed spheres) and runs
``scalar height -> heat_smooth k=100 -> colorize`` on them with :func:`o3dheat.pipelines.batch.run`, in this
process (all of o3dheat's threads, the files one after the other) and on
:func:`o3dheat.pipelines.cluster.local_cluster` (one single-threaded worker per core, one file per task).
Prints a Markdown table: wall time, CPU time, files per minute and the ratio to the sequential
run, and checks that every run wrote the same files, byte for byte. One-time costs are measured
apart: the sequential run follows a one-file batch that imports everything; the cluster is started
(``cluster start``) and its workers then run a one-file batch (``workers' warm-up``: imports, first
calls); the last column counts both. Runs alternate and the fastest of ``--repeat`` is shown; the
machine should be otherwise idle.

    .venv/bin/python scripts/bench_batch.py
    .venv/bin/python scripts/bench_batch.py --files 32 --vertices 50000 -k 100 --repeat 3
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_study import _cpu, _worker_cpu  # noqa: E402  (CPU seconds here and in a worker)


def _meshes(folder, files, vertices):
    import numpy as np
    import open3d as o3d

    from o3dheat.io import write_mesh

    res = max(4, int(round((vertices / 2) ** 0.5)))  # create_sphere: 2 res (res - 1) + 2 vertices
    for i in range(files):  # every file different: no spectrum is shared between files
        m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, res)
        V = m.vertex.positions.numpy().astype(np.float64)
        rng = np.random.default_rng(i)
        V = V * rng.uniform(0.6, 1.4, 3) + 0.05 * np.sin(rng.uniform(2, 5) * V[:, [1, 2, 0]])
        m.vertex.positions = o3d.core.Tensor(V)
        write_mesh(Path(folder) / f"scan{i:03d}.ply", m)
    return len(V)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--files", type=int, default=16, help="meshes (default: %(default)s)")
    ap.add_argument("--vertices", type=int, default=20000, help="vertices per mesh, about (default: %(default)s)")
    ap.add_argument("-k", type=int, default=100, help="eigenpairs of heat_smooth (default: %(default)s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each kind; the fastest is shown")
    args = ap.parse_args(argv)

    from distributed import Client

    from o3dheat.parallel import get_threads
    from o3dheat.pipelines.batch import run
    from o3dheat.pipelines.cluster import local_cluster
    from o3dheat.pipelines.filters import Chain

    chain = Chain([("scalar", {"kind": "height"}), ("heat_smooth", {"attribute": "height", "k": args.k}),
                   ("colorize", {"attribute": "height_smooth", "column": 4})])
    best, ok = {}, True
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "in").mkdir()
        (tmp / "warm").mkdir()
        n = _meshes(tmp / "in", args.files, args.vertices)
        _meshes(tmp / "warm", 1, 2000)
        pattern = str(tmp / "in" / "*.ply")
        run(chain, tmp / "warm" / "*.ply", tmp / "warm-seq", scheduler="sequential", progress=False)
        for i in range(args.repeat):
            c0, t0 = _cpu(), time.perf_counter()
            seq = run(chain, pattern, tmp / f"seq{i}", scheduler="sequential", progress=False)
            result = (time.perf_counter() - t0, _cpu() - c0, 0.0, 0.0, seq["seconds"].mean())
            ok &= bool((seq["status"] == "done").all())
            best["seq"] = min(best.get("seq", result), result)

            t0 = time.perf_counter()
            cluster = local_cluster(args.workers)
            client = Client(cluster)
            start = time.perf_counter() - t0
            t0 = time.perf_counter()
            run(chain, tmp / "warm" / "*.ply", tmp / f"warm-dask{i}", scheduler=client, progress=False)
            client.run(lambda: __import__("o3dheat.pipelines.batch"))  # every worker, not only the one that ran it
            warm = time.perf_counter() - t0
            w0, c0, t0 = sum(client.run(_worker_cpu).values()), _cpu(), time.perf_counter()
            dist = run(chain, pattern, tmp / f"dask{i}", scheduler=client, progress=False)
            t = time.perf_counter() - t0
            result = (t, sum(client.run(_worker_cpu).values()) - w0 + _cpu() - c0, start, warm, dist["seconds"].mean())
            client.close()
            cluster.close()
            ok &= bool((dist["status"] == "done").all())
            best["dask"] = min(best.get("dask", result), result)
            for p in (tmp / "seq0").glob("*.ply"):
                ok &= p.read_bytes() == (tmp / f"dask{i}" / p.name).read_bytes()
                ok &= p.read_bytes() == (tmp / f"seq{i}" / p.name).read_bytes()
        ok &= len(list((tmp / "seq0").glob("*.ply"))) == args.files
    t_seq = best["seq"][0]
    print(f"{args.files} meshes of {n} vertices; chain: scalar height -> heat_smooth k={args.k} -> colorize; "
          f"fastest of {args.repeat}\n")
    print("| run | wall s | CPU s | s per file | files / min | ratio | cluster start + workers' warm-up | "
          "ratio, start-up counted |\n|---|---|---|---|---|---|---|---|")
    t, c, _, _, per = best["seq"]
    print(f"| sequential ({get_threads()} o3dheat threads) | {t:.1f} | {c:.1f} | {per:.2f} | "
          f"{60 * args.files / t:.0f} | 1.00x | | |")
    t, c, start, warm, per = best["dask"]
    print(f"| Dask, {args.workers} single-threaded workers | {t:.1f} | {c:.1f} | {per:.2f} | "
          f"{60 * args.files / t:.0f} | {t_seq / t:.2f}x | {start:.1f} + {warm:.1f} s | "
          f"{t_seq / (t + start + warm):.2f}x |")
    print(f"\nall files done, outputs identical byte for byte in every run: {ok}")
    return 0 if ok else 1

if __name__ == "__main__":
    sys.exit(main())
