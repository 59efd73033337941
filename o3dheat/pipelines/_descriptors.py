"""The robustness study's measures: the descriptors of one sampling, the reference's, one task's rows.

Entry points: :func:`reference` (a mesh's descriptors, times, axis and areas) and :func:`task` (the
rows of one resampling against it), run by :func:`o3dheat.pipelines.study.robustness_study`
in-process or on Dask workers; :data:`DESCRIPTORS` and :data:`COLUMNS` (what is measured, the
table's columns). What each descriptor and metric is: :mod:`o3dheat.pipelines.study`.
"""

from __future__ import annotations

import logging
import traceback

import numpy as np

from o3dheat.geometry import resample, transfer
from o3dheat.parallel import blas_one_thread, threads
from o3dheat.spectral import HeatFlow, fem, heat_kernel, mass_matrix, variants
from o3dheat.spectral.signatures import wks_energies
from o3dheat.topology import Surface, critical_points, persistence, track_critical_points

log = logging.getLogger("o3dheat")

#: what a study measures: one HKS per form of :data:`o3dheat.spectral.variants.HKS_FORMS`, then the others
DESCRIPTORS = tuple(f"hks_{form}" for form in variants.HKS_FORMS) + (
    "wks", "si_hks", "smooth_height", "smooth_curvature", "eigenvalues", "critical_points", "track_lifetime",
    "diagram")
#: the descriptors compared without a transfer between the samplings (values, not fields)
UNTRANSFERRED = ("eigenvalues", "critical_points", "track_lifetime", "diagram")
#: SI-HKS frequencies kept by a study
SI_HKS_FREQUENCIES = 8
COLUMNS = ["mesh", "resampling", "kind", "kernel", "descriptor", "scale", "t", "rel_l2", "rel_linf",
           "vertices", "error"]


def compute(V, F, kernels, descriptors, k, times, axis, grid="paper", scales=10, method="spectral"):
    """({(kernel, descriptor): array} on one sampling, {kernel: times}); fields are (n, T).

    Each kernel is built from its own spectrum (:func:`o3dheat.spectral.kernel.heat_kernel`). ``times``
    maps each kernel to its times; None (the reference sampling) takes each kernel's own scales
    (``grid``, ``scales``). With ``method="exact"`` the smoothed fields (and their critical points)
    come from the full kernel (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`); a sampling then needs no spectrum unless
    an HKS, the eigenvalues or its own scales are asked for."""
    V, F = aligned(V), aligned(F)
    k = min(k, len(V) - 2)
    height = aligned(V[:, axis])
    curvature = aligned(fem.mean_curvature(V, F)) if "smooth_curvature" in descriptors else None
    topo = {"critical_points", "track_lifetime", "diagram"} & set(descriptors)
    surface = Surface.from_faces(len(V), F, V) if topo else None
    out, used = {}, {}
    smooth_only = {"smooth_height", "smooth_curvature", "critical_points", "track_lifetime", "diagram"}
    for kern in kernels:
        spectral = method == "spectral" or times is None or not set(descriptors) <= smooth_only
        K = heat_kernel((V, F), k=k, variant=kern) if spectral else None
        t = used[kern] = K.scales(scales, grid=grid) if times is None else times[kern]
        S = K if method == "spectral" or not smooth_only & set(descriptors) else HeatFlow((V, F), variant=kern,
                                                                                        cache=False)
        # the smoothed height, once per kernel: a descriptor itself and the field of the topological ones
        needs_height = {"smooth_height", "critical_points", "track_lifetime", "diagram"} & set(descriptors)
        H = S.smooth(height, t) if needs_height else None
        for d in descriptors:
            if d.startswith("hks_"):
                out[kern, d] = K.hks(t, form=d[len("hks_"):])
            elif d == "smooth_height":
                out[kern, d] = H
            elif d == "smooth_curvature":
                out[kern, d] = S.smooth(curvature, t)
            elif d == "eigenvalues":
                out[kern, d] = K.spectrum.eigenvalues.copy()
            elif d == "critical_points":
                out[kern, d] = np.array([sum(critical_points(surface, H[:, i]).counts)
                                         for i in range(len(t))], dtype=np.float64)
            elif d == "track_lifetime":
                out[kern, d] = track_critical_points(surface, H, t)
            elif d == "wks":  # the reference's log-energies and width on every sampling, as its times
                e, sigma = used[kern, d] = (wks_energies(K, max(scales, 2)) if times is None else times[kern, d])
                e = np.clip(e, *np.log(K.rates[K.rates > 1e-9 * K.rates.max()][[0, -1]]))  # this spectrum's ends
                out[kern, d] = K.wks(e, sigma)
            elif d == "si_hks":
                out[kern, d] = K.si_hks(SI_HKS_FREQUENCIES)
            elif d == "diagram":
                out[kern, d] = [finite_diagram(persistence(surface, H[:, i])) + (float(np.ptp(H[:, i])),)
                                for i in range(len(t))]
    return out, used


def finite_diagram(d):
    """``(dim 0, dim 1)``: the finite pairs of a :class:`~o3dheat.topology.diagrams.PersistenceDiagram` as
    (birth, death) of sublevel persistence: (minimum, saddle) and (saddle, maximum). The essential
    classes (global extrema, the loops of the genus) are left out: every sampling of one surface
    has the same, and their values only restate the field's range."""
    one = d.intervals(1)
    return d.intervals(0), one[:, ::-1].copy()


def diagram_distances(mine, ref):
    """``(Wasserstein, bottleneck)`` of two samplings' diagrams at one scale (:func:`finite_diagram`
    plus the range), each the larger of dimensions 0 and 1 (gudhi's Hera Wasserstein of order 1,
    relative error 1e-6, and its exact bottleneck distance), over the reference field's range."""
    import gudhi
    import gudhi.hera

    span = ref[2] if ref[2] > 0 else 1.0
    w = max(gudhi.hera.wasserstein_distance(a, b, order=1.0, internal_p=np.inf, delta=1e-6)
            for a, b in zip(mine[:2], ref[:2], strict=True))
    bn = max(gudhi.bottleneck_distance(a, b, 0.0) for a, b in zip(mine[:2], ref[:2], strict=True))
    return w / span, bn / span


def lifetime_errors(tracks, ref, extent, top=10):
    """(root mean square, largest) per scale of the "track_lifetime" errors (module docstring) of
    the tracks of a resampling against the reference's."""
    t = ref.times
    radius = 0.05 * float(np.linalg.norm(extent))
    l2, inf = np.zeros(len(t)), np.zeros(len(t))
    for j in range(len(t)):
        span = np.log(t[-1] / t[j])
        alive = np.flatnonzero((ref.vertex[:, j] >= 0) & (ref.kind != "saddle"))
        alive = alive[np.lexsort((ref.vertex[alive, j], -ref.persistence[alive, j], -ref.last[alive]))][:top]
        mine = np.flatnonzero(tracks.vertex[:, j] >= 0)
        err = []
        for a in alive:
            same = mine[tracks.kind[mine] == ref.kind[a]]
            d = np.linalg.norm(tracks.positions_of[tracks.vertex[same, j]] - ref.positions_of[ref.vertex[a, j]], axis=1)
            if not len(d) or d.min() > radius:
                err.append(1.0)
            elif span > 0:
                err.append(abs(np.log(t[tracks.last[same[np.argmin(d)]]] / t[ref.last[a]])) / span)
            else:
                err.append(0.0)
        if err:
            l2[j], inf[j] = np.sqrt(np.mean(np.square(err))), np.max(err)
    return l2, inf


def aligned(a):
    """A C-contiguous copy on a 64-byte boundary: BLAS kernels pick their summation order by the
    address, and arrays that travelled to a Dask worker land anywhere; aligned inputs give
    bit-identical results in every process."""
    a = np.asarray(a)
    buf = np.empty(a.nbytes + 64, np.uint8)
    off = (-buf.ctypes.data) % 64
    out = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


def reference(V, F, cfg, up="z"):
    """Reference descriptors, the times, the up axis ("x", "y" or "z": the height's) and the vertex areas of one mesh; or
    ``{"error": message}``: a failure is a result (each task of the mesh reports it as its row),
    not an exception that Dask would log with its traceback in every worker."""
    try:
        with blas_one_thread(), threads(1):
            axis = "xyz".index(up)
            desc, times = compute(V, F, cfg["kernels"], cfg["descriptors"], cfg["k"], None, axis,
                                       cfg["grid"], cfg["scales"], cfg.get("method", "spectral"))
            areas = np.asarray(mass_matrix((V, F), "lumped").diagonal())
    except Exception as e:
        log.debug("the reference failed: %s", traceback.format_exc())
        return {"error": f"the reference sampling failed: {one_line(e)}"}
    return {"times": times, "axis": axis, "areas": areas, "descriptors": desc, "V": V, "F": F}


def one_line(e):
    return f"{type(e).__name__}: {' '.join(str(e).split()) or repr(e)}"


def failed(mesh_name, res_name, kind, error):
    """The one row of a failed task."""
    return [[mesh_name, res_name, kind, "", "", 0, float("nan"), float("nan"), float("nan"), 0, error]]


def relative_errors(d, r, a):
    """(mass-weighted relative L2, relative L∞) of d against r, column by column."""
    diff = d - r
    if diff.ndim == 1:
        diff, r = diff[:, None], r[:, None]
    num = np.sqrt(np.einsum("i,it->t", a, diff**2))
    den = np.sqrt(np.einsum("i,it->t", a, r**2))
    l2 = num / np.where(den > 0, den, 1.0)
    inf = np.abs(diff).max(axis=0) / np.where(np.abs(r).max(axis=0) > 0, np.abs(r).max(axis=0), 1.0)
    return l2, inf


def task(mesh_name, res_name, spec, ref, cfg):
    """Rows of one (mesh, resampling) unit; errors become one row with the message."""
    kind = spec["kind"]
    if "error" in ref:  # the reference failed: so does every task of its mesh
        return failed(mesh_name, res_name, kind, ref["error"])
    try:
        with blas_one_thread(), threads(1):
            params = {key: v for key, v in spec.items() if key not in ("kind", "name")}
            r = resample((ref["V"], ref["F"]), kind, **params)
            desc, _ = compute(r.V, r.F, cfg["kernels"], cfg["descriptors"], cfg["k"], ref["times"], ref["axis"],
                                   method=cfg.get("method", "spectral"))
            rows = []
            for (kern, d), value in desc.items():
                base = ref["descriptors"][kern, d]
                if d == "eigenvalues":
                    m = min(len(value), len(base))
                    a, b = value[1:m], base[1:m]  # λ_1 = 0
                    l2 = [np.linalg.norm(a - b) / np.linalg.norm(b)]
                    inf = [np.abs(a - b).max() / np.abs(b).max()]
                    scales, ts = [0], [float("nan")]
                elif d == "critical_points":
                    l2 = inf = np.abs(value - base) / np.maximum(base, 1.0)
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                elif d == "track_lifetime":
                    l2, inf = lifetime_errors(value, base, np.ptp(ref["V"], axis=0))
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                elif d == "diagram":  # rel_l2: Wasserstein, rel_linf: bottleneck (an L∞ distance)
                    l2, inf = np.array([diagram_distances(m, b) for m, b in zip(value, base, strict=True)]).T
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                elif d in ("wks", "si_hks"):  # columns: energies, frequencies
                    back = transfer(value, r, ref["V"])
                    l2, inf = relative_errors(back, base, ref["areas"])
                    scales = range(1, value.shape[1] + 1)
                    ts = ref["times"][kern, d][0] if d == "wks" else np.full(value.shape[1], np.nan)
                else:
                    back = transfer(value, r, ref["V"])
                    l2, inf = relative_errors(back, base, ref["areas"])
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                for s, t, x, y in zip(scales, ts, l2, inf, strict=True):
                    rows.append([mesh_name, res_name, kind, kern, d, int(s), float(t), float(x), float(y),
                                 len(r.V), ""])
            return rows
    except Exception as e:  # a failing task is a result, not the end of the study
        log.debug("task %s/%s failed: %s", mesh_name, res_name, traceback.format_exc())
        return failed(mesh_name, res_name, kind, one_line(e))
