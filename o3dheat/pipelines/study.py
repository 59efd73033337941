"""Robustness studies: do descriptors survive when the same shape is sampled differently? (P17)

Entry points: :func:`robustness_study` (meshes and resamplings -> a table of errors) and
:func:`load_config` (its arguments from a TOML file); the measures themselves are computed by
``o3dheat.pipelines._descriptors``, on Dask workers or in-process (:mod:`o3dheat.pipelines.cluster`).

Notes
-----
A study takes meshes and resamplings, computes the same descriptors with several kernels on the
reference mesh and on every resampling, brings the resampled descriptors back to the reference
vertices (:func:`o3dheat.geometry.interpolation.transfer`) and measures how far they moved:

* ``rel_l2 = ‖d − d_ref‖_A / ‖d_ref‖_A``, with the lumped-mass (area) norm of the reference;
* ``rel_linf = ‖d − d_ref‖∞ / ‖d_ref‖∞``.

Kernels (the ``kernel`` column): the variants of :data:`o3dheat.spectral.variants.VARIANTS` (all of them by
default), each the heat kernel of its own eigenproblem ``L x = λ W x``, ``K_t = X D_t Xᵀ W``.
Descriptors (:data:`DESCRIPTORS`): "hks_<form>" for each HKS form of
:data:`o3dheat.spectral.variants.HKS_FORMS` ("hks_density", "hks_paper"), "wks" (the wave kernel
signature at ``max(scales, 2)`` log-energies of the reference's spectrum, Aubry's width, the same
energies on every resampling: the ``t`` column holds them), "si_hks" (the scale-invariant HKS, 8
frequencies, one row each), "smooth_height" (``Φ_t`` of the
height along each mesh's up axis: the argument ``up``), "smooth_curvature" (``Φ_t`` of the FEM mean
curvature), "eigenvalues" (λ_2..λ_k of the kernel's own eigenproblem, one row with scale 0),
"critical_points" (the number of critical points of the smoothed height; both metrics are
``|c − c_ref| / c_ref``) and "track_lifetime" (do the extrema of the smoothed height live as long?
:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>` over the kernel's times on each sampling; at scale j, the 10
extremum tracks of the reference alive at j that live longest (ties: the more persistent at j)
are each matched to the nearest track of the same kind alive at j on the resampling, within 5% of
the reference's bounding-box diagonal; with ``L = t_last / t_j`` the factor of time a track lives
on from j (its last scale capped at the grid's end), the error of a track is
``|log L − log L_ref| / log(t_T / t_j)`` (0 at the last scale), 1 when nothing matched; rel_l2 is
the root mean square of the errors, rel_linf their largest) and "diagram" (the persistence diagram
of the smoothed height at each scale, its finite pairs in sublevel form, against the reference's,
no transfer: they live in value space; rel_l2 the Wasserstein distance of order 1 (gudhi's Hera,
relative error 1e-6), rel_linf the bottleneck distance (gudhi's, exact), each the larger over
dimensions 0 and 1, over the range of the reference's field at that scale). :func:`ranking` ranks
every descriptor and kernel by stability per resampling kind.

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

import csv
import hashlib
import io
import json
import logging
import re
import typing
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from o3dheat.errors import MeshError
from o3dheat.geometry import KINDS, decimate, prepare, up_axis
from o3dheat.io import SAMPLES, atomic_write, atomic_write_text, read_mesh, read_toml, sample_mesh
from o3dheat.spectral import heatflow, variants
from o3dheat.typing import MeshLike, PathLike

from ._descriptors import COLUMNS, DESCRIPTORS, failed, reference, task
from .cluster import progress_bar, session, task_error

__all__ = ["robustness_study", "DESCRIPTORS", "COLUMNS", "load_config", "ranking"]

log = logging.getLogger("o3dheat")

if typing.TYPE_CHECKING:  # annotations only: pandas is imported where the table is made
    import pandas as pd


# ------------------------------------------------------------------------------- bookkeeping
def _slug(text):
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text))


def _task_file(out, mesh_name, res_name):
    return out / "tasks" / f"{_slug(mesh_name)}__{_slug(res_name)}.csv"


def _write_rows(path, rows):
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(COLUMNS)
    w.writerows([[repr(x) if isinstance(x, float) else x for x in row] for row in rows])
    atomic_write_text(path, buf.getvalue())


def _read_rows(path):
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


def robustness_study(meshes: dict[str, MeshLike], resamplings: dict | list | str,
                     kernels: str | Sequence[str] | None = None, descriptors: str | Sequence[str] = DESCRIPTORS,
                     scales: int = 10, k: int = 100, out: PathLike | None = None, scheduler: object = None,
                     progress: bool | None = None, grid: str = "paper", method: str = "spectral",
                     up: str | dict[str, str] = "auto") -> pd.DataFrame:
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
        Keys of :data:`o3dheat.spectral.variants.VARIANTS`; default: all of them.
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
        The scale grid, one of :data:`o3dheat.spectral.variants.GRIDS` (:meth:`o3dheat.HeatKernel.scales <o3dheat.spectral.kernel.HeatKernel.scales>`), on
        each kernel's reference spectrum.
    method : str
        How the smoothed descriptors ("smooth_height", "smooth_curvature", "critical_points") are
        computed, one of :data:`o3dheat.spectral.heatflow.METHODS`: "spectral" (the truncated kernel on
        k eigenpairs, the paper's) or "exact" (the full kernel, :class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`: the
        truncation no longer smooths, and resamplings need no eigensolve for these descriptors).
        The scales stay those of each kernel's reference spectrum either way.
    up : str or dict
        The axis of "smooth_height" (and of the topological descriptors' field), for all meshes or
        per mesh name: "x", "y", "z", or "auto", the rule of :func:`o3dheat.geometry.up.up_axis` (a
        mesh given here has no file: z; :func:`load_config` passes each mesh's own, from its file's
        format: y for the OBJ and PLY samples).

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
    cfg, items = _settings(meshes, resamplings, kernels, descriptors, scales, k, progress, grid, method)
    cfg["up"] = {str(name): up_axis(up.get(name, "auto") if isinstance(up, dict) else up)[0] for name in meshes}
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

    try:
        with session(scheduler if todo else "sequential", warm_up=bool(todo)) as client:
            if out is not None:  # the scheduler is reached: now the folder (none is left by a bad address)
                _record(out, state)
            if client is None:
                _run_here(todo, arrays, cfg, done)
            else:
                _run_on(client, todo, arrays, cfg, done)
    finally:
        if bar is not None:
            bar.close()
    return _table(rows, out)


def _settings(meshes, resamplings, kernels, descriptors, scales, k, progress, grid, method):
    """(the study's configuration, its resamplings as [(name, spec)]) after every check of
    :func:`robustness_study`'s arguments, in its order."""
    if kernels is None:
        kernels = list(variants.VARIANTS)  # read now: a variant defined there is studied too
    kernels = [kernels] if isinstance(kernels, str) else list(kernels)  # one name is a list of one
    descriptors = [descriptors] if isinstance(descriptors, str) else list(descriptors)
    bad = [x for x in kernels if x not in variants.VARIANTS] + [x for x in descriptors if x not in DESCRIPTORS]
    if bad:
        raise MeshError(f"unknown kernels/descriptors {bad}: kernels are {', '.join(variants.VARIANTS)} "
                        f"(o3dheat.spectral.variants.VARIANTS), descriptors {', '.join(DESCRIPTORS)}")
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
    if not isinstance(grid, str) or grid not in variants.GRIDS:
        raise MeshError(f"unknown scale grid {grid!r}: use one of {', '.join(variants.GRIDS)}")
    if not isinstance(method, str) or method not in heatflow.METHODS:
        raise MeshError(f"unknown method {method!r}: use one of {', '.join(heatflow.METHODS)}")
    cfg = {"kernels": kernels, "descriptors": descriptors, "scales": int(scales), "k": int(k), "grid": grid}
    if method != "spectral":  # (a spectral study's folder stays resumable by earlier versions' record)
        cfg["method"] = method
    return cfg, items


def _run_here(todo, arrays, cfg, done):
    """The tasks in this process, each mesh's reference once, before its first task."""
    refs = {}
    for mname, rname, spec in todo:
        if mname not in refs:
            refs[mname] = reference(*arrays[mname], cfg, cfg["up"][str(mname)])
        done(mname, rname, task(mname, rname, spec, refs[mname], cfg))


def _run_on(client, todo, arrays, cfg, done):
    """The tasks on a Dask client: the longest first (a worker that starts one last would finish
    alone), the references before everything (every task of a mesh waits for its own)."""
    from distributed import as_completed  # here: distributed costs ~0.5 s at import, which `import o3dheat` avoids

    needed = sorted({m for m, _, _ in todo})
    order = sorted(todo, key=lambda x: -_cost(x[2], len(arrays[x[0]][0])))
    top = len(order) + 1
    refs = {m: client.submit(reference, *arrays[m], cfg, cfg["up"][str(m)], pure=False, priority=top) for m in needed}
    futures = {client.submit(task, m, r, s, refs[m], cfg, pure=False, priority=len(order) - i):
               (m, r, s) for i, (m, r, s) in enumerate(order)}
    for fut in as_completed(list(futures)):
        m, r, s = futures[fut]
        try:
            result = fut.result()
        except Exception as e:  # the worker died (KilledWorker), was cancelled...
            result = failed(m, r, s["kind"], task_error(e))
        done(m, r, result)


def _table(rows, out):
    """The study's table, sorted; written to ``out`` (csv, and parquet when pyarrow is installed)."""
    import pandas as pd  # here, not at the top: pandas costs ~0.4 s, which `import o3dheat` avoids

    table = pd.DataFrame(rows, columns=COLUMNS)
    table = table.sort_values(["mesh", "resampling", "kernel", "descriptor", "scale"], kind="stable")
    table = table.reset_index(drop=True)
    if out is not None:
        atomic_write_text(out / "study.csv", table.to_csv(index=False, float_format="%.17g"))
        try:
            import pyarrow  # noqa: F401  (optional: the parquet copy only when it is installed)

            atomic_write(out / "study.parquet", lambda fh: table.to_parquet(fh, index=False))
        except ImportError:
            pass
    return table


def _check_config(out, cfg, items, arrays):
    """Refuse to resume a study folder made with other settings (its task files would not fit);
    returns the folder's record (``study.json``) to write (:func:`_record`). Writes nothing."""
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
    try:
        (out / "tasks").mkdir(parents=True, exist_ok=True)
    except OSError as e:  # a file-system failure stays one, naming the folder
        raise type(e)(e.errno, f"cannot create the study folder {out / 'tasks'}: {e.strerror}") from None
    atomic_write_text(out / "study.json", json.dumps(state, indent=1, sort_keys=True))


def load_config(path: PathLike) -> dict:
    r"""A study configuration from TOML: ``meshes``, ``[[resampling]]`` tables and settings.

    ::

        k = 100
        scales = 10
        grid = "paper"                   # one of o3dheat.spectral.variants.GRIDS
        method = "spectral"              # or "exact": the full kernel for the smoothed descriptors
        kernels = ["weighted"]                           # of o3dheat.spectral.variants.VARIANTS (default: all)
        descriptors = ["hks_density", "smooth_height"]   # of DESCRIPTORS (default: all)
        up = "auto"                      # the height's axis: the file format's rule (y for OBJ/PLY), or x/y/z
        [meshes]
        bunny = "builtin:bunny@20000"    # bunny, airplane, bone, cow, torus (@ decimates); or a file path
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
    >>> sorted(kw), kw["kernels"], kw["resamplings"], kw["up"]       # a .ply file: y up
    (['kernels', 'meshes', 'resamplings', 'up'], ['weighted'], [{'kind': 'jitter'}], {'sphere': 'y'})
    """
    path = Path(path)
    data = read_toml(path)
    allowed = {"k", "scales", "grid", "method", "kernels", "descriptors", "meshes", "resampling", "up"}
    unknown = set(data) - allowed
    if unknown:
        raise MeshError(f"{path}: unknown settings {sorted(unknown)}; allowed: {sorted(allowed)}")
    expected = {"k": (int, "an integer"), "scales": (int, "an integer"), "grid": (str, "a string"),
                "method": (str, "a string"), "up": (str, "one of \"auto\", \"x\", \"y\", \"z\""),
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
    meshes, up = {}, {}
    for name, src in (data.get("meshes") or {}).items():
        meshes[name] = _builtin(src) if src.startswith("builtin:") else read_mesh(path.parent / src)
        # the up rule needs the file: a sample's own (the torus is made in Python: z)
        name_of = src.partition(":")[2].partition("@")[0]
        source = (SAMPLES.get(name_of) if src.startswith("builtin:") else path.parent / src)
        up[name] = up_axis(data.get("up", "auto"), source)[0]
    res = data.get("resampling") or []
    if not meshes or not res:
        raise MeshError(f"{path}: needs a [meshes] table and at least one [[resampling]]")
    kw = {key: data[key] for key in ("k", "scales", "grid", "kernels", "descriptors") if key in data}
    return {"meshes": meshes, "resamplings": res, "up": up, **kw}


def _builtin(src):
    """``builtin:NAME[@FACES]``: a sample mesh (:func:`o3dheat.io.samples.sample_mesh`), optionally
    decimated to FACES faces."""
    name, _, size = src.partition(":")[2].partition("@")
    mesh = sample_mesh(name)
    if size:
        try:
            faces = int(size)
        except ValueError:
            raise MeshError(f"{src!r}: the size after @ must be a number of faces") from None
        return decimate(mesh, target_faces=faces).mesh
    return mesh


def ranking(table: pd.DataFrame, metric: str = "rel_l2") -> pd.DataFrame:
    """Every (descriptor, kernel) of a study ranked by stability per resampling kind: the median of
    ``metric`` over the meshes, resamplings of that kind and scales (energies, frequencies), the
    smallest first (rank 1: the most stable).

    The metrics are all relative discrepancies (module docstring), so they compare across
    descriptors, with one caveat stated in ``docs/details/studies.md``: "critical_points" and
    "diagram" measure counts and persistence in value space, the others fields brought back to the
    reference vertices.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`robustness_study`'s table (failed rows are left out).
    metric : {"rel_l2", "rel_linf"}
        The column ranked.

    Returns
    -------
    pandas.DataFrame
        Columns ``kind, rank, descriptor, kernel, median, rows``, sorted by kind then rank.

    Examples
    --------
    >>> import pandas as pd
    >>> from o3dheat.pipelines.study import ranking
    >>> t = pd.DataFrame(dict(kind="jitter", descriptor=["wks", "wks", "si_hks"], kernel="weighted",
    ...                       rel_l2=[0.1, 0.3, 0.05], error=""))
    >>> ranking(t)[["rank", "descriptor", "median"]].values.tolist()
    [[1, 'si_hks', 0.05], [2, 'wks', 0.2]]
    """
    if metric not in ("rel_l2", "rel_linf"):
        raise MeshError(f"metric must be 'rel_l2' or 'rel_linf', got {metric!r}")
    ok = table[table["error"].fillna("") == ""]
    g = ok.groupby(["kind", "descriptor", "kernel"])[metric]
    out = g.median().rename("median").to_frame().join(g.size().rename("rows")).reset_index()
    out = out.sort_values(["kind", "median", "descriptor", "kernel"], kind="stable")
    out.insert(1, "rank", out.groupby("kind").cumcount() + 1)
    return out.reset_index(drop=True)
