#!/usr/bin/env python
"""Benchmark: the interactive page of a scale space (``o3dheat.view``) and the static figures
(``o3dheat figure``), each against the computations it shows, measured in one run.

Page. Meshes: the bunny of scripts/bench_spectrum.py at each size (20k, 200k, 1M vertices), the
field its height plus noise (0.1 of the range, seed 0), 20 log-spaced times from ``1/λ_100`` to
``2 ln(100)/λ_2`` (computed once per mesh, untimed, and passed to both sides). Timed in this process
from the (V, F) arrays in memory, after a warm-up on a small sphere (numba's cached loops, SciPy's
lazy modules):

* ``heat_flow``: ``o3dheat.heat_flow(mesh, f, t)`` alone — the computation the page shows;
  o3dheat's in-memory caches are cleared before each side (set-up counted on both);
* ``page``: ``o3dheat.view(mesh, f, t).save(path)`` — the same flow, plus the critical points at
  every scale, the tracks, decimation above ``max_faces`` (400k faces: the 1M-vertex mesh is shown
  on a copy of about 200k vertices, its fields transferred) and writing the HTML file.

Each side is run ``--repeat`` times (default 3; 5 times as often below 100k vertices, where a
run takes 0.2 s and the ratio of one run varies from 1.1x to 1.7x), the two interleaved; the table
gives the medians of the times and of the run-by-run ratios (each run's are printed on stderr).
Ratio = page / heat_flow (target: <= 1.5x). Then, in headless Chromium (Debian's ``chromium``,
SwiftShader WebGL, through Playwright, every request outside the page refused): the time from
navigation to ``o3dheat.ready`` (the first frame drawn with the data), and the time of a scale
change (``o3dheat.setScale(i)`` until the next animation frame is drawn), the median of 10 changes
(target: <= 100 ms at 200k vertices).

Figures (``--figures``): ``o3dheat.visualization.figures.paper_figures`` on pymeshlab's bunny.obj
(decimated to 30k faces as the command does), the whole run against its own computations, i.e. the
run less the time spent drawing (plot.fields/tracks, charts, saving PNGs), measured by wrapping
those functions (target: whole <= 4x the computations).

    .venv/bin/python scripts/bench_view.py                       # 20k and 200k vertices, figures
    .venv/bin/python scripts/bench_view.py --sizes 1000000       # minutes
    .venv/bin/python scripts/bench_view.py --no-browser --no-figures

Prints Markdown tables.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_spectrum import bunny  # noqa: E402

CHROMIUM_ARGS = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]


def field_and_times(V, F):
    import o3dheat

    h = V[:, 1]
    f = h + 0.1 * np.ptp(h) * np.random.default_rng(0).standard_normal(len(V))
    t = o3dheat.HeatFlow((V, F)).scales(20, grid="log", k=100)
    return f, t


def warm_up():
    import open3d as o3d

    import o3dheat

    m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)
    z = m.vertex.positions.numpy()[:, 2]
    o3dheat.heat_flow(m, z, [0.01, 0.1])
    # a noisy field over several scales: the tracks' saddle matching (SciPy's assignment) and every
    # compiled loop of the page are loaded here, not in the first timed case
    noisy = z + 0.3 * np.random.default_rng(0).standard_normal(len(z))
    o3dheat.view(m, noisy, np.geomspace(1e-4, 0.1, 6)).html()


def page_case(n, out, repeat):
    import o3dheat
    from o3dheat.spectral.cache import clear_cache

    V, F = bunny(n)
    f, t = field_and_times(V, F)
    path = out / f"bunny_{n}.html"
    flows, pages = [], []
    for _ in range(repeat):  # the two sides interleaved, medians
        clear_cache()  # operators and factors are cached per geometry: set-up counted on both sides
        t0 = time.perf_counter()
        o3dheat.heat_flow((V, F), f, t)
        flows.append(time.perf_counter() - t0)
        clear_cache()
        t0 = time.perf_counter()
        v = o3dheat.view((V, F), f, t, up="y")
        v.save(path, overwrite=True)
        pages.append(time.perf_counter() - t0)
    return {"n": len(V), "shown": len(v.scene.V), "flow": statistics.median(flows), "page": statistics.median(pages),
            "ratio": statistics.median(np.divide(pages, flows)), "ratios": np.divide(pages, flows), "path": path,
            "mb": path.stat().st_size / 2**20}


def browser_times(path, changes=10):
    from playwright.sync_api import sync_playwright

    exe = shutil.which("chromium")
    if exe is None:
        raise SystemExit("no chromium: bash scripts/test.sh installs it (or --no-browser)")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1200, "height": 800})
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(("file:", "data:", "blob:"))
                   else r.abort())
        t0 = time.perf_counter()
        page.goto(path.as_uri())
        page.wait_for_function("window.o3dheat && window.o3dheat.ready", timeout=300_000, polling=10)
        first = time.perf_counter() - t0
        T = page.evaluate("o3dheat.scales.length")
        ms = []
        for i in range(changes):
            ms.append(page.evaluate("""async (i) => {
                const t0 = performance.now();
                o3dheat.setScale(i);
                await new Promise(requestAnimationFrame);
                return performance.now() - t0; }""", (i * 7 + 3) % T))
        browser.close()
    return first, statistics.median(ms)


def figures_case():
    import pymeshlab

    import o3dheat
    from o3dheat.visualization import charts, figures, plot

    src = Path(pymeshlab.__file__).parent / "tests" / "sample_meshes" / "bunny.obj"
    mesh = o3dheat.io.read_mesh(src)
    drawing = [0.0]

    def timed(module, name):
        fn = getattr(module, name)

        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                drawing[0] += time.perf_counter() - t0
        setattr(module, name, wrapper)

    for module, name in ((figures, "_save"), (plot, "fields"), (plot, "tracks"), (charts, "scale_space"),
                         (charts, "lifetime_chart")):
        timed(module, name)
    out = Path(tempfile.mkdtemp())
    t0 = time.perf_counter()
    figures.paper_figures(mesh, out, source=src, tracks=True)
    whole = time.perf_counter() - t0
    shutil.rmtree(out)
    return whole, whole - drawing[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="20000,200000", help="vertices, comma-separated")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each side, interleaved (medians)")
    ap.add_argument("--no-browser", action="store_true")
    ap.add_argument("--no-figures", action="store_true")
    args = ap.parse_args()
    warm_up()
    out = Path(tempfile.mkdtemp())
    rows = []
    for n in (int(s) for s in args.sizes.split(",")):
        r = page_case(n, out, args.repeat * (5 if n < 100_000 else 1))  # small cases: noisier, cheap
        if not args.no_browser:
            r["first"], r["change"] = browser_times(r["path"])
        rows.append(r)
        print(f"  {n}: done; page / flow run by run: {', '.join(f'{x:.2f}' for x in r['ratios'])}", file=sys.stderr)
    print("| vertices | shown | heat_flow s | page s (flow + critical points + tracks + HTML) | page / flow "
          "| HTML MB | first frame s | scale change ms |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        browser = (f"{r['first']:.1f} | {r['change']:.0f}" if "first" in r else "– | –")
        print(f"| {r['n']:,} | {r['shown']:,} | {r['flow']:.1f} | {r['page']:.1f} | {r['ratio']:.2f}x | "
              f"{r['mb']:.1f} | {browser} |")
    shutil.rmtree(out)
    if not args.no_figures:
        whole, compute = figures_case()
        print("\n| o3dheat figure bunny.obj (30k faces) | whole s | computations s | whole / computations |")
        print("|---|---|---|---|")
        print(f"| paper_figures(tracks=True) | {whole:.1f} | {compute:.1f} | {whole / compute:.2f}x |")


if __name__ == "__main__":
    main()
