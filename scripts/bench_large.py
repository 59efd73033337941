#!/usr/bin/env python
"""Benchmark: full-size scans end to end on one machine (10M vertices by default), each stage's
time and memory.

Meshes, made here (each in its own process, which then runs every stage):

* ``scan``: the embedded bunny, Loop-subdivided once, quadric-decimated to ``n / 4^s`` vertices
  (an adaptive sampling), Loop-subdivided ``s`` times to about ``n`` vertices, and displaced
  along the normals by Gaussian noise of 0.2 mean edge lengths (seed 0): a scan's roughness at
  its sampling scale;
* ``ellipsoid``: an ellipsoid of axes 1, 0.8, 0.6 sampled uniformly (a cube's faces as grids of
  equal angles, projected); ``torus``: a torus sampled uniformly (``scripts/bench_spectrum.torus``),
  whose factor has about twice the fill.

Stages, in processes of their own (the parent holds no mesh): make the mesh and write it to a
binary PLY (set-up, not counted in the total); then in one process: read it back
(``o3dheat.io.read_mesh``), the scales (λ_2 and λ_100 of a copy decimated to
``o3dheat.visualization.scene.GRID_FACES`` faces, as ``o3dheat view`` gets them: the mesh's own
eigensolve would not fit), the HeatFlow (operators and symbolic analysis), ``heat_flow`` of the
noisy height (0.1 of its range, seed 0) on the paper's 10 scales and on 20 log scales (with
``HeatFlow.peak_bytes``, the estimate it checks), critical points at every one of the 30 scales,
the tracks of both grids; then the commands ``o3dheat view`` (defaults: it decimates the page,
says so, and computes its own flow and scales) and ``o3dheat figure``; last the k = 100
eigensolve (refused up front with its estimate, or run). For each stage: seconds, the largest
resident set size during it (sampled every 20 ms) and the resident size at its start (what the
process already held); for the commands, their own peak (``wait4``'s ``ru_maxrss``).

    .venv/bin/python scripts/bench_large.py                       # scan and ellipsoid, 10M vertices
    .venv/bin/python scripts/bench_large.py --sizes 1000000       # a quicker check of the same stages
    .venv/bin/python scripts/bench_large.py --meshes scan --no-eigensolve

Prints a Markdown table per mesh, then one line each: the total time (set-up excluded) and the
process' peak memory. Targets (issue 35): every mesh within 16 GB peak, the whole run within
15 minutes per mesh.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_spectrum import torus  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
O3DHEAT = str(Path(sys.executable).parent / "o3dheat")


def scan(n, seed=0):
    """About n vertices: the bunny subdivided, decimated, subdivided again and displaced (see the module notes)."""
    import fast_simplification
    import open3d as o3d

    from o3dheat.io import default_mesh

    s = 0
    while n / 4**s > 100_000:
        s += 1
    base = default_mesh()[0].to_legacy().subdivide_loop(1)
    V, F = np.asarray(base.vertices), np.asarray(base.triangles, np.int32)
    V, F = fast_simplification.simplify(V, F, target_count=int(2 * n / 4**s))
    leg = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(V, np.float64)),
                                    o3d.utility.Vector3iVector(np.asarray(F, np.int32)))
    if s:
        leg = leg.subdivide_loop(s)
    V, F = np.asarray(leg.vertices, np.float64), np.asarray(leg.triangles, np.int64)
    del leg
    N = np.zeros_like(V)
    cross = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    for k in range(3):
        np.add.at(N, F[:, k], cross)
    N /= np.maximum(np.linalg.norm(N, axis=1), 1e-300)[:, None]
    edge = float(np.mean(np.linalg.norm(V[F[:, 1]] - V[F[:, 0]], axis=1)))
    V += (0.2 * edge * np.random.default_rng(seed).standard_normal(len(V)))[:, None] * N
    return V, F


def ellipsoid(n, axes=(1.0, 0.8, 0.6)):
    """About n vertices, uniformly: the six faces of a cube, each an m x m grid of equal angles,
    projected onto the unit sphere (seams welded), then scaled to the ellipsoid's axes."""
    m = max(2, int(round(np.sqrt((n - 2) / 6))))
    u = np.tan(np.linspace(-np.pi / 4, np.pi / 4, m + 1))
    a, b = np.meshgrid(u, u, indexing="ij")
    a, b, one = a.ravel(), b.ravel(), np.ones((m + 1) ** 2)
    quads = np.arange(m * (m + 1)).reshape(m, m + 1)[:, :m].ravel()  # lower-left corner of each cell
    tri = np.r_[np.c_[quads, quads + m + 1, quads + m + 2], np.c_[quads, quads + m + 2, quads + 1]]
    V, F = [], []
    for k, (x, y, z) in enumerate([(one, a, b), (-one, b, a), (a, one, b), (b, -one, a), (a, b, one), (b, a, -one)]):
        V.append(np.c_[x, y, z])
        F.append(tri + k * len(one))
    V, F = np.concatenate(V), np.concatenate(F)
    V /= np.linalg.norm(V, axis=1)[:, None]
    key = np.round(V * 2**40).astype(np.int64)  # the seams' copies of a point coincide exactly enough
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    V, F = V[first] * np.asarray(axes), inverse.ravel()[F]
    return V, F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]


class Stages:
    """Each stage's seconds and peak resident memory (sampled every 20 ms)."""

    def __init__(self):
        self.rows = []
        self._page = os.sysconf("SC_PAGE_SIZE")
        self._peak = 0
        self._stop = False
        threading.Thread(target=self._sample, daemon=True).start()

    def _rss(self):
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * self._page

    def _sample(self):
        while not self._stop:
            self._peak = max(self._peak, self._rss())
            time.sleep(0.02)

    def run(self, name, fn, *args):
        self._peak = start = self._rss()
        t0 = time.perf_counter()
        try:
            out = fn(*args)
            note = ""
        except Exception as e:  # noqa: BLE001 - a refusal or a failure is a result of the benchmark
            out, note = None, f"{type(e).__name__}: {e}"
        seconds = time.perf_counter() - t0
        peak = max(self._peak, self._rss())
        if isinstance(out, dict):  # a command's own numbers
            note, peak = out.get("note", ""), out.get("peak", peak)
        self.rows.append({"stage": name, "s": seconds, "peak": peak, "start": start, "note": note})
        print(f"  {name}: {seconds:.1f} s, peak {peak / 2**30:.2f} GiB {note}", file=sys.stderr, flush=True)
        return out


def command(args):
    """Run an o3dheat command; its own peak memory (ru_maxrss of the child) and the last lines it printed."""
    p = subprocess.Popen([O3DHEAT, *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    out = p.stdout.read()
    _, status, usage = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    lines = [line for line in out.splitlines() if line.strip()]
    said = [line.strip() for line in lines if "decimat" in line or "scales" in line][:3]
    note = f"exit {p.returncode}; " + " | ".join(said or lines[-2:])
    return {"peak": usage.ru_maxrss * 1024, "note": note[:400]}


def make(kind, n, folder):
    """The mesh, written to ``folder/kind.ply`` (a process of its own: its memory is not the stages')."""
    import open3d as o3d

    import o3dheat

    V, F = {"scan": scan, "ellipsoid": ellipsoid, "torus": torus}[kind](n)
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(V)
    mesh.triangle.indices = o3d.core.Tensor(F)
    o3dheat.io.write_mesh(Path(folder) / f"{kind}.ply", mesh, overwrite=True)
    print(json.dumps({"n": len(V), "faces": len(F)}))


def stages(kind, folder):
    """The Python stages on the written mesh, each timed with its peak memory."""
    import o3dheat
    from o3dheat.geometry.sampling import decimate
    from o3dheat.topology import Surface, critical_points, track_critical_points
    from o3dheat.visualization.scene import GRID_FACES

    o3dheat.heat_flow(o3dheat.io.default_mesh()[0], np.arange(28088.0), [1e-3, 1e-2])  # numba's cache, imports
    st = Stages()
    mesh = st.run("read the PLY", o3dheat.io.read_mesh, Path(folder) / f"{kind}.ply")
    V = mesh.vertex.positions.numpy().astype(np.float64)
    F = mesh.triangle.indices.numpy().astype(np.int64)
    mesh = None
    axis = int(np.argmax(np.ptp(V, axis=0)))
    f = V[:, axis] + 0.1 * np.ptp(V[:, axis]) * np.random.default_rng(0).standard_normal(len(V))

    def scales():
        K = o3dheat.HeatKernel(o3dheat.eigensolve(decimate((V, F), target_faces=GRID_FACES, vertex_map=False).arrays,
                                                  k=100))
        return K.scales(10), K.scales(20, grid="log")

    paper, log = st.run(f"scales: λ_2, λ_100 of a {GRID_FACES:,}-face copy", scales)
    flow = st.run("HeatFlow: operators and symbolic analysis", o3dheat.HeatFlow, (V, F))
    info = {}

    def smooth(t, name):
        est = flow.peak_bytes(1, t)
        out, rep = flow.apply(f, t, return_report=True)
        info[name] = (f"{rep.solves} solves, {len(rep.shifts)} shift(s), estimate <= {rep.estimate.max():.1e}; "
                      f"peak_bytes {est / 2**30:.2f} GiB")
        return out

    results = {}
    for name, t, what in (("paper", paper, "the paper's 10 scales"), ("log", log, "20 log scales")):
        results[name] = st.run(f"heat_flow, {what}", smooth, t, name)
        if name in info:
            st.rows[-1]["note"] = info[name]
    flow.release()  # its factors' memory back (the in-memory cache keeps its newest entry), as the page does
    flow = None
    P, G = results["paper"], results["log"]
    if P is None or G is None:
        st.rows.append({"stage": "critical points, tracks", "s": 0.0, "peak": 0, "note": "skipped: no flow"})
    else:
        S = st.run("surface (topology tables)", Surface.from_faces, len(V), F, V)

        def critical():
            from o3dheat import parallel

            cols = [P[:, j] for j in range(P.shape[1])] + [G[:, j] for j in range(G.shape[1])]
            return parallel.run(lambda c: critical_points(S, c), [(c,) for c in cols])

        cps = st.run("critical points at 30 scales", critical)
        st.rows[-1]["note"] = f"first {cps[0].counts}, last {cps[-1].counts}"

        def tracks():
            a = track_critical_points(S, P, paper, critical=tuple(cps[:10]))
            b = track_critical_points(S, G, log, critical=tuple(cps[10:]))
            return f"{len(a):,} + {len(b):,} tracks"

        st.rows[-1]["note"] = st.run("tracks of both grids", tracks) or st.rows[-1]["note"]
    st._stop = True
    print(json.dumps({"rows": st.rows, "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))


def eigensolve(kind, folder):
    """The k = 100 eigensolve of the mesh: refused up front with its estimate, or run."""
    import o3dheat

    mesh = o3dheat.io.read_mesh(Path(folder) / f"{kind}.ply")
    st = Stages()

    def eig():
        s = o3dheat.eigensolve(mesh, k=100)
        return {"note": f"ran: λ_100 = {s.eigenvalues[-1]:.6g}"}

    st.run("eigensolve k = 100", eig)
    st._stop = True
    print(json.dumps({"rows": st.rows, "maxrss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))


def child_process(args):
    """``(json, peak bytes, exit code)`` of ``python bench_large.py --child ARGS`` (wait4's ru_maxrss)."""
    p = subprocess.Popen([sys.executable, __file__, "--child", *args], stdout=subprocess.PIPE, text=True)
    out = p.stdout.read()
    _, status, usage = os.wait4(p.pid, 0)
    lines = [line for line in out.splitlines() if line.startswith("{")]
    return (json.loads(lines[-1]) if lines else None), usage.ru_maxrss * 1024, os.waitstatus_to_exitcode(status)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="10000000", help="vertices, comma-separated (default: 10000000)")
    ap.add_argument("--meshes", default="scan,ellipsoid", help="scan, ellipsoid (uniform), torus (uniform)")
    ap.add_argument("--no-eigensolve", action="store_true", help="skip the k = 100 eigensolve")
    ap.add_argument("--keep", default=None, help="folder for the meshes, pages and figures (default: temporary)")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        what, kind, rest = a.child[0], a.child[1], a.child[2:]
        {"make": lambda: make(kind, int(rest[0]), rest[1]), "stages": lambda: stages(kind, rest[0]),
         "eigensolve": lambda: eigensolve(kind, rest[0])}[what]()
        return
    folder = a.keep or tempfile.mkdtemp(prefix="o3dheat-large-")
    Path(folder).mkdir(parents=True, exist_ok=True)
    for n in [int(s) for s in a.sizes.split(",")]:
        for kind in a.meshes.split(","):
            rows, peaks = [], {}
            t0 = time.perf_counter()
            made, peak, code = child_process(["make", kind, str(n), folder])
            if made is None:
                print(f"\n{kind} at {n:,}: making the mesh failed (exit {code})")
                continue
            rows.append({"stage": "make and write the mesh (set-up, a process)", "s": time.perf_counter() - t0,
                         "peak": peak, "note": ""})
            r, peak, code = child_process(["stages", kind, folder])
            rows += r["rows"] if r else [{"stage": "the Python stages", "s": 0, "peak": peak, "note": f"exit {code}"}]
            peaks["stages"] = peak
            ply = str(Path(folder) / f"{kind}.ply")
            for name, args in (("view", ["view", ply, "-o", str(Path(folder) / f"{kind}.html"), "--overwrite"]),
                               ("figure", ["figure", ply, "-o", str(Path(folder) / f"{kind}-figures"), "--overwrite"])):
                t1 = time.perf_counter()
                out = command(args)
                rows.append({"stage": f"o3dheat {name} (a process)", "s": time.perf_counter() - t1, **out})
                peaks[name] = out["peak"]
            if not a.no_eigensolve:
                r, peak, code = child_process(["eigensolve", kind, folder])
                rows += r["rows"] if r else [{"stage": "eigensolve k = 100", "s": 0, "peak": peak,
                                              "note": f"exit {code}"}]
                peaks["eigensolve"] = peak
            print(f"\n### {kind}: {made['n']:,} vertices, {made['faces']:,} faces\n")
            print("| stage | s | peak GiB | at its start GiB | |\n|---|---|---|---|---|")
            for row in rows:
                start = f"{row['start'] / 2**30:.2f}" if "start" in row else ""
                print(f"| {row['stage']} | {row['s']:.1f} | {row['peak'] / 2**30:.2f} | {start} | {row['note']} |",
                      flush=True)
            total = sum(row["s"] for row in rows[1:])
            print(f"\ntotal (set-up excluded): {total / 60:.1f} min; each process' peak: "
                  + ", ".join(f"{k} {v / 2**30:.2f} GiB" for k, v in peaks.items()))
    print(f"\n(meshes, pages and figures in {folder})")


if __name__ == "__main__":
    main()
