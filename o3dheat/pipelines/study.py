"""Robustness studies: do descriptors survive when the same shape is sampled differently? (P17)

A study takes meshes and resamplings, computes the same descriptors with several kernels on the
reference mesh and on every resampling, brings the resampled descriptors back to the reference
vertices (:func:`o3dheat.geometry.sampling.transfer`) and measures how far they moved:

* ``rel_l2 = ‖d − d_ref‖_A / ‖d_ref‖_A``, with the lumped-mass (area) norm of the reference;
* ``rel_linf = ‖d − d_ref‖∞ / ‖d_ref‖∞``.

Kernels (the ``kernel`` column): the variants of :data:`o3dheat.spectral.kernel.VARIANTS` (all of them by
default), each the heat kernel of its own eigenproblem ``L x = λ W x``, ``K_t = X D_t Xᵀ W``.
Descriptors (:data:`DESCRIPTORS`): "hks_<form>" for each HKS form of
:data:`o3dheat.spectral.kernel.HKS_FORMS` ("hks_density", "hks_paper"), "smooth_height" (``Φ_t`` of the
height along the reference's longest axis), "smooth_curvature" (``Φ_t`` of the FEM mean
curvature), "eigenvalues" (λ_2..λ_k of the kernel's own eigenproblem, one row with scale 0),
"critical_points" (the number of critical points of the smoothed height; both metrics are
``|c − c_ref| / c_ref``) and "track_lifetime" (do the extrema of the smoothed height live as long?
:func:`o3dheat.track_critical_points` over the kernel's times on each sampling; at scale j, the 10
extremum tracks of the reference alive at j that live longest (ties: the more persistent at j)
are each matched to the nearest track of the same kind alive at j on the resampling, within 5% of
the reference's bounding-box diagonal; with ``L = t_last / t_j`` the factor of time a track lives
on from j (its last scale capped at the grid's end), the error of a track is
``|log L − log L_ref| / log(t_T / t_j)`` (0 at the last scale), 1 when nothing matched; rel_l2 is
the root mean square of the errors, rel_linf their largest).

Times: each kernel's scales are computed once, from its own spectrum on the reference sampling
(the paper's grid ``t_i = (i/10)/λ_k`` by default, or the log grid), and applied unchanged to
every resampling of that shape: one t per shape and kernel, whatever the sampling, as a user
who picked a scale on one scan and applies it to another. (The "linear" kernel's eigenvalues are
dimensionless and grow with the vertex spacing, so its times are not comparable to the others'.)

Execution: one task per (mesh, resampling) that computes its spectra once; on a local Dask
cluster by default, in-process with ``scheduler="sequential"``, or on any cluster by address
(:mod:`o3dheat.pipelines.cluster`); on Dask the largest resamplings start first, so that no worker is left
alone with a long task at the end.
Each task's rows are written to ``out/tasks/`` as soon as it finishes, so an interrupted study
resumes where it stopped; a failing task becomes a row with its error and does not stop the
study. All computations run with one BLAS thread and one o3dheat thread (the workers are the
parallelism), so a sequential and a distributed run give the same table, bit for bit.
"""

from __future__ import annotations

import json
import logging
import re
import traceback
from pathlib import Path

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.spectral import heatflow, kernel

from .cluster import progress_bar, session, task_error

__all__ = ["robustness_study", "DESCRIPTORS", "COLUMNS", "load_config"]

log = logging.getLogger("o3dheat")

#: what a study measures: one HKS per form of :data:`o3dheat.spectral.kernel.HKS_FORMS`, then the others
DESCRIPTORS = tuple(f"hks_{form}" for form in kernel.HKS_FORMS) + (
    "smooth_height", "smooth_curvature", "eigenvalues", "critical_points", "track_lifetime")
COLUMNS = ["mesh", "resampling", "kind", "kernel", "descriptor", "scale", "t", "rel_l2", "rel_linf",
           "vertices", "error"]


# ------------------------------------------------------------------------------- computation
def _descriptors(V, F, kernels, descriptors, k, times, axis, grid="paper", scales=10, method="spectral"):
    """({(kernel, descriptor): array} on one sampling, {kernel: times}); fields are (n, T).

    Each kernel is built from its own spectrum (:func:`o3dheat.spectral.kernel.heat_kernel`). ``times``
    maps each kernel to its times; None (the reference sampling) takes each kernel's own scales
    (``grid``, ``scales``). With ``method="exact"`` the smoothed fields (and their critical points)
    come from the full kernel (:class:`o3dheat.HeatFlow`); a sampling then needs no spectrum unless
    an HKS, the eigenvalues or its own scales are asked for."""
    from o3dheat.spectral import HeatFlow, fem, heat_kernel
    from o3dheat.topology import Surface, critical_points, track_critical_points

    V, F = _aligned(V), _aligned(F)
    k = min(k, len(V) - 2)
    height = _aligned(V[:, axis])
    curvature = _aligned(fem.mean_curvature(V, F)) if "smooth_curvature" in descriptors else None
    topo = {"critical_points", "track_lifetime"} & set(descriptors)
    surface = Surface.from_faces(len(V), F, V) if topo else None
    out, used = {}, {}
    smooth_only = {"smooth_height", "smooth_curvature", "critical_points", "track_lifetime"}
    for kern in kernels:
        spectral = method == "spectral" or times is None or not set(descriptors) <= smooth_only
        K = heat_kernel((V, F), k=k, variant=kern) if spectral else None
        t = used[kern] = K.scales(scales, grid=grid) if times is None else times[kern]
        S = K if method == "spectral" or not smooth_only & set(descriptors) else HeatFlow((V, F), variant=kern,
                                                                                        cache=False)
        # the smoothed height, once per kernel: a descriptor itself and the field of the topological ones
        needs_height = {"smooth_height", "critical_points", "track_lifetime"} & set(descriptors)
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
    return out, used


def _lifetime_errors(tracks, ref, extent, top=10):
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


def _aligned(a):
    """A C-contiguous copy on a 64-byte boundary: BLAS kernels pick their summation order by the
    address, and arrays that travelled to a Dask worker land anywhere; aligned inputs give
    bit-identical results in every process."""
    a = np.asarray(a)
    buf = np.empty(a.nbytes + 64, np.uint8)
    off = (-buf.ctypes.data) % 64
    out = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


def _reference(V, F, cfg):
    """Reference descriptors, the times, the longest axis and the vertex areas of one mesh; or
    ``{"error": message}``: a failure is a result (each task of the mesh reports it as its row),
    not an exception that Dask would log with its traceback in every worker."""
    from threadpoolctl import threadpool_limits

    from o3dheat.parallel import threads
    from o3dheat.spectral import mass_matrix

    try:
        with threadpool_limits(1), threads(1):
            axis = int(np.argmax(np.ptp(V, axis=0)))
            desc, times = _descriptors(V, F, cfg["kernels"], cfg["descriptors"], cfg["k"], None, axis,
                                       cfg["grid"], cfg["scales"], cfg.get("method", "spectral"))
            areas = np.asarray(mass_matrix(V, F, "lumped").diagonal())
    except Exception as e:
        log.debug("the reference failed: %s", traceback.format_exc())
        return {"error": f"the reference sampling failed: {_one_line(e)}"}
    return {"times": times, "axis": axis, "areas": areas, "descriptors": desc, "V": V, "F": F}


def _one_line(e):
    return f"{type(e).__name__}: {' '.join(str(e).split()) or repr(e)}"


def _failed(mesh_name, res_name, kind, error):
    """The one row of a failed task."""
    return [[mesh_name, res_name, kind, "", "", 0, float("nan"), float("nan"), float("nan"), 0, error]]


def _rel(d, r, a):
    """(mass-weighted relative L2, relative L∞) of d against r, column by column."""
    diff = d - r
    if diff.ndim == 1:
        diff, r = diff[:, None], r[:, None]
    num = np.sqrt(np.einsum("i,it->t", a, diff**2))
    den = np.sqrt(np.einsum("i,it->t", a, r**2))
    l2 = num / np.where(den > 0, den, 1.0)
    inf = np.abs(diff).max(axis=0) / np.where(np.abs(r).max(axis=0) > 0, np.abs(r).max(axis=0), 1.0)
    return l2, inf


def _task(mesh_name, res_name, spec, ref, cfg):
    """Rows of one (mesh, resampling) unit; errors become one row with the message."""
    from threadpoolctl import threadpool_limits

    from o3dheat.geometry import resample, transfer
    from o3dheat.parallel import threads

    kind = spec["kind"]
    if "error" in ref:  # the reference failed: so does every task of its mesh
        return _failed(mesh_name, res_name, kind, ref["error"])
    try:
        with threadpool_limits(1), threads(1):
            params = {key: v for key, v in spec.items() if key not in ("kind", "name")}
            r = resample((ref["V"], ref["F"]), kind, **params)
            desc, _ = _descriptors(r.V, r.F, cfg["kernels"], cfg["descriptors"], cfg["k"], ref["times"], ref["axis"],
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
                    l2, inf = _lifetime_errors(value, base, np.ptp(ref["V"], axis=0))
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                else:
                    back = transfer(value, r, ref["V"])
                    l2, inf = _rel(back, base, ref["areas"])
                    scales, ts = range(1, len(ref["times"][kern]) + 1), ref["times"][kern]
                for s, t, x, y in zip(scales, ts, l2, inf, strict=True):
                    rows.append([mesh_name, res_name, kind, kern, d, int(s), float(t), float(x), float(y),
                                 len(r.V), ""])
            return rows
    except Exception as e:  # a failing task is a result, not the end of the study
        log.debug("task %s/%s failed: %s", mesh_name, res_name, traceback.format_exc())
        return _failed(mesh_name, res_name, kind, _one_line(e))


# ------------------------------------------------------------------------------- bookkeeping
def _slug(text):
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text))


def _task_file(out, mesh_name, res_name):
    return out / "tasks" / f"{_slug(mesh_name)}__{_slug(res_name)}.csv"


def _write_rows(path, rows):
    import csv
    import io as _io

    from o3dheat.io import atomic_write_text

    buf = _io.StringIO()
    w = csv.writer(buf)
    w.writerow(COLUMNS)
    w.writerows([[repr(x) if isinstance(x, float) else x for x in row] for row in rows])
    atomic_write_text(path, buf.getvalue())


def _read_rows(path):
    import csv

    with open(path, newline="") as fh:
        rd = csv.reader(fh)
        header = next(rd)
        if header != COLUMNS:
            raise MeshError(f"{path}: not a task file of this version")
        out = []
        for row in rd:
            m, rname, kind, kern, d, s, t, l2, inf, nv, err = row
            out.append([m, rname, kind, kern, d, int(s), float(t), float(l2), float(inf), int(nv), err])
        return out


def _normalise_resamplings(resamplings):
    """[(name, spec)] from a dict name -> spec, a list of specs with a "name", or kind names
    (``["decimate", "remesh"]``: each kind with the defaults of its function in
    :mod:`o3dheat.geometry.sampling`, named after it)."""
    from o3dheat.geometry import KINDS

    if isinstance(resamplings, str):
        resamplings = [resamplings]
    if isinstance(resamplings, dict):
        items = []
        for name, spec in resamplings.items():
            if isinstance(spec, str):
                spec = {"kind": spec}
            elif isinstance(spec, (tuple, list)) and len(spec) == 2:
                spec = {"kind": spec[0], **spec[1]}
            if not isinstance(spec, dict):
                raise MeshError(f"resampling {name!r}: expected a kind name or a table with a kind, got {spec!r}")
            items.append((str(name), dict(spec)))
    else:
        items = []
        for s in resamplings:
            if isinstance(s, str):
                s = {"kind": s}
            if not isinstance(s, dict):
                raise MeshError(f"a resampling is a kind name or a table with a kind, got {s!r}")
            items.append((str(s.get("name") or s.get("kind")), dict(s)))
    for name, spec in items:
        if spec.get("kind") not in KINDS:
            raise MeshError(f"resampling {name!r}: kind must be one of {', '.join(KINDS)}, got {spec.get('kind')!r}")
    _unique_slugs([n for n, _ in items], "resampling")
    return items


def _unique_slugs(names, what):
    """Refuse names that are equal, or equal once made file names (their task files would mix)."""
    seen = {}
    for n in names:
        s = _slug(n)
        if s in seen:
            raise MeshError(f"{what} names {seen[s]!r} and {n!r} are the same once made file names ({s!r}): "
                            "rename one")
        seen[s] = n


def _cost(spec, n):
    """A rough size (vertices) of a resampling of an n-vertex mesh: only to start the longest
    tasks first."""
    kind = spec.get("kind")
    try:
        if kind == "decimate":
            faces = spec.get("target_faces")
            return faces / 2 if faces else n * (1 - spec.get("reduction", 0.7))
        if kind == "subdivide":
            return n * 4 ** spec.get("iterations", 1)
        if kind == "remesh":
            return n / spec.get("edge_factor", 1.0) ** 2 if spec.get("target_edge_length") is None else n
        if kind == "anisotropic":
            return n * (0.5 / spec.get("coarse", 8.0) ** 2 + 0.5 / spec.get("fine", 0.5) ** 2)
        return float(n)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):  # bad values fail in the task
        return float(n)


def robustness_study(meshes, resamplings, kernels=None, descriptors=DESCRIPTORS, scales=10, k=100,
                     out=None, scheduler=None, progress=None, grid="paper", method="spectral"):
    """Run a robustness study (see the module docstring for what is measured).

    Parameters
    ----------
    meshes : dict
        Name -> mesh (Open3D mesh or (V, F)); each is the reference of its resamplings.
    resamplings : dict or list
        Name -> ``{"kind": "decimate", "reduction": 0.7}`` (or ``("decimate", {...})``, or a kind
        name), or a list of such dicts with a "name", or kind names (``["decimate", "remesh"]``:
        the defaults of each function of :mod:`o3dheat.geometry.sampling`, e.g. ``decimate(reduction=0.7)``,
        ``remesh(edge_factor=1)``); kinds of :data:`o3dheat.geometry.sampling.KINDS`. Names must stay
        distinct once made file names.
    kernels : str or sequence of str, optional
        Keys of :data:`o3dheat.spectral.kernel.VARIANTS`; default: all of them.
    descriptors : sequence of str
        From :data:`DESCRIPTORS`.
    scales : int
        Number of scales per kernel.
    k : int
        Eigenpairs per sampling and kernel (capped at n − 2).
    out : str or Path, optional
        Folder for ``tasks/*.csv`` (one file per finished task: resumable), ``study.csv`` and, when
        pyarrow is installed, ``study.parquet``; created once the scheduler is reached (a bad
        address leaves no folder). None keeps everything in memory (no resume).
    scheduler : None, "sequential", str or distributed.Client
        None: a local Dask cluster with one single-threaded worker process per core;
        "sequential": in this process; "tcp://host:port": an existing cluster; a Client: used
        and left open (:mod:`o3dheat.pipelines.cluster`).
    progress : bool, optional
        A progress bar (default: when stderr is a terminal).
    grid : str
        The scale grid, one of :data:`o3dheat.spectral.kernel.GRIDS` (:meth:`o3dheat.HeatKernel.scales`), on
        each kernel's reference spectrum.
    method : str
        How the smoothed descriptors ("smooth_height", "smooth_curvature", "critical_points") are
        computed, one of :data:`o3dheat.spectral.heatflow.METHODS`: "spectral" (the truncated kernel on
        k eigenpairs, the paper's) or "exact" (the full kernel, :class:`o3dheat.HeatFlow`: the
        truncation no longer smooths, and resamplings need no eigensolve for these descriptors).
        The scales stay those of each kernel's reference spectrum either way.

    Returns
    -------
    pandas.DataFrame
        Columns :data:`COLUMNS`, one row per mesh × resampling × kernel × descriptor × scale,
        sorted; failed tasks have one row with ``error`` set.

    Examples
    --------
    >>> import open3d as o3d, o3dheat
    >>> table = o3dheat.robustness_study({"sphere": o3d.t.geometry.TriangleMesh.create_sphere(1.0, 20)},
    ...                                  {"jitter": {"kind": "jitter", "amount": 0.2}}, kernels=["weighted"],
    ...                                  descriptors=["hks_density"], scales=3, k=20, scheduler="sequential")
    >>> table[["kernel", "descriptor", "scale"]].values.tolist()
    [['weighted', 'hks_density', 1], ['weighted', 'hks_density', 2], ['weighted', 'hks_density', 3]]
    """
    import pandas as pd

    from o3dheat.geometry import prepare

    if kernels is None:
        kernels = list(kernel.VARIANTS)  # read now: a variant defined there is studied too
    kernels = [kernels] if isinstance(kernels, str) else list(kernels)  # one name is a list of one
    descriptors = [descriptors] if isinstance(descriptors, str) else list(descriptors)
    bad = [x for x in kernels if x not in kernel.VARIANTS] + [x for x in descriptors if x not in DESCRIPTORS]
    if bad:
        raise MeshError(f"unknown kernels/descriptors {bad}: kernels are {', '.join(kernel.VARIANTS)} "
                        f"(o3dheat.spectral.kernel.VARIANTS), descriptors {', '.join(DESCRIPTORS)}")
    if not kernels or not descriptors:
        raise MeshError("give at least one kernel and one descriptor")
    if not isinstance(meshes, dict) or not meshes:
        raise MeshError("meshes must be a non-empty dict name -> mesh")
    _unique_slugs([str(m) for m in meshes], "mesh")
    items = _normalise_resamplings(resamplings)
    for value, name, least in ((scales, "scales", 1), (k, "k", 2)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise MeshError(f"{name} must be an integer >= {least}, got {value!r} (scales must be >= 1 and k >= 2)")
    if progress is not None and not isinstance(progress, (bool, np.bool_)):
        raise MeshError(f"progress must be True, False or None, got {progress!r}")
    if not isinstance(grid, str) or grid not in kernel.GRIDS:
        raise MeshError(f"unknown scale grid {grid!r}: use one of {', '.join(kernel.GRIDS)}")
    if not isinstance(method, str) or method not in heatflow.METHODS:
        raise MeshError(f"unknown method {method!r}: use one of {', '.join(heatflow.METHODS)}")
    cfg = {"kernels": kernels, "descriptors": descriptors, "scales": int(scales), "k": int(k), "grid": grid}
    if method != "spectral":  # (a spectral study's folder stays resumable by earlier versions' record)
        cfg["method"] = method
    arrays = {}
    for name, mesh in meshes.items():
        p = prepare(mesh)
        arrays[name] = (p.V, p.F)
    out = Path(out) if out is not None else None
    state = None
    if out is not None:
        if out.exists() and not out.is_dir():
            raise MeshError(f"{out} is a file: the study's output is a folder")
        state = _check_config(out, cfg, items, arrays)  # written once the scheduler is reached
    rows, todo = [], []
    for mname in arrays:
        for rname, spec in items:
            f = _task_file(out, mname, rname) if out is not None else None
            if f is not None and f.exists():
                rows += _read_rows(f)
            else:
                todo.append((mname, rname, spec))
    bar = progress_bar(len(todo), progress)

    def done(mname, rname, result):
        rows.extend(result)
        if out is not None and not any(r[-1] for r in result):  # failures are retried next time
            _write_rows(_task_file(out, mname, rname), result)
        if any(r[-1] for r in result):
            log.warning("task %s / %s failed: %s", mname, rname, result[0][-1])
        if bar is not None:
            bar.update(1)

    needed = sorted({m for m, _, _ in todo})
    try:
        with session(scheduler if todo else "sequential", warm_up=bool(todo)) as client:
            if out is not None:  # the scheduler is reached: now the folder (none is left by a bad address)
                _record(out, state)
            if client is None:
                refs = {}
                for mname, rname, spec in todo:
                    if mname not in refs:
                        refs[mname] = _reference(*arrays[mname], cfg)
                    done(mname, rname, _task(mname, rname, spec, refs[mname], cfg))
            else:
                from distributed import as_completed

                # the longest tasks first (a worker that starts one last would finish alone);
                # the references before everything (every task of a mesh waits for its own)
                order = sorted(todo, key=lambda x: -_cost(x[2], len(arrays[x[0]][0])))
                top = len(order) + 1
                refs = {m: client.submit(_reference, *arrays[m], cfg, pure=False, priority=top) for m in needed}
                futures = {client.submit(_task, m, r, s, refs[m], cfg, pure=False, priority=len(order) - i):
                           (m, r, s) for i, (m, r, s) in enumerate(order)}
                for fut in as_completed(list(futures)):
                    m, r, s = futures[fut]
                    try:
                        result = fut.result()
                    except Exception as e:  # the worker died (KilledWorker), was cancelled...
                        result = _failed(m, r, s["kind"], task_error(e))
                    done(m, r, result)
    finally:
        if bar is not None:
            bar.close()
    table = pd.DataFrame(rows, columns=COLUMNS)
    table = table.sort_values(["mesh", "resampling", "kernel", "descriptor", "scale"], kind="stable")
    table = table.reset_index(drop=True)
    if out is not None:
        from o3dheat.io import atomic_write, atomic_write_text

        atomic_write_text(out / "study.csv", table.to_csv(index=False, float_format="%.17g"))
        try:
            import pyarrow  # noqa: F401

            atomic_write(out / "study.parquet", lambda fh: table.to_parquet(fh, index=False))
        except ImportError:
            pass
    return table


def _check_config(out, cfg, items, arrays):
    """Refuse to resume a study folder made with other settings (its task files would not fit);
    returns the folder's record (``study.json``) to write (:func:`_record`). Writes nothing."""
    import hashlib

    h = hashlib.sha256()
    for name in sorted(arrays):
        V, F = arrays[name]
        h.update(name.encode())
        h.update(np.ascontiguousarray(V).tobytes())
        h.update(np.ascontiguousarray(F).tobytes())
    state = {"config": cfg, "resamplings": {n: s for n, s in items}, "meshes": h.hexdigest()}
    path = out / "study.json"
    if path.exists():
        old = json.loads(path.read_text())
        same_cfg = old.get("config") == state["config"] and old.get("meshes") == state["meshes"]
        clash = [n for n, s in state["resamplings"].items() if n in old.get("resamplings", {})
                 and old["resamplings"][n] != s]
        if not same_cfg or clash:
            raise MeshError(f"{out} holds a study with other settings or meshes; use another folder "
                            "or delete it")
        state["resamplings"] = {**old.get("resamplings", {}), **state["resamplings"]}
    return state


def _record(out, state):
    """The study folder, its ``tasks/`` and its record ``study.json``."""
    from o3dheat.io import atomic_write_text

    try:
        (out / "tasks").mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise MeshError(f"cannot create the study folder {out / 'tasks'}: {e.strerror}") from None
    atomic_write_text(out / "study.json", json.dumps(state, indent=1, sort_keys=True))


def load_config(path):
    r"""A study configuration from TOML: ``meshes``, ``[[resampling]]`` tables and settings.

    ::

        k = 100
        scales = 10
        grid = "paper"                   # one of o3dheat.spectral.kernel.GRIDS
        method = "spectral"              # or "exact": the full kernel for the smoothed descriptors
        kernels = ["weighted"]                           # of o3dheat.spectral.kernel.VARIANTS (default: all)
        descriptors = ["hks_density", "smooth_height"]   # of DESCRIPTORS (default: all)
        [meshes]
        bunny = "builtin:bunny@20000"    # bunny, airplane, bone, torus (@ decimates); or a file path
        [[resampling]]
        name = "decimate-70"
        kind = "decimate"
        reduction = 0.7

    Returns
    -------
    dict
        Keyword arguments of :func:`robustness_study` (meshes loaded).

    Examples
    --------
    >>> import os, tempfile, open3d as o3d, o3dheat
    >>> from o3dheat.pipelines.study import load_config
    >>> d = tempfile.mkdtemp()
    >>> o3dheat.io.write_mesh(os.path.join(d, "s.ply"), o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8))
    >>> with open(os.path.join(d, "study.toml"), "w") as fh:
    ...     _ = fh.write('kernels = ["weighted"]\n[meshes]\nsphere = "s.ply"\n[[resampling]]\nkind = "jitter"\n')
    >>> kw = load_config(os.path.join(d, "study.toml"))
    >>> sorted(kw), kw["kernels"], kw["resamplings"]
    (['kernels', 'meshes', 'resamplings'], ['weighted'], [{'kind': 'jitter'}])
    """
    from o3dheat.io import read_mesh, read_toml

    path = Path(path)
    data = read_toml(path)
    allowed = {"k", "scales", "grid", "method", "kernels", "descriptors", "meshes", "resampling"}
    unknown = set(data) - allowed
    if unknown:
        raise MeshError(f"{path}: unknown settings {sorted(unknown)}; allowed: {sorted(allowed)}")
    expected = {"k": (int, "an integer"), "scales": (int, "an integer"), "grid": (str, "a string"),
                "method": (str, "a string"),
                "kernels": (list, "a list of names"), "descriptors": (list, "a list of names"),
                "meshes": (dict, "a [meshes] table of name = \"file or builtin:NAME\""),
                "resampling": (list, "[[resampling]] tables")}
    for key, (kind, text) in expected.items():
        if key in data and (not isinstance(data[key], kind) or isinstance(data[key], bool)):
            raise MeshError(f"{path}: {key} must be {text}, got {data[key]!r}")
    for key in ("kernels", "descriptors"):
        if not all(isinstance(x, str) for x in data.get(key, [])):
            raise MeshError(f"{path}: {key} must be a list of names, got {data[key]!r}")
    bad = {name: src for name, src in (data.get("meshes") or {}).items() if not isinstance(src, str)}
    if bad:
        raise MeshError(f"{path}: each mesh is a file path or \"builtin:NAME\" (a string), got {bad}")
    if not all(isinstance(r, dict) for r in data.get("resampling", [])):
        raise MeshError(f"{path}: each [[resampling]] is a table with a kind")
    meshes = {}
    for name, src in (data.get("meshes") or {}).items():
        meshes[name] = _builtin(src) if src.startswith("builtin:") else read_mesh(path.parent / src)
    res = data.get("resampling") or []
    if not meshes or not res:
        raise MeshError(f"{path}: needs a [meshes] table and at least one [[resampling]]")
    kw = {key: data[key] for key in ("k", "scales", "grid", "kernels", "descriptors") if key in data}
    return {"meshes": meshes, "resamplings": res, **kw}


def _builtin(src):
    """``builtin:NAME[@FACES]``: a sample mesh (:func:`o3dheat.demo.sample_mesh`), optionally
    decimated to FACES faces."""
    from o3dheat.geometry import decimate
    from o3dheat.io import sample_mesh

    name, _, size = src.partition(":")[2].partition("@")
    mesh = sample_mesh(name)
    if size:
        try:
            faces = int(size)
        except ValueError:
            raise MeshError(f"{src!r}: the size after @ must be a number of faces") from None
        return decimate(mesh, target_faces=faces).mesh
    return mesh
