"""Figure recipes writing PNGs and an ``index.md``: :func:`paper_figures`, :func:`track_figures`, :func:`study_figures`.

:func:`paper_figures` draws the kinds of the paper's Figs. 1–7 for a mesh, :func:`track_figures`
the critical points followed across scales, :func:`study_figures` a robustness study's charts.

They are built from the library's pieces (:mod:`o3dheat.geometry.sampling`,
:mod:`o3dheat.spectral.kernel`, :mod:`o3dheat.topology`, ...) and drawn by
:mod:`o3dheat.visualization.plot` and :mod:`o3dheat.visualization.charts`; each ``index.md`` says
what its figures show.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.geometry import as_arrays, check_mesh, decimate, height, prepare, transfer, up_axis
from o3dheat.io import atomic_write, atomic_write_text
from o3dheat.pipelines.study import ranking
from o3dheat.spectral import HeatFlow, HeatKernel, diffuse, eigensolve, heat_flow, heat_kernel
from o3dheat.topology import Surface, feature_driven, persistence, simplify_critical_points, track_critical_points
from o3dheat.topology import scale_space as hierarchy

from . import _layout, _panels, charts, plot

if TYPE_CHECKING:
    import pandas as pd

    from o3dheat.typing import FieldLike, MeshLike, PathLike

__all__ = ["paper_figures", "track_figures", "study_figures"]


def _fields(up, *args, suptitle="", **kwargs):
    """plot.fields with ``up`` vertical, said in the title."""
    return plot.fields(*args, up=up, suptitle=f"{suptitle}  [{up} up]", **kwargs)


def _save(fig, path):
    atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=100))


def paper_figures(mesh: MeshLike, out: PathLike, field: FieldLike | None = None, k: int = 100, noise: float = 0.1,
                  seed: int = 0, name: str = "mesh", max_faces: int | None = 30000, up: str = "auto",
                  tracks: bool = False, source: PathLike | None = None,
                  echo: Callable[[str], None] | None = None) -> Path:
    """The kinds of the paper's Figs. 1–7 for one mesh, as PNGs with an ``index.md``; Fig. 1 also
    with the full heat kernel (:class:`o3dheat.HeatFlow <o3dheat.spectral.heatflow.HeatFlow>`), whose hierarchy the truncation hides.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        Meshes above ``max_faces`` faces are decimated first.
    out : str or Path
        Output folder (created).
    field : (n,) array_like, optional
        The field to study; default the height along ``up`` plus Gaussian noise.
    k : int
        Eigenpairs of the main spectrum (the comparisons use 10 and k).
    noise : float
        Noise standard deviation relative to the range of the height (default field only).
    seed : int
        Seed of the default field's noise (results are reproducible).
    name : str
        Used in titles.
    max_faces : int or None
        Larger meshes are decimated to this many faces first (the eigensolves and critical points
        of every panel dominate the time), said through ``echo`` and in ``index.md``; None keeps
        every face.
    up : {"auto", "x", "y", "z"}
        The axis drawn vertical (and of the default field's height): "auto" by the rule of
        :func:`o3dheat.geometry.up.up_axis` (from ``source``); stated in the titles and ``index.md``.
    tracks : bool
        Also the critical points' tracks across scales and their lifetimes (two more PNGs, as
        :func:`track_figures` makes them; the ``o3dheat figure`` command draws them).
    source : str or Path, optional
        The file the mesh was read from (for the up rule).
    echo : callable, optional
        Called with a line of progress per stage (the command prints them).

    Returns
    -------
    pathlib.Path
        The ``index.md`` written in ``out``.

    Examples
    --------
    >>> import tempfile, pathlib, open3d as o3d, o3dheat.visualization.figures as figures
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> sphere = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 8)
    >>> index = figures.paper_figures(sphere, out, k=12)  # doctest: +SKIP
    >>> len(list(out.glob("*.png"))), index.name  # doctest: +SKIP
    (10, 'index.md')

    (Skipped in the test run, which draws them in ``tests/visualization/test_figures.py``: ten figures take
    a few seconds.)
    """
    out = Path(out)
    say = _stopwatch(echo)
    up, why_up = up_axis(up, source)
    if max_faces is not None:
        max_faces = checks.count(max_faces, "max_faces", minimum=100, maximum=10**9)
    V, F, f, about = _prepared(mesh, field, noise, seed, max_faces, up, out, say)
    k = min(k, len(V) - 2)
    K = HeatKernel(eigensolve((V, F), k=k))
    K10 = HeatKernel(eigensolve((V, F), k=min(10, k)))
    say(f"eigensolves ({k} and {K10.spectrum.k} eigenpairs)")
    S = Surface.from_faces(len(V), F, V)
    entries = _fig1(V, F, f, S, K, k, out, name, up)
    say("Fig. 1: scales, the full kernel, the log grid")
    entries += _fig2(V, F, f, S, K, K10, k, out, name, up)
    irregular, more = _fig3(V, F, f, k, out, name, up)
    say("Figs. 2-3: eigenpairs, an irregular sampling")
    entries += more + _fig4_5(*irregular, out, name, up)
    entries += _fig6_7(V, F, S, f, K, out, name, up)
    say("Figs. 4-7: canonic basis, feature-driven approximation")
    if tracks:
        entries += _track_entries(V, F, f, out, name, up, t_max=K.scales(2, grid="log")[-1])
        say("tracks across scales")
    return _index(out, name, f"{len(V)} vertices, {len(F)} faces; k = {k}; drawn with {why_up}" + about, field,
                  noise, seed, entries)


def _stopwatch(echo):
    """``say(text)``: echo ``text`` with the seconds since the start and since the last line."""
    import time

    start = [time.perf_counter()] * 2

    def say(text):
        now = time.perf_counter()
        if echo is not None:
            echo(f"{text} ({now - start[1]:.1f} s)")
        start[1] = now

    return say


def _count(S, g):
    """The critical points of ``g`` as the panels draw them: none of rounding errors on a part
    where ``g`` is constant."""
    return sum(plot.drawn_critical_points(S, g).counts)


def _fig1(V, F, f, S, K, k, out, name, up):
    """Fig. 1: level sets and critical points across scales, and their variation; the same times
    with the full kernel (the hierarchy the truncation hides); the log grid's whole range."""
    t = K.scales()
    entries = []
    ss = hierarchy(K, f, stop="linf")
    se = hierarchy(HeatFlow((V, F)), f, scales=t, stop="linf")
    sl = hierarchy(K, f, scales=K.scales(10, grid="log"))
    panels = (
        (ss, "fig1_scales.png", "fig1_variation.png", lambda i: f"Φ_t f, t = t{i + 1}",
         f"{name}: multi-scale approximation, k = {k} (Fig. 1e-k)", f"{name}: variation and critical points vs t "
         "(Fig. 1c,d)", "the field and Φ_t f at the paper's scales t1, t5, t10 with level sets and critical points "
         "(red maxima, blue minima, green saddles)",
         "‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞, ε∞ and the number of critical points against t; the l∞ stop criterion "
         "(tolerance 1e-3 ‖f‖∞) " + (f"holds at scale {ss.stop_index + 1}" if ss.stopped else
                                    "holds at none of the scales")),
        (se, "fig1_exact_scales.png", "fig1_exact_variation.png", lambda i: f"exact Φ_t f, t{i + 1}",
         f"{name}: the full heat kernel (no truncation) at the paper's scales",
         f"{name}: variation and critical points vs t, full kernel",
         "the field and Φ_t f of the full heat kernel (o3dheat.heat_flow, no eigenpairs) at the same t1, t5, t10: "
         f"critical points {se.critical_counts[0].sum()} -> {se.critical_counts[-1].sum()}, where {k} eigenpairs "
         f"give {ss.critical_counts[0].sum()} -> {ss.critical_counts[-1].sum()} (the truncation, not t, smooths "
         "there)", "variation, ε∞ and critical points against t, full kernel"),
        (sl, "fig1_log_scales.png", "fig1_log_variation.png", lambda i: f"Φ_t f, log t{i + 1} = {sl.scales[i]:.3g}",
         f"{name}: Φ_t f on the log grid 1/λ_k .. 2 ln(100)/λ_2, k = {k}",
         f"{name}: variation and critical points vs t, log grid",
         "the field and Φ_t f at t1, t5, t10 of the log grid, from 1/λ_k (what k eigenpairs resolve) to "
         f"2 ln(100)/λ_2 (nearly constant): critical points {sl.critical_counts[0].sum()} -> "
         f"{sl.critical_counts[-1].sum()}", "variation, ε∞ and critical points against t on the log grid"),
    )
    cols = [0, 4, 9]
    for h, scales_png, variation_png, label, suptitle, chart, about_scales, about_chart in panels:
        titles = [f"f ({_count(S, f)} critical points)"] + [
            f"{label(i)} ({_count(S, h.fields[:, i])} c.p., ε∞ {h.errors[i]:.3f})" for i in cols]
        _save(_fields(up, (V, F), np.c_[f, h.fields[:, cols]], titles=titles, ncols=4, label="f, Φ_t f",
                     suptitle=suptitle), out / scales_png)
        _save(charts.scale_space(h, title=chart), out / variation_png)
        entries += [(scales_png, about_scales), (variation_png, about_chart)]
    return entries


def _fig2(V, F, f, S, K, K10, k, out, name, up):
    """Fig. 2: 10 vs k eigenpairs at two scales."""
    panels, titles = [], []
    for KK, kk in ((K10, K10.spectrum.k), (K, k)):
        for i in (0, 9):
            ti = KK.scales()[i]
            g = KK.smooth(f, ti)
            panels.append(g)
            titles.append(f"k = {kk}, t{i + 1}: ε∞ {KK.error(f, ti):.3f}, {_count(S, g)} c.p.")
    _save(_fields(up, (V, F), np.stack(panels, 1), titles=titles, ncols=4, label="Φ_t f",
                 suptitle=f"{name}: 10 vs {k} eigenpairs (Fig. 2)"), out / "fig2_eigenpairs.png")
    return [("fig2_eigenpairs.png", f"10 vs {k} eigenpairs at the first and last scale: more "
             "eigenfunctions, smaller ε∞ and more critical points")]


def _fig3(V, F, f, k, out, name, up):
    """Fig. 3: an irregular sampling; the Voronoi kernel (7) and the iterative scheme (8).
    Returns ``((Vi, Fi, Ki, ki), entries)``: the sampling and its weighted kernel, for Figs. 4-5."""
    Vi, Fi = decimate((V, F), reduction=0.7).arrays
    fi = transfer(f, (V, F), Vi)
    ki = min(k, len(Vi) - 2)
    Ki, Kv = heat_kernel((Vi, Fi), ki), heat_kernel((Vi, Fi), ki, variant="voronoi")
    ti = Ki.scales()[4]
    d1 = diffuse((Vi, Fi), fi, dt=ti / 10, steps=10, scheme="implicit")
    d2 = diffuse((Vi, Fi), fi, dt=ti / 2, steps=10, scheme="implicit")
    _save(_fields(up, (Vi, Fi), np.stack([fi, Kv.smooth(fi, Kv.scales()[4]), Ki.smooth(fi, ti), d1, d2], 1), ncols=5,
                 label="f, Φ_t f",
                 titles=["f (irregular sampling)", "Voronoi kernel (7), t5", "weighted kernel, t5",
                         "scheme (8), t5", "scheme (8), 5 t5"],
                 suptitle=f"{name}: irregular sampling ({len(Vi)} vertices) (Figs. 3, 6)"),
          out / "fig3_irregular.png")
    return (Vi, Fi, Ki, ki), [("fig3_irregular.png", "a curvature-adaptive decimation: the Voronoi kernel of "
                               "eq. (7), the weighted kernel and the implicit time stepping of eq. (8) at two times")]


def _fig4_5(Vi, Fi, Ki, ki, out, name, up):
    """Figs. 4-5: canonic basis functions, linear vs weighted kernel, on the irregular sampling."""
    Kl = heat_kernel((Vi, Fi), ki, variant="linear")  # its own spectrum (L x = λ x) and its own scales
    a = {"x": 0, "y": 1, "z": 2}[up]  # the vertex nearest the top of the drawing (half-way up from the centre)
    c = int(np.argmin(np.linalg.norm(Vi - Vi.mean(0) - np.eye(3)[a] * np.ptp(Vi[:, a]) / 2, axis=1)))
    B = np.stack([Kl.canonic_basis(c, Kl.scales()[0]), Kl.canonic_basis(c, Kl.scales()[4]),
                  Ki.canonic_basis(c, Ki.scales()[0]), Ki.canonic_basis(c, Ki.scales()[4])], 1)
    _save(_fields(up, (Vi, Fi), B, ncols=4, shared_range=False, critical_points=True, label="Φ_t(e_i)",
                 titles=["linear kernel, t1", "linear kernel, t5", "weighted kernel, t1", "weighted kernel, t5"],
                 suptitle=f"{name}: canonic basis Φ_t(e_i) on the irregular sampling (Figs. 4, 5)"),
          out / "fig4_5_canonic.png")
    return [("fig4_5_canonic.png", "the canonic basis function of one vertex with the linear (B := I) and "
             "the weighted kernel, each at its own scales t1 and t5 (t_i = (i/10)/λ_k of its spectrum)")]


def _fig6_7(V, F, S, f, K, out, name, up):
    """Figs. 6-7: feature-driven approximation with all vs simplified critical points."""
    t = K.scales()
    d = persistence(S, f)
    A_all = simplify_critical_points(S, f, diagram=d)
    A_few = simplify_critical_points(S, f, keep_fraction=0.1, diagram=d)
    ga, _ = feature_driven(K, f, A_all, t[0])
    gf, _ = feature_driven(K, f, A_few, t[0])
    pct = 100.0 * len(A_few) / max(len(A_all), 1)
    _save(_fields(up, (V, F), np.stack([f, ga, gf], 1), ncols=3, shared_range=False, label="f, Φ_t(pr_A f)",
                 titles=["f", f"A = all {len(A_all)} critical points", f"A = δ-simplified ({pct:.0f}%)"],
                 suptitle=f"{name}: feature-driven approximation Φ_t(pr_A f), t1 (Figs. 6, 7)"),
          out / "fig6_7_feature.png")
    return [("fig6_7_feature.png", "the global component Φ_t(pr_A f) with A all the critical points of f "
             f"and A the most persistent ones (10% of the pairs, {pct:.0f}% of the points)")]


def _index(out, name, about, field, noise, seed, entries):
    lines = [f"# o3dheat figures: {name}", "",
             f"{about}; field: " + ("given attribute" if field is not None else f"height along the up axis + {noise:g} noise (seed {seed})"),
             ""]
    lines += [f"- `{fn}`: {text}" for fn, text in entries]
    index = out / "index.md"
    atomic_write_text(index, "\n".join(lines) + "\n")
    return index


def _prepared(mesh, field, noise, seed, max_faces, up, out, say):
    """``(V, F, f, about)``: the mesh and field the figures are made of (the default field: the
    height along ``up`` plus noise), repaired (said), prepared, decimated to ``max_faces`` (said,
    and ``about`` says it for the index); ``out`` created."""
    V0, F0 = as_arrays(mesh)
    if field is None:
        h = height(V0, up)
        f0 = h + noise * np.ptp(h) * np.random.default_rng(seed).standard_normal(len(V0))
    else:
        f0 = checks.field(field, len(V0), "the field")
        if f0.ndim != 1:
            raise MeshError(f"the field must have one value per vertex, shape ({len(V0)},), got {f0.shape}: "
                            "pick a column")
    report = check_mesh((V0, F0))
    if report.non_manifold_edges or report.non_manifold_vertices:  # as plot draws them: repaired, said
        V0, F0, f0 = _layout.repaired(V0, F0, f0, f"{report.non_manifold_edges} non-manifold edges and "
                                    f"{report.non_manifold_vertices} non-manifold vertices", "the figures are made")
    out.mkdir(parents=True, exist_ok=True)
    prep = prepare((V0, F0))
    V, F, f = prep.V, prep.F, prep.restrict(f0)
    about = ""
    if max_faces is not None and len(F) > max_faces:
        Vd, Fd = decimate((V, F), target_faces=max_faces, vertex_map=False).arrays
        about = (f"; decimated from {len(F):,} faces ({len(V):,} vertices) to {len(Fd):,} ({len(Vd):,}) first "
                 "(max_faces, --max-faces none keeps all), the field transferred")
        say(f"decimated {len(F):,} → {len(Fd):,} faces ({len(V):,} → {len(Vd):,} vertices): larger than max_faces "
            f"= {max_faces:,} (--max-faces none keeps every face)")
        f, V, F = transfer(f, (V, F), Vd), Vd, Fd
    return V, F, f, about


#: Scales of the tracks' figures, and how many of the longest-lived tracks the surface shows.
TRACK_SCALES = 40
TRACK_LONGEST = 60


def _track_times(V, F, count, t_max=None):
    """``t = 0`` (the field itself) and ``count - 1`` log-spaced times from the squared mean edge
    length (smoothing over about an edge) to ``2 ln(100) / λ_2`` (Φ_t f nearly constant)."""
    if t_max is None:
        parts = int(_panels.vertex_parts(len(V), F).max()) + 1
        t_max = HeatKernel(eigensolve((V, F), k=min(parts + 3, len(V) - 2))).scales(2, grid="log")[-1]
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    t_min = float(np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1).mean()) ** 2
    if not t_min < t_max / 100:
        t_min = t_max / 1000
    return np.r_[0.0, np.geomspace(t_min, t_max, count - 1)]


def _track_entries(V, F, f, out, name, up, t_max=None, count=TRACK_SCALES, longest=TRACK_LONGEST):
    """Draw the tracks' two figures of ``f``'s heat flow into ``out``; their index entries."""
    t = _track_times(V, F, count, t_max)
    Ft = heat_flow((V, F), f, t)
    parts = _panels.vertex_parts(len(V), F)
    # a part where Φ_t f is constant to rounding (a small one, at late scales): its mean there, as the
    # drawings take it; the tracks born on it then (critical points of the vertices' order) are left out
    flat = np.stack([_panels.flat_parts(Ft[:, j], parts) for j in range(len(t))], 1)  # (parts, T)
    for j in range(len(t)):
        Ft[:, j] = _panels.flattened(Ft[:, j], parts, flat[:, j])
    tr = track_critical_points((V, F), Ft, t)
    born_flat = flat[parts[tr.vertex[np.arange(len(tr)), tr.first]], tr.first]
    tr = tr.subset(~born_flat)
    flat = int(flat.any(axis=1).sum())
    n_scales = tr.last - tr.first + 1
    alive = int((tr.last == len(t) - 1).sum())
    drawn = min(longest, len(tr))
    _save(plot.tracks((V, F), tr, Ft, longest=longest, up=up, label="f",
                      title=f"{name}: critical points of the heat flow Φ_t f across {len(t)} scales"),
          out / "tracks_paths.png")
    _save(charts.lifetime_chart(tr, title=f"{name}: lifetimes of the {len(tr):,} tracks of critical points"),
          out / "tracks_lifetimes.png")
    grid = f"t = 0 and {len(t) - 1} log-spaced times {t[1]:.3g} .. {t[-1]:.3g}"
    return [("tracks_paths.png", f"the critical points of Φ_t f (exact heat flow, o3dheat.heat_flow; {grid}) "
             f"followed across the scales (o3dheat.track_critical_points), the {drawn} longest-lived of "
             f"{len(tr):,} tracks drawn on f: a line through each track's positions (blue minima, green saddles, "
             "red maxima) and a dot where it ends"),
            ("tracks_lifetimes.png", f"one bar per track ({len(tr):,}) from the scale it starts at to the scale it "
             f"ends at, the longest-lived at the top; {int((n_scales == 1).sum()):,} live at one scale only, "
             f"{alive} live on past the last scale (▶); t = 0 is drawn one grid step left of t = {t[1]:.3g} "
             "on the log axis" + (f"; {int(born_flat.sum()):,} tracks born on the {flat} part(s) where Φ_t f "
                                  "becomes constant to rounding (it varies there by at most "
                                  f"{_panels.FLAT_RTOL:g} of its largest magnitude, and is taken as constant "
                                  "there) are left out: critical points of the vertices' order, not of the field"
                                  if born_flat.any() else ""))]


def track_figures(mesh: MeshLike, out: PathLike, field: FieldLike | None = None, noise: float = 0.1, seed: int = 0,
                  name: str = "mesh", max_faces: int | None = 30000, up: str = "auto", count: int = TRACK_SCALES,
                  longest: int = TRACK_LONGEST, source: PathLike | None = None) -> Path:
    """The critical points of a field's heat flow followed across scales: the tracks on the
    surface (:func:`o3dheat.visualization.plot.tracks`, ``tracks_paths.png``) and their lifetimes
    (:func:`o3dheat.visualization.charts.lifetime_chart`, ``tracks_lifetimes.png``), with an ``index.md``.

    The field (as for :func:`paper_figures`) is smoothed by the exact heat flow
    (:func:`o3dheat.heat_flow <o3dheat.spectral.heatflow.heat_flow>`) at ``t = 0`` and ``count - 1`` log-spaced times from the squared
    mean edge length to ``2 ln(100) / λ_2`` (Φ_t f nearly constant), and its critical points
    tracked (:func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`).

    Parameters
    ----------
    mesh, out, field, noise, seed, name, max_faces, up, source
        As for :func:`paper_figures`.
    count : int
        Number of scales (at least 3).
    longest : int
        How many of the longest-lived tracks the surface shows (the chart has every track).

    Returns
    -------
    pathlib.Path
        The ``index.md`` written in ``out``.

    Examples
    --------
    >>> import tempfile, pathlib, open3d as o3d, o3dheat.visualization.figures as figures
    >>> out = pathlib.Path(tempfile.mkdtemp())
    >>> index = figures.track_figures(o3d.t.geometry.TriangleMesh.create_torus(), out, count=12)
    >>> sorted(p.name for p in out.glob("*.png"))
    ['tracks_lifetimes.png', 'tracks_paths.png']
    """
    count = checks.count(count, "count", maximum=1000)
    if count < 3:
        raise MeshError(f"count must be at least 3 scales, got {count}")
    longest = checks.count(longest, "longest")
    out = Path(out)
    up, why_up = up_axis(up, source)
    V, F, f, about = _prepared(mesh, field, noise, seed, max_faces, up, out, lambda text: None)
    entries = _track_entries(V, F, f, out, name, up, count=count, longest=longest)
    return _index(out, name, f"{len(V)} vertices, {len(F)} faces; drawn with {why_up}" + about, field, noise, seed,
                  entries)


def study_figures(table: pd.DataFrame, out: PathLike) -> list[Path]:
    """One plot per descriptor of a robustness study (:func:`o3dheat.visualization.charts.study`), as
    ``study_<descriptor>.png`` in ``out``.

    Parameters
    ----------
    table : pandas.DataFrame
        From :func:`o3dheat.robustness_study <o3dheat.pipelines.study.robustness_study>`; failed rows are left out.
    out : str or Path
        An existing folder.

    Returns
    -------
    list of pathlib.Path
        The PNGs written (none when no task succeeded).

    Examples
    --------
    >>> import tempfile, pathlib, pandas as pd, o3dheat.visualization.figures as figures
    >>> rows = [dict(descriptor="hks_density", error="", kind="jitter", kernel="weighted", scale=s, rel_l2=0.01 * s)
    ...         for s in range(1, 11)]
    >>> [p.name for p in figures.study_figures(pd.DataFrame(rows), tempfile.mkdtemp())]
    ['study_hks_density.png']
    """
    ok = table[table["error"].fillna("") == ""]
    written = []
    for d in sorted(ok["descriptor"].unique()):
        path = Path(out) / f"study_{d}.png"
        _save(charts.study(table, descriptor=d), path)
        written.append(path)
    if len(ok) and ok["descriptor"].nunique() * ok["kernel"].nunique() > 1:  # something to rank
        path = Path(out) / "study_ranking.png"
        _save(charts.study_ranking(ranking(ok)), path)
        written.append(path)
    return written
