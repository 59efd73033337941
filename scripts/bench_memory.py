#!/usr/bin/env python
"""Measurement: the peak memory of o3dheat's large steps against the pre-flight estimates with
which it refuses work (issue 35: "memory that is measured, not feared").

Meshes: the bunny of scripts/bench_spectrum.py (curvature-adaptive: decimated by quadrics, strongly
non-uniform) and its torus (uniform), at 250k, 1M, 2M and 4M vertices, made once and kept as .npz
(and .ply for the page) in ``--dir`` (making the 4M bunny takes about 2 minutes). Stages:

* ``factor``: the Cholesky factor of ``A = W + γL`` (consistent mass, γ = 1e-3: the pattern
  matters, not the values), ``CholmodFactor(library(), A, "supernodal", analysis=a)`` after
  ``a = linalg.analyze(A, mode="supernodal")``; estimate ``a.nbytes`` (from the analysis' xsize),
  also CHOLMOD's own peak count ``f.peak_bytes`` and the final ``f.nbytes``;
* ``eigensolve``: ``o3dheat.eigensolve((V, F), k=100)``; estimate ``memory.peak_memory(n, 100)``;
* ``heat``: ``flow.apply(f, t)`` of ``flow = o3dheat.HeatFlow((V, F))``, made before the
  measurement (apply's check sees the memory left after it: what the flow holds is shown
  apart, "flow holds"), f the height along the longest axis plus noise of
  0.1 x its range (seed 0; c fields: seeds 0..c-1, as scripts/bench_heat.py), t the paper's grid
  (10 times) or paper + log grid (20), computed once per kind from its 250k mesh (``HeatKernel(
  eigensolve(k=100)).scales(10)``, ``grid="log"``) and used at every size; at 1M also 8 and 32
  fields. Estimate: the sum of its parts, the result ``8 n c T``, the factor's ``a.nbytes`` (of the
  analysis the flow made) and the stored basis ``8 n c s`` (s: the most steps of a column in one shift
  group, recorded by wrapping ``heatflow.propagate``); o3dheat's own check (``2 x 8 n c T``) shown;
* ``decimate``: ``sampling.decimate((V, F), target_faces=400_000)`` (the page's default; with and
  without the vertex map, the page's call having none); estimate ``sampling.decimate_bytes``;
  above 1M faces it runs in a forked child: measured is then the child's peak resident size
  (``RUSAGE_CHILDREN``) less this process' resident size before (the pages they share);
* ``page``: the command ``o3dheat view MESH.ply -o page.html --overwrite --times a+b+c`` (the
  first and last paper times and the last log time: no eigensolve) under ``/usr/bin/time -v``:
  its maximum resident set size less that of ``python -c "import o3dheat, open3d"``.

Every case runs alone in a fresh subprocess under an address-space limit (``--cap-gib``, 20 GiB:
``RLIMIT_AS``, which o3dheat's estimates see as ``memory_limits()["address space"]``). A Python
case loads its mesh, imports everything and warms up untimed (heat_flow, eigensolve and decimate on
small spheres: numba's cached loops, CHOLMOD, SciPy's lazy modules), then the stage runs: its peak
is the resident set size sampled every 10 ms (``bench_spectrum.PeakMemory``) and the kernel's
high-water mark (``ru_maxrss``, reset to the resident size at the start by writing 5 to
``/proc/self/clear_refs``: no spike missed), each less the resident size at the start; "measured"
is the larger. A stage at 4M vertices that would run longer than its budget (from the 2M time) is
skipped and said so. Failures (an exception, a refusal by o3dheat's estimate, a kill) are printed
with their message; the run goes on. Every result is also appended to ``DIR/results.jsonl``, with
the o3dheat commit it measured (``+edits``: files changed since).

    .venv/bin/python scripts/bench_memory.py                               # everything: about an hour
    .venv/bin/python scripts/bench_memory.py --sizes 250000 --stages factor,heat
    .venv/bin/python scripts/bench_memory.py --kinds torus --sizes 250000,1000000 --stages page

Prints Markdown tables: per stage, rows = kind x size, estimate / measured (higher = safer; the
aim is 1.00..1.25).
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_heat import make_fields  # noqa: E402
from bench_spectrum import PeakMemory, bunny, torus  # noqa: E402

STAGES = ["factor", "eigensolve", "heat", "decimate", "page"]
KINDS = ["bunny", "torus"]
SIZES = [250_000, 1_000_000, 2_000_000, 4_000_000]
TIMES_SIZE = 250_000  # the mesh whose spectrum defines the times of its kind
GAMMA = 1e-3  # the factor's shift (W + γL: any γ > 0 has the same pattern)
MAX_FACES = 400_000  # the page's default decimation
ALWAYS = 2_000_000  # sizes above this run only within their stage's budget
BUDGETS = {"eigensolve": 480.0, "page": 600.0}  # seconds, for sizes above ALWAYS
MiB = 2**20


class StagePeak(PeakMemory):
    """:class:`PeakMemory`, with the kernel's high-water mark reset to the resident size first:
    ``stop()`` returns ``(sampled, maxrss)``, both above the resident size at the start (bytes)."""

    def __init__(self):
        try:
            Path("/proc/self/clear_refs").write_text("5")  # VmHWM (ru_maxrss) := VmRSS
            self.reset = True
        except OSError:
            self.reset = False
        super().__init__()

    def stop(self):
        sampled = super().stop()
        return sampled, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - self._base


def status(field):
    """A field of /proc/self/status, in bytes."""
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def warm_up(c=1, T=10):
    """Untimed: CHOLMOD, numba's cached loops and SciPy's lazy modules, on small spheres."""
    import open3d as o3d

    import o3dheat
    from o3dheat.geometry.sampling import decimate
    from o3dheat.spectral.cache import clear_cache
    from o3dheat.spectral.linalg import available_backends

    available_backends()
    small = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 16)
    fs = make_fields(small.vertex.positions.numpy().astype(np.float64), c)
    o3dheat.heat_flow(small, fs[:, 0] if c == 1 else fs, np.geomspace(1e-3, 1.0, T))
    larger = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 60)  # 3.5k vertices: the Lanczos path
    o3dheat.eigensolve(larger, k=100)
    decimate(larger, target_faces=1000)
    decimate(larger, target_faces=1000, vertex_map=False)
    clear_cache()


def child(job):
    """One case, in this fresh process; prints one JSON line."""
    kind, size, path = job.get("kind"), job.get("size"), job.get("path")
    if job["job"] == "make":  # the mesh, and its PLY
        V, F = (bunny if kind == "bunny" else torus)(size)
        np.savez(path, V=V, F=F)
        print(json.dumps({"n": len(V), "faces": len(F)}))
        return
    z = np.load(path)
    V, F = z["V"], z["F"]
    import gc

    import o3dheat

    if job["job"] == "ply":
        import open3d as o3d

        m = o3d.t.geometry.TriangleMesh()
        m.vertex.positions = o3d.core.Tensor(V)
        m.triangle.indices = o3d.core.Tensor(F)
        o3dheat.io.write_mesh(job["ply"], m)
        return
    if job["job"] == "times":
        K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=100))
        np.savez(job["out"], paper=K.scales(10), log=K.scales(10, grid="log"))
        return
    from o3dheat.memory import memory_limits

    n, stage = len(V), job["job"]
    c = job.get("fields", 1)
    res = {"n": n, "faces": len(F)}
    if stage == "heat":
        tz = np.load(job["times"])
        t = tz["paper"] if job["grid"] == "paper" else np.concatenate([tz["paper"], tz["log"]])
        f = np.ascontiguousarray(make_fields(V, c)[:, 0] if c == 1 else make_fields(V, c))
        warm_up(c, len(t))
    else:
        warm_up()
    if stage == "factor":
        import scipy.sparse as sp

        import o3dheat.spectral._cholmod as ch
        import o3dheat.spectral.linalg as la
        from o3dheat.spectral import fem

        L, W, _ = fem.operators(V, F, "consistent")
        A = sp.csc_matrix(W + GAMMA * L)
        del L, W
        a = la.analyze(A, mode="supernodal")
        res |= {"estimate": a.nbytes, "lnz": a.lnz, "flops": a.flops, "wide": a.wide,
                "xsize": int(ch._field(a.handle, "factor.xsize").value), "nnz_A": A.nnz}
        lib = ch.library()
    elif stage == "eigensolve":
        from o3dheat.memory import peak_memory

        res["estimate"] = peak_memory(n, 100)
        if job.get("factor") and "factor" in inspect.signature(peak_memory).parameters:  # given the analysis
            res["estimate_factor"] = peak_memory(n, 100, factor=job["factor"])
    elif stage == "heat":
        import o3dheat.spectral.heatflow as hf

        groups, propagate = [], hf.propagate

        def recording(*args, **kw):  # each shift group's steps and basis budget
            U, info = propagate(*args, **kw)
            groups.append({"times": len(args[3]), "max_steps": int(info.steps.max()),
                           "sum_steps": int(info.steps.sum()), "budget": kw.get("basis_bytes"),
                           "replayed": int(getattr(info, "replayed", 0))})
            return U, info

        class Recording(hf.Shifted):  # the analysis and factor the flow made (its ordering, its size)
            def __init__(self, ops, gamma, backend):
                super().__init__(ops, gamma, backend)
                a = ops.analysis
                factors.append({"estimate": a.nbytes, "lnz": a.lnz, "ordering": getattr(a, "ordering", ""),
                                "final": self.nbytes} if a is not None else {"final": self.nbytes})

        factors, checks = [], []
        hf.propagate, hf.Shifted = recording, Recording
        if hasattr(hf.HeatFlow, "peak_bytes"):  # o3dheat's own estimate, as apply() computes it for its check
            peak_bytes = hf.HeatFlow.peak_bytes

            def checked(self, *args, **kw):  # the expected peak (apply checks the least, least=True)
                checks.append(peak_bytes(self, *args))
                return peak_bytes(self, *args, **kw)

            hf.HeatFlow.peak_bytes = checked
        res |= {"T": len(t), "fields": c, "factors": factors}
        gc.collect()
        before = status("VmRSS")
        flow = o3dheat.HeatFlow((V, F))  # its operators and analysis: held before apply's check
        res["flow_held"] = status("VmRSS") - before
    gc.collect()
    res |= {"base_rss": status("VmRSS"), "base_vm": status("VmSize"), "room": memory_limits()}
    peak = StagePeak()
    t0 = time.perf_counter()
    if stage == "factor":
        fac = ch.CholmodFactor(lib, A, "supernodal", analysis=a)
        res |= {"cholmod_peak": fac.peak_bytes, "final": fac.nbytes}
    elif stage == "eigensolve":
        s = o3dheat.eigensolve((V, F), k=100)
        res |= {"backend": s.backend, "timings": s.timings}
    elif stage == "heat":
        out, rep = flow.apply(f, t, return_report=True)
        res |= {"solves": int(rep.solves), "steps": int(rep.steps.max()), "shifts": len(rep.shifts),
                "groups": groups, "timings": rep.timings, "backend": rep.backend}
    elif stage == "decimate":
        from o3dheat.geometry.sampling import decimate

        r = decimate((V, F), target_faces=MAX_FACES, vertex_map=job["vertex_map"])
        res["out_faces"] = len(r.F)
    seconds = time.perf_counter() - t0
    sampled, maxrss = peak.stop()
    res |= {"seconds": seconds, "sampled": sampled, "maxrss": maxrss if peak.reset else None,
            "measured": max(sampled, maxrss if peak.reset else 0), "vm_peak": status("VmPeak")}
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    if child:  # a large decimation runs in a forked child: its peak less what it shares with this process
        res["child"] = child - res["base_rss"]
        res["measured"] = max(res["measured"], res["child"])
    if stage == "factor":
        res["ordering"] = getattr(a, "ordering", "")
    if stage == "heat" and checks:
        res["peak_bytes"] = checks[0]
    print(json.dumps(res))


def code_version():
    """The commit of the o3dheat measured, "+edits" when its files differ from it."""
    repo = Path(__file__).resolve().parents[1]
    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(repo), "status", "--porcelain", "o3dheat"], capture_output=True,
                               text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+edits" if dirty else "")


def limit(cap):
    """preexec_fn: the address-space limit of the child."""
    return lambda: resource.setrlimit(resource.RLIMIT_AS, (cap, cap))


def run(cmd, cap, timeout=None):
    """``(returncode, stdout, stderr, seconds)`` of ``cmd`` in a session of its own under the cap;
    past ``timeout`` its whole process group is killed (returncode None)."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=limit(cap))
    try:
        out, err = p.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        out, err = p.communicate()
        return None, out, err, time.perf_counter() - t0
    return p.returncode, out, err, time.perf_counter() - t0


def failure(rc, err, seconds):
    """The message of a failed child: its exception's last line, or the signal that killed it."""
    if rc is None:
        return f"stopped after {seconds:.0f} s (over budget)"
    lines = [s for s in err.splitlines() if s.strip() and not s.startswith("\t")]
    lines = [s for s in lines if not s.startswith("Command exited")]
    msg = lines[-1].strip() if lines else "no message"
    if rc < 0:
        msg = f"killed by {signal.Signals(-rc).name}" + (f" (last line: {msg})" if lines else "")
    return msg


def py_job(job, cap, timeout=None):
    """A Python child's JSON result, or ``{"error": message}``."""
    rc, out, err, seconds = run([sys.executable, __file__, "--child", json.dumps(job)], cap, timeout)
    if rc != 0:
        return {"error": failure(rc, err, seconds), "wall": seconds}
    lines = out.strip().splitlines()
    return (json.loads(lines[-1]) if lines else {}) | {"wall": seconds}


def time_v(cmd, cap, timeout=None):
    """``/usr/bin/time -v cmd``: (maximum resident set size in bytes, seconds) or ``{"error": ...}``."""
    rc, _, err, seconds = run(["/usr/bin/time", "-v", *cmd], cap, timeout)
    if rc != 0:
        return {"error": failure(rc, err, seconds), "wall": seconds}
    kb = next(int(s.split(":")[-1]) for s in err.splitlines() if "Maximum resident set size" in s)
    return {"maxrss": kb * 1024, "wall": seconds}


def mib(b):
    return "" if b is None else f"{b / MiB:.0f}"


def ratio(a, b):
    return f"{a / b:.2f}" if a and b else ""


def predicted(results, stage, kind, size):
    """Seconds a case would take, from the same kind's largest smaller size (linear in n, +10%)."""
    done = [(s, r["wall"]) for (st, k, s, *_), r in results.items()
            if st == stage and k == kind and s < size and "error" not in r]
    if not done:
        return None
    s, w = max(done)
    return 1.1 * w * size / s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default=",".join(map(str, SIZES)))
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--stages", default=",".join(STAGES))
    ap.add_argument("--dir", default=str(Path(tempfile.gettempdir()) / "memcal"), help="meshes, times, results.jsonl")
    ap.add_argument("--cap-gib", type=float, default=20.0, help="address-space limit of every case (GiB)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(json.loads(args.child))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    kinds, stages = args.kinds.split(","), args.stages.split(",")
    if bad := (set(stages) - set(STAGES)) | (set(kinds) - set(KINDS)):
        sys.exit(f"unknown stage or kind: {', '.join(sorted(bad))}")
    cap = int(args.cap_gib * 2**30)
    home = Path(args.dir)
    home.mkdir(parents=True, exist_ok=True)
    log = home / "results.jsonl"
    wall0 = time.perf_counter()
    version = code_version()

    def say(text):
        print(f"[{time.perf_counter() - wall0:6.0f} s] {text}", file=sys.stderr, flush=True)

    def mesh(kind, size, ply=False):
        path = home / f"{kind}-{size}.npz"
        if not path.exists():
            say(f"making {path.name}")
            r = py_job({"job": "make", "kind": kind, "size": size, "path": str(path)}, cap)
            if "error" in r:
                sys.exit(f"making {path.name} failed: {r['error']}")
        if ply and not path.with_suffix(".ply").exists():
            say(f"writing {path.stem}.ply")
            r = py_job({"job": "ply", "path": str(path), "ply": str(path.with_suffix(".ply"))}, cap)
            if "error" in r:
                sys.exit(f"writing {path.stem}.ply failed: {r['error']}")
        return path

    def times(kind):
        out = home / f"times-{kind}.npz"
        if not out.exists():
            say(f"times of {kind} (eigensolve k=100 at {TIMES_SIZE})")
            r = py_job({"job": "times", "path": str(mesh(kind, TIMES_SIZE)), "out": str(out)}, cap)
            if "error" in r:
                sys.exit(f"the times of {kind} failed: {r['error']}")
        return out

    for kind in kinds:
        for size in sizes:
            mesh(kind, size, ply="page" in stages)
        if "heat" in stages or "page" in stages:
            times(kind)

    results = {}

    def record(key, r):
        results[key] = r
        with open(log, "a") as fh:
            fh.write(json.dumps({"key": key, "cap": cap, "code": code_version(),
                                "date": time.strftime("%Y-%m-%d %H:%M")} | r) + "\n")
        say(f"{key}: " + (r["error"] if "error" in r else f"measured {mib(r.get('measured'))} MiB, {r['wall']:.0f} s"))

    def skip(stage, kind, size):
        if size <= ALWAYS or stage not in BUDGETS:
            return None
        p = predicted(results, stage, kind, size)
        if p is not None and p > BUDGETS[stage]:
            return f"skipped: would take about {p:.0f} s (> {BUDGETS[stage]:.0f} s budget, from the smaller size)"
        return None

    def factor_estimate(kind, size):
        """a.nbytes of this mesh: from this run's factor stage, else from an earlier run's log."""
        r = results.get(("factor", kind, size))
        if r and "estimate" in r:
            return r["estimate"]
        if log.exists():
            for line in log.read_text().splitlines()[::-1]:
                e = json.loads(line)
                if e["key"][:3] == ["factor", kind, size] and "estimate" in e:
                    return e["estimate"]
        return None

    bare = None
    for stage in stages:
        if stage == "page":
            runs = [time_v([sys.executable, "-c", "import o3dheat, open3d"], cap) for _ in range(3)]
            bare = sorted(r["maxrss"] for r in runs)[1]
            say(f"bare python -c 'import o3dheat, open3d': {mib(bare)} MiB (median of 3)")
        for kind in kinds:
            for size in sizes:
                path = mesh(kind, size)
                if stage == "heat":
                    more = [("paper", 8), ("paper", 32)] if size == 1_000_000 else []
                    for grid, c in [("paper", 1), ("paper+log", 1), *more]:
                        job = {"job": "heat", "path": str(path), "times": str(times(kind)), "grid": grid, "fields": c}
                        r = py_job(job, cap) | {"factor_estimate": factor_estimate(kind, size)}
                        record((stage, kind, size, grid, c), r)
                elif stage == "decimate":
                    for vmap in (True, False):
                        job = {"job": stage, "path": str(path), "vertex_map": vmap}
                        record((stage, kind, size, vmap), py_job(job, cap))
                elif stage == "page":
                    why = skip(stage, kind, size)
                    if why:
                        record((stage, kind, size), {"error": why, "wall": 0.0})
                        continue
                    tz = np.load(times(kind))
                    t = "+".join(repr(float(x)) for x in (tz["paper"][0], tz["paper"][-1], tz["log"][-1]))
                    z = np.load(path)
                    cmd = [str(Path(sys.executable).parent / "o3dheat"), "view", str(path.with_suffix(".ply")),
                           "-o", str(home / "page.html"), "--overwrite", "--times", t]
                    r = time_v(cmd, cap, BUDGETS["page"] if size > ALWAYS else None)
                    if "maxrss" in r:
                        r["measured"] = r["maxrss"] - bare
                    record((stage, kind, size), r | {"n": len(z["V"]), "faces": len(z["F"]), "times": t, "bare": bare})
                else:
                    why = skip(stage, kind, size)
                    job = {"job": stage, "path": str(path), "factor": factor_estimate(kind, size)}
                    r = {"error": why, "wall": 0.0} if why else py_job(job, cap)
                    record((stage, kind, size), r)
        tables(stage, results)
    ram = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE") / 2**30
    print(f"\nmachine: {os.cpu_count()} cores, {ram:.0f} GiB; "
          f"address-space limit {args.cap_gib:g} GiB per case; python {sys.version.split()[0]}; "
          f"date {time.strftime('%Y-%m-%d')}; whole run {time.perf_counter() - wall0:.0f} s; o3dheat {version}")
    if code_version() != version:
        print(f"\n**o3dheat changed during the run** ({version} -> {code_version()}): the cases measured "
              "different code (each line of DIR/results.jsonl says which)")


def tables(stage, results):
    """The Markdown table of one stage, then its failures with their full messages."""
    rows = [(k, r) for k, r in results.items() if k[0] == stage]
    fails = [(k, r["error"]) for k, r in rows if "error" in r]
    head = {
        "factor": "| mesh | n | faces | lnz (ordering) | xsize | flops | estimate a.nbytes MiB | "
                  "measured MiB (sampled / maxrss) | estimate / measured | CHOLMOD peak MiB | CHOLMOD / measured | "
                  "final f.nbytes MiB | s |",
        "eigensolve": "| mesh | n | estimate peak_memory(n, 100) MiB | measured MiB (sampled / maxrss) | "
                      "estimate / measured | peak_memory(n, 100, factor=a.nbytes) MiB | its ratio | "
                      "s (factorize + solve) |",
        "heat": "| mesh | n | grid | T | c | estimate: result + factor + basis MiB | measured MiB (sampled / maxrss) | "
                "estimate / measured | HeatFlow.peak_bytes MiB | its ratio | result 8ncT MiB | factor a.nbytes MiB | "
                "basis 8nc·steps MiB | 2·8ncT MiB | solves | steps (max per group) | basis budget MiB | replayed | "
                "flow holds B/vertex | s |",
        "decimate": "| mesh | n | faces | vertex_map | decimate_bytes MiB | measured MiB (sampled / maxrss) | "
                    "estimate / measured | bytes / input face | faces out | s |",
        "page": "| mesh | n | faces | max RSS MiB | measured: max RSS - bare MiB | bytes / vertex | bytes / face | "
                "wall s |",
    }[stage]
    print(f"\n### {stage}\n")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for k, r in rows:
        kind, size = k[1], k[2]
        if "error" in r:
            lead = (f" {k[3]} | {10 if k[3] == 'paper' else 20} | {k[4]} |" if stage == "heat"
                    else f" {k[3]} |" if stage == "decimate" else "")
            print(f"| {kind} | {size} |{lead} {r['error'][:120]} |")
            continue
        n, m = r["n"], r.get("measured")
        both = f"{mib(m)} ({mib(r.get('sampled'))} / {mib(r.get('maxrss'))})"
        if stage == "factor":
            print(f"| {kind} | {n} | {r['faces']} | {r['lnz']} ({r.get('ordering', '')}) | {r['xsize']} | "
                  f"{r['flops']:.3g} | {mib(r['estimate'])} | {both} | {ratio(r['estimate'], m)} | "
                  f"{mib(r['cholmod_peak'])} | "
                  f"{ratio(r['cholmod_peak'], m)} | {mib(r['final'])} | {r['seconds']:.1f} |")
        elif stage == "eigensolve":
            tm = r["timings"]
            ef = r.get("estimate_factor")
            print(f"| {kind} | {n} | {mib(r['estimate'])} | {both} | {ratio(r['estimate'], m)} | {mib(ef)} | "
                  f"{ratio(ef, m)} | {r['seconds']:.1f} ({tm.get('factorize', 0):.1f} + {tm.get('solve', 0):.1f}) |")
        elif stage == "heat":
            c, T = r["fields"], r["T"]
            result = 8 * n * c * T
            steps = max(g["max_steps"] for g in r["groups"])
            basis = 8 * n * c * steps
            fe = (r.get("factors") or [{}])[0].get("estimate", r.get("factor_estimate"))
            est = result + basis + (fe or 0)
            budgets = [g["budget"] for g in r["groups"] if g["budget"] is not None]
            per = ", ".join(str(g["max_steps"]) for g in r["groups"])
            pb = r.get("peak_bytes")
            print(f"| {kind} | {n} | {k[3]} | {T} | {c} | {mib(est)} | {both} | {ratio(est, m)} | {mib(pb)} | "
                  f"{ratio(pb, m)} | {mib(result)} | "
                  f"{mib(fe)} | {mib(basis)} | {mib(2 * result)} | {r['solves']} | {steps} ({per}) | "
                  f"{mib(min(budgets)) if budgets else ''} | {sum(g['replayed'] for g in r['groups'])} | "
                  f"{r.get('flow_held', 0) / n:.0f} | {r['seconds']:.1f} |")
        elif stage == "decimate":
            from o3dheat.geometry.sampling import decimate_bytes

            est = decimate_bytes(r["faces"], k[3])
            print(f"| {kind} | {n} | {r['faces']} | {k[3]} | {mib(est)} | {both} | {ratio(est, m)} | "
                  f"{m / r['faces']:.0f} | {r['out_faces']} | {r['seconds']:.1f} |")
        else:
            print(f"| {kind} | {n} | {r['faces']} | {mib(r['maxrss'])} | {mib(m)} | {m / n:.0f} | "
                  f"{m / r['faces']:.0f} | {r['wall']:.1f} |")
    if fails:
        print("\nFailures and skips (full messages):\n")
        for k, e in fails:
            print(f"- {' / '.join(map(str, k))}: {e}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
