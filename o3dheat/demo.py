"""The demo behind ``o3dheat demo``: a real scan, irregularly resampled, a noisy field smoothed at
the paper's ten scales (truncated to k eigenpairs, and with the full kernel), heat kernel
signatures, and a PLY with everything attached.

The default mesh is the Stanford Bunny as shipped inside pymeshlab (a required dependency), at
``pymeshlab/tests/sample_meshes/bunny.obj`` -- courtesy of the Stanford 3D Scanning Repository.
When that file is absent a procedural surface (a bumpy torus) is used instead. Nothing is
downloaded.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from o3dheat._jit import any_compiled
from o3dheat.geometry import as_arrays, decimate, height, up_axis
from o3dheat.io import bumpy_torus, default_mesh, write_mesh  # noqa: F401 - bumpy_torus: run's example uses it (d.bumpy_torus)
from o3dheat.pipelines import apply
from o3dheat.spectral import HeatFlow, HeatKernel, eigensolve
from o3dheat.topology import Surface, critical_points
from o3dheat.typing import MeshLike, PathLike

__all__ = ["run"]

log = logging.getLogger("o3dheat")


def run(out: PathLike = "o3dheat-demo/bunny_heat.ply", k: int = 100, reduction: float = 0.6, noise: float = 0.1,
        seed: int = 0, mesh: MeshLike | None = None, echo: Callable[[str], Any] = print) -> dict:
    """Run the demo and write its PLY.

    Parameters
    ----------
    out : str or Path
        Output PLY (folders are created).
    k : int
        Eigenpairs.
    reduction : float
        Fraction of triangles removed by :func:`o3dheat.geometry.sampling.decimate` (quadric decimation
        gives an irregular, curvature-adaptive sampling); 0 keeps the mesh.
    noise : float
        Standard deviation of the Gaussian noise, relative to the range of the height (along the
        up axis of :func:`o3dheat.geometry.up.up_axis`: y for the embedded bunny, an OBJ file; z for
        a ``mesh`` given here).
    seed : int
        Seed of the noise (numpy's ``default_rng``).
    mesh : Open3D mesh, optional
        Use this mesh instead of the embedded one.
    echo : callable
        Where the table goes (``print`` by default).

    Returns
    -------
    dict
        ``path``, ``n_vertices``, ``scales``, ``errors`` (the paper's grid, truncated),
        ``log_scales``, ``errors_log`` (the log grid), ``errors_exact`` (the paper's grid, the full
        kernel), ``critical_points`` (of f, then of Φ_t f on the paper's grid, the log grid and the
        paper's grid exact), ``truncation_bound`` (the paper's grid), ``backend``, ``timings``.

    Examples
    --------
    >>> import os, tempfile, o3dheat.demo as d
    >>> out = d.run(os.path.join(tempfile.mkdtemp(), "t.ply"), k=10, reduction=0.5, mesh=d.bumpy_torus(32, 16),
    ...             echo=lambda line: None)
    >>> out["path"].name, len(out["errors"]), out["critical_points"][0] > 0
    ('t.ply', 10, True)
    """
    import open3d  # noqa: F401 - imported before the clock starts: "load" times reading the mesh, not Open3D

    timings = {}
    t0 = time.perf_counter()
    name, up = "input", up_axis()[0]  # a mesh made in Python: z up
    if mesh is None:
        mesh, name = default_mesh()
        up = up_axis("auto", "bunny.obj" if name == "bunny" else None)[0]  # pymeshlab's OBJ: y up
    V, F = as_arrays(mesh)
    timings["load"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if reduction > 0:
        V, F = decimate((V, F), reduction=reduction).arrays
    timings["resample"] = time.perf_counter() - t0
    spec = eigensolve((V, F), k=min(k, len(V)))
    timings["eigensolve"] = sum(v for key, v in spec.timings.items() if key != "cache")
    r = _smooth(V, F, spec, _noisy_height(V, noise, seed, up), timings)
    t0 = time.perf_counter()
    out = _write(out, V, F, r)
    timings["write"] = time.perf_counter() - t0
    stages = _stages(spec, timings)
    _report(echo, name, V, F, reduction, spec, r)
    echo("seconds per stage: " + ", ".join(f"{key} {v:.2f}" for key, v in stages.items()))
    echo(f"wrote {out} (vertex attributes: f, f_smooth (n,10), f_smooth_log (n,10), f_exact (n,10), hks (n,10) "
         "density form, colors)")
    return {"path": out, "n_vertices": len(V), "scales": r["scales"], "errors": r["errors"],
            "log_scales": r["log_scales"], "errors_log": r["errors_log"], "errors_exact": r["errors_exact"],
            "critical_points": r["counts"], "truncation_bound": r["bound"], "backend": spec.backend,
            "timings": stages}


def _noisy_height(V, noise, seed, up):
    """The height along ``up`` (:mod:`o3dheat.geometry.up`'s rule) plus Gaussian noise (relative to
    its range, seeded)."""
    rng = np.random.default_rng(seed)
    h = height(V, up)
    return h + noise * np.ptp(h) * rng.standard_normal(len(V))


def _smooth(V, F, spec, f, timings):
    """Φ_t f on the paper's grid and the log grid (truncated), the paper's grid exact, the HKS and
    the critical points of every field; the stages' seconds into ``timings``."""
    t0 = time.perf_counter()
    K = HeatKernel(spec)
    scales, log_scales = K.scales(10), K.scales(10, grid="log")
    (smooth, bound), smooth_log = K.smooth(f, scales, return_bound=True), K.smooth(f, log_scales)
    errors, errors_log = K.error(f, scales), K.error(f, log_scales)
    timings["smooth"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    exact, flow_report = HeatFlow((V, F)).apply(f, scales, return_report=True)
    errors_exact = np.abs(exact - f[:, None]).max(axis=0) / np.abs(f).max()
    timings["exact"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    hks = K.hks(scales)
    timings["hks"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    surface = Surface.from_faces(len(V), F)
    fields = [f] + list(smooth.T) + list(smooth_log.T) + list(exact.T)
    counts = [sum(critical_points(surface, g).counts) for g in fields]
    timings["critical"] = time.perf_counter() - t0
    return {"f": f, "scales": scales, "log_scales": log_scales, "smooth": smooth, "bound": bound,
            "smooth_log": smooth_log, "errors": errors, "errors_log": errors_log, "exact": exact,
            "errors_exact": errors_exact, "flow_report": flow_report, "hks": hks, "counts": counts}


def _write(out, V, F, r):
    """The PLY with every field attached and colours of Φ_t f at t5; its path."""
    import open3d as o3d

    result = o3d.t.geometry.TriangleMesh()
    result.vertex.positions = o3d.core.Tensor(V)
    result.triangle.indices = o3d.core.Tensor(F)
    result.vertex["f"] = o3d.core.Tensor(r["f"])
    for key, name in (("smooth", "f_smooth"), ("smooth_log", "f_smooth_log"), ("exact", "f_exact"), ("hks", "hks")):
        result.vertex[name] = o3d.core.Tensor(np.ascontiguousarray(r[key]))
    result = apply(result, "colorize", attribute="f_smooth", column=4)  # Φ_t f at t5, coolwarm
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_mesh(out, result)  # run() is asked for this path: the command keeps earlier results apart
    return out


def _report(echo, name, V, F, reduction, spec, r):
    """The demo's table: the mesh, the spectrum, and per scale the errors and critical points."""
    counts, scales, log_scales, bound = r["counts"], r["scales"], r["log_scales"], r["bound"]
    echo(f"o3dheat demo: {name}, resampled to {len(V)} vertices / {len(F)} faces "
         f"(quadric decimation, reduction {reduction:g})")
    echo(f"eigenpairs: {spec.k}   backend: {spec.backend}   λ_k = {spec.eigenvalues[-1]:.4g}   "
         f"max residual: {spec.residuals.max():.1e}")
    echo(f"noisy field f: {counts[0]} critical points (minima + saddles + maxima, each saddle counted with "
         "its multiplicity)")
    echo(f"Φ_t f at the paper's scales t_i = (i/10)/λ_k, truncated to k = {spec.k} eigenpairs (the paper's "
         f"computation) and exact (the full kernel, o3dheat.heat_flow, tol {r['flow_report'].tol:g}); and truncated "
         "on the log grid 1/λ_k .. 2 ln(100)/λ_2 (the whole range, to nearly constant):")
    echo(f"{'':>5} {'-- paper grid, truncated --':<29} {'-- exact --':<15}  {'-- log grid, truncated -----':<29}")
    echo(f"{'scale':>5} {'t':>10} {'eps_inf':>8} {'crit.':>9} {'eps_inf':>8} {'crit.':>6}  {'t':>10} "
         f"{'eps_inf':>8} {'crit.':>9}")
    for i in range(len(scales)):
        echo(f"{i + 1:>5} {scales[i]:>10.3e} {r['errors'][i]:>8.4f} {counts[1 + i]:>9} "
             f"{r['errors_exact'][i]:>8.4f} {counts[21 + i]:>6}  {log_scales[i]:>10.3e} {r['errors_log'][i]:>8.4f} "
             f"{counts[11 + i]:>9}")
    echo(f"(with k = {spec.k} eigenpairs Φ_t f is band-limited: at t_1 the eigenpairs it drops would keep "
         f"{np.exp(-0.5 * spec.eigenvalues[-1] * scales[0]):.0%} of their weight, so k, not t, smooths; its "
         f"certificate, ‖Φ_t f − exact‖_W / ‖f‖_W <= {bound[0]:.2g} at t_1 .. {bound[-1]:.2g} at t_10. The exact "
         f"kernel smooths by t alone: {counts[21]} -> {counts[30]} critical points across the paper's scales, "
         f"{r['flow_report'].solves} solves on one factor)")


def _label(name, detail, module, what):
    """A stage's name, with its detail and a note when this process compiled the stage's loops (the
    first run of an installation does)."""
    notes = ([detail] if detail else []) + ([f"incl. compiling {what}, once per installation"]
                                             if any_compiled(module) else [])
    return f"{name} ({'; '.join(notes)})" if notes else name


def _stages(spec, timings):
    """Seconds per stage, in the order they ran."""
    return {"load": timings["load"], "resample": timings["resample"],
            _label("assemble", "", "o3dheat.geometry._loops", "the assembly loops"): spec.timings.get("assemble", 0.0),
            "factorize": spec.timings.get("factorize", 0.0),
            "eigensolve": spec.timings.get("solve", 0.0), "smooth (2 x 10 scales)": timings["smooth"],
            _label("exact", "10 scales", "o3dheat.spectral._krylov_loops", "the Krylov loops"): timings["exact"],
            "hks (10 scales)": timings["hks"],
            _label("critical points", "31 fields", "o3dheat.topology", "the topology loops"): timings["critical"],
            "write PLY": timings["write"]}
