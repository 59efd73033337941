"""Figures with matplotlib (headless): fields on meshes with level sets and critical points, and
the variation of the scale hierarchy (the kinds of the paper's Figs. 1–7).

Colours follow the paper: maxima red, minima blue, saddles green. Every function returns a
``matplotlib.figure.Figure`` (save it with ``fig.savefig("name.png")``); nothing is shown on
screen, so they run on servers without a display.
"""

from __future__ import annotations

import numpy as np

from . import checks
from .errors import MeshError
from .fem import _vertex_normals
from .mesh import as_arrays

__all__ = ["field", "fields", "scale_space", "paper_figures", "study"]

CRITICAL_COLORS = {"maxima": "red", "minima": "blue", "saddles": "green"}


def _figure(ncols=1, nrows=1, size=4.0, three_d=True):
    from matplotlib.figure import Figure  # no pyplot: no GUI backend, no global state

    fig = Figure(figsize=(size * ncols, size * nrows), dpi=100)
    axes = [fig.add_subplot(nrows, ncols, i + 1, projection="3d" if three_d else None)
            for i in range(nrows * ncols)]
    return fig, axes


_UP = {"z": [0, 1, 2], "y": [2, 0, 1], "x": [1, 2, 0]}  # cyclic: keeps the orientation


def _upright(V, up):
    if up not in _UP:
        raise MeshError(f"up must be 'x', 'y' or 'z', got {up!r}")
    return V[:, _UP[up]]


def _surface(V, F, level_sets, critical_points):
    """The checked surface, built once per mesh, when level sets or critical points are drawn."""
    from .topology import Surface

    wanted = (level_sets is not None and level_sets is not False) or critical_points is True
    return Surface.from_faces(len(V), F, V) if wanted else None


def _draw(ax, V, F, f, level_sets, critical_points, view, cmap, lo, hi, title, S=None):
    from matplotlib import colormaps
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    from .topology import critical_points as find_critical
    from .topology import level_sets as find_levels

    s = np.clip((f[F].mean(axis=1) - lo) / (hi - lo), 0, 1) if hi > lo else np.full(len(F), 0.5)
    colors = colormaps[cmap](s)
    # a little Lambert shading so the shape reads
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    vn = _vertex_normals(V, F)
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    elev, azim = np.radians(view[0]), np.radians(view[1])
    eye = np.array([np.cos(elev) * np.cos(azim), np.cos(elev) * np.sin(azim), np.sin(elev)])
    colors[:, :3] *= (0.55 + 0.45 * np.abs(n @ eye))[:, None]
    # lines and points are drawn over the surface, only where it faces the viewer
    ax.computed_zorder = False
    facing = vn @ eye >= 0
    ax.add_collection3d(Poly3DCollection(V[F], facecolors=colors, edgecolors="none", linewidths=0, zorder=1))
    if level_sets is not None and level_sets is not False:
        kw = {"count": int(level_sets)} if np.isscalar(level_sets) else {"values": level_sets}
        ls = find_levels(S if S is not None else (V, F), f, **kw)
        P, L = np.asarray(ls.points), np.asarray(ls.lines)
        if len(L):
            from scipy.spatial import cKDTree

            _, near = cKDTree(V).query(P[L].mean(axis=1))
            L = L[facing[near]]
            ax.add_collection3d(Line3DCollection(P[L], colors="black", linewidths=0.6, zorder=2))
    if critical_points is not None and critical_points is not False:
        cp = find_critical(S if S is not None else (V, F), f) if critical_points is True else critical_points
        for kind, color in CRITICAL_COLORS.items():
            idx = getattr(cp, kind)
            idx = idx[facing[idx]]
            if len(idx):
                ax.scatter(*V[idx].T, color=color, s=16, depthshade=False, edgecolors="white",
                           linewidths=0.3, zorder=3)
    lo_v, hi_v = V.min(0), V.max(0)
    pad = 0.02 * np.ptp(V, axis=0).max()
    ax.set_xlim(lo_v[0] - pad, hi_v[0] + pad)
    ax.set_ylim(lo_v[1] - pad, hi_v[1] + pad)
    ax.set_zlim(lo_v[2] - pad, hi_v[2] + pad)
    ax.set_box_aspect(np.ptp(V, axis=0) + 2 * pad, zoom=1.2)  # equal scales on the three axes
    ax.view_init(elev=view[0], azim=view[1])
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=9)


def _field_values(f, n):
    return checks.field(f, n, "the field")


def field(mesh, f, level_sets=10, critical_points=True, view=(20.0, -60.0), cmap="coolwarm",
          title=None, size=5.0, up="z"):
    """A mesh coloured by a field, with its level sets and critical points (paper P16).

    Parameters
    ----------
    mesh : o3d.t.geometry.TriangleMesh, o3d.geometry.TriangleMesh or (V, F) tuple
    f : (n,) array_like
    level_sets : int, sequence of float, or None
        Number of evenly spaced level sets, their values, or None for none.
    critical_points : bool or CriticalPoints
        True computes them (red maxima, blue minima, green saddles); False draws none.
    view : (elevation, azimuth) in degrees
    cmap : str
        Matplotlib colormap; the range is the 2nd–98th percentile of f.
    title : str, optional
    size : float
        Inches.
    up : {"z", "y", "x"}
        The axis drawn vertical (scans often have y up).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import open3d as o3d, o3dheat.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> fig = plot.field(m, m.vertex.positions.numpy()[:, 2], title="height")
    >>> len(fig.axes)
    1
    """
    V, F = as_arrays(mesh)
    f = _field_values(f, len(V))
    V = _upright(V, up)
    lo, hi = np.percentile(f, [2, 98])
    fig, (ax,) = _figure(size=size)
    _draw(ax, V, F, f, level_sets, critical_points, view, cmap, lo, hi, title,
          _surface(V, F, level_sets, critical_points))
    fig.subplots_adjust(0, 0, 1, 0.95 if title else 1)
    return fig


def fields(mesh, F_values, titles=None, ncols=None, level_sets=10, critical_points=True,
           view=(20.0, -60.0), cmap="coolwarm", shared_range=True, size=3.5, suptitle=None, up="z"):
    """Several fields on one mesh side by side (for example ``Φ_t f`` at several scales).

    Parameters
    ----------
    mesh : mesh or (V, F)
    F_values : (n, T) array_like
        One column per panel.
    titles : sequence of str, optional
    ncols : int, optional
        Panels per row (default: all in one row, at most 5).
    level_sets, critical_points, view, cmap, up
        As for :func:`field` (``critical_points`` True or False).
    shared_range : bool
        One colour range for all panels (compare values across scales).
    size : float
        Inches per panel.
    suptitle : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    V, Fc = as_arrays(mesh)
    V = _upright(V, up)
    G = np.asarray(F_values, dtype=np.float64)
    if G.ndim == 1:
        G = G[:, None]
    G = _field_values(G, len(V))
    T = G.shape[1]
    ncols = ncols or min(T, 5)
    nrows = -(-T // ncols)
    fig, axes = _figure(ncols, nrows, size)
    lo, hi = np.percentile(G, [2, 98])
    S = _surface(V, Fc, level_sets, critical_points)
    for i, ax in enumerate(axes):
        if i >= T:
            ax.set_axis_off()
            continue
        if not shared_range:
            lo, hi = np.percentile(G[:, i], [2, 98])
        _draw(ax, V, Fc, G[:, i], level_sets, critical_points, view, cmap, lo, hi,
              titles[i] if titles is not None else None, S)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    fig.subplots_adjust(0, 0, 1, 0.88 if suptitle else (0.93 if titles is not None else 1.0), wspace=0, hspace=0.08)
    return fig


def scale_space(ss, title=None):
    """The variation of ``Φ_t f`` and the number of critical points across scales (Fig. 1c,d).

    Parameters
    ----------
    ss : ScaleSpace
        From :func:`o3dheat.scale_space`.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
        Left: ``‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞`` and ε∞ against t; right: minima, saddles,
        maxima and their total against t. The stop scale is marked when a criterion held.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.plot as plot
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(m, k=20))
    >>> fig = plot.scale_space(o3dheat.scale_space(K, m.vertex.positions.numpy()[:, 0]))
    >>> len(fig.axes)
    2
    """
    from .approximation import ScaleSpace

    if not isinstance(ss, ScaleSpace):
        raise MeshError(f"expected a ScaleSpace (from o3dheat.scale_space), got {type(ss).__name__}")
    fig, (a1, a2) = _figure(2, 1, 4.0, three_d=False)
    t = ss.scales
    if len(t) > 1:
        a1.plot(t[1:], ss.variation, "o-", color="black", label="‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞")
    a1.plot(t, ss.errors, "s--", color="gray", label="ε∞ (relative)")
    a1.set_xlabel("t")
    a1.set_title("variation of Φ_t f", fontsize=10)
    a1.legend(fontsize=8)
    c = ss.critical_counts
    if np.all(c >= 0):
        for j, (name, color) in enumerate([("minima", "blue"), ("saddles", "green"), ("maxima", "red")]):
            a2.plot(t, c[:, j], "o-", color=color, label=name)
        a2.plot(t, c.sum(axis=1), "k:", label="total")
        a2.legend(fontsize=8)
    a2.set_xlabel("t")
    a2.set_title("critical points of Φ_t f", fontsize=10)
    if ss.stopped:
        for a in (a1, a2):
            a.axvline(t[ss.stop_index], color="orange", lw=1)
    if t[0] > 0 and t[-1] > 20 * t[0]:  # a log grid of times
        for a in (a1, a2):
            a.set_xscale("log")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def _fields_up(up, *args, **kwargs):
    return fields(*args, up=up, **kwargs)


def _save(fig, path):
    from .io import atomic_write

    atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=100))


def paper_figures(mesh, out, field=None, k=100, noise=0.1, seed=0, name="mesh", max_faces=30000, up="z"):
    """The kinds of the paper's Figs. 1–7 for one mesh, as PNGs with an ``index.md``.

    Parameters
    ----------
    mesh : Open3D mesh or (V, F)
        Meshes above ``max_faces`` faces are decimated first (drawing cost).
    out : str or Path
        Output folder (created).
    field : (n,) array_like, optional
        The field to study; default the height along the longest axis plus Gaussian noise.
    k : int
        Eigenpairs of the main spectrum (the comparisons use 10 and k).
    noise : float
        Noise standard deviation relative to the range of the height (default field only).
    seed : int
    name : str
        Used in titles.
    max_faces : int
        Larger meshes are decimated to this many faces first (matplotlib draws every face).
    up : {"z", "y", "x"}
        The axis drawn vertical.

    Returns
    -------
    pathlib.Path
        The ``index.md`` written in ``out``.
    """
    from pathlib import Path

    from .approximation import feature_driven
    from .approximation import scale_space as hierarchy
    from .diffusion import diffuse
    from .kernel import HeatKernel, heat_kernel
    from .mesh import prepare
    from .sampling import decimate, transfer
    from .spectrum import eigensolve
    from .topology import Surface, critical_points, persistence, simplify_critical_points

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    V0, F0 = as_arrays(mesh)
    if field is None:
        axis = int(np.argmax(np.ptp(V0, axis=0)))
        h = V0[:, axis]
        f0 = h + noise * np.ptp(h) * np.random.default_rng(seed).standard_normal(len(V0))
    else:
        f0 = _field_values(np.asarray(checks.values(field), dtype=np.float64).reshape(len(V0), -1)[:, 0], len(V0))
    prep = prepare((V0, F0))
    V, F, f = prep.V, prep.F, prep.restrict(f0)
    if len(F) > max_faces:
        Vd, Fd = decimate((V, F), target_faces=max_faces).arrays
        f, V, F = transfer(f, (V, F), Vd), Vd, Fd
    k = min(k, len(V) - 2)
    K = HeatKernel(eigensolve((V, F), k=k))
    K10 = HeatKernel(eigensolve((V, F), k=min(10, k)))
    t = K.scales()
    entries = []

    S = Surface.from_faces(len(V), F, V)

    def count(g):
        return sum(critical_points(S, g).counts)

    # Fig. 1: level sets and critical points across scales, and their variation
    ss = hierarchy(K, f, stop="linf")
    cols = [0, 4, 9]
    titles = [f"f ({count(f)} critical points)"] + [
        f"Φ_t f, t = t{i + 1} ({ss.critical_counts[i].sum()} c.p., ε∞ {ss.errors[i]:.3f})" for i in cols]
    _save(_fields_up(up, (V, F), np.c_[f, ss.fields[:, cols]], titles=titles, ncols=4,
                 suptitle=f"{name}: multi-scale approximation, k = {k} (Fig. 1e-k)"), out / "fig1_scales.png")
    _save(scale_space(ss, title=f"{name}: variation and critical points vs t (Fig. 1c,d)"), out / "fig1_variation.png")
    entries += [("fig1_scales.png", "the field and Φ_t f at the paper's scales t1, t5, t10 with level sets and "
                 "critical points (red maxima, blue minima, green saddles)"),
                ("fig1_variation.png", "‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞, ε∞ and the number of critical points "
                 "against t; the l∞ stop criterion (tolerance 1e-3 ‖f‖∞) "
                 + (f"holds at scale {ss.stop_index + 1}" if ss.stopped else "holds at none of the scales"))]
    # the same on the log grid (1/λ_k .. 2 ln(100)/λ_2): the whole multi-scale range
    sl = hierarchy(K, f, scales=K.scales(10, grid="log"))
    titles = [f"f ({count(f)} critical points)"] + [
        f"Φ_t f, log t{i + 1} = {sl.scales[i]:.3g} ({sl.critical_counts[i].sum()} c.p.)" for i in cols]
    _save(_fields_up(up, (V, F), np.c_[f, sl.fields[:, cols]], titles=titles, ncols=4,
                 suptitle=f"{name}: Φ_t f on the log grid 1/λ_k .. 2 ln(100)/λ_2, k = {k}"),
          out / "fig1_log_scales.png")
    _save(scale_space(sl, title=f"{name}: variation and critical points vs t, log grid"),
          out / "fig1_log_variation.png")
    entries += [("fig1_log_scales.png", "the field and Φ_t f at t1, t5, t10 of the log grid, from 1/λ_k (what k "
                 "eigenpairs resolve) to 2 ln(100)/λ_2 (nearly constant): critical points "
                 f"{sl.critical_counts[0].sum()} -> {sl.critical_counts[-1].sum()}"),
                ("fig1_log_variation.png", "variation, ε∞ and critical points against t on the log grid")]
    # Fig. 2: 10 vs k eigenpairs at two scales
    panels, titles = [], []
    for KK, kk in ((K10, K10.spectrum.k), (K, k)):
        for i in (0, 9):
            ti = KK.scales()[i]
            g = KK.smooth(f, ti)
            panels.append(g)
            titles.append(f"k = {kk}, t{i + 1}: ε∞ {KK.error(f, ti):.3f}, {count(g)} c.p.")
    _save(_fields_up(up, (V, F), np.stack(panels, 1), titles=titles, ncols=4,
                 suptitle=f"{name}: 10 vs {k} eigenpairs (Fig. 2)"), out / "fig2_eigenpairs.png")
    entries.append(("fig2_eigenpairs.png", f"10 vs {k} eigenpairs at the first and last scale: more "
                    "eigenfunctions, smaller ε∞ and more critical points"))
    # Fig. 3: an irregular sampling; the Voronoi kernel (7) and the iterative scheme (8)
    Vi, Fi = decimate((V, F), reduction=0.7).arrays
    fi = transfer(f, (V, F), Vi)
    ki = min(k, len(Vi) - 2)
    Ki, Kv = heat_kernel((Vi, Fi), ki), heat_kernel((Vi, Fi), ki, variant="voronoi")
    ti = Ki.scales()[4]
    d1 = diffuse((Vi, Fi), fi, dt=ti / 10, steps=10, scheme="implicit")
    d2 = diffuse((Vi, Fi), fi, dt=ti / 2, steps=10, scheme="implicit")
    _save(_fields_up(up, (Vi, Fi), np.stack([fi, Kv.smooth(fi, Kv.scales()[4]), Ki.smooth(fi, ti), d1, d2], 1), ncols=5,
                 titles=["f (irregular sampling)", "Voronoi kernel (7), t5", "weighted kernel, t5",
                         "scheme (8), t5", "scheme (8), 5 t5"],
                 suptitle=f"{name}: irregular sampling ({len(Vi)} vertices) (Figs. 3, 6)"),
          out / "fig3_irregular.png")
    entries.append(("fig3_irregular.png", "a curvature-adaptive decimation: the Voronoi kernel of eq. (7), "
                    "the weighted kernel and the implicit time stepping of eq. (8) at two times"))
    # Figs. 4-5: canonic basis functions, linear vs weighted kernel, on the irregular sampling
    Kl = heat_kernel((Vi, Fi), ki, variant="linear")  # its own spectrum (L x = λ x) and its own scales
    c = int(np.argmin(np.linalg.norm(Vi - Vi.mean(0) - [0, 0, np.ptp(Vi[:, 2]) / 2], axis=1)))
    B = np.stack([Kl.canonic_basis(c, Kl.scales()[0]), Kl.canonic_basis(c, Kl.scales()[4]),
                  Ki.canonic_basis(c, Ki.scales()[0]), Ki.canonic_basis(c, Ki.scales()[4])], 1)
    _save(_fields_up(up, (Vi, Fi), B, ncols=4, shared_range=False, critical_points=True,
                 titles=["linear kernel, t1", "linear kernel, t5", "weighted kernel, t1", "weighted kernel, t5"],
                 suptitle=f"{name}: canonic basis Φ_t(e_i) on the irregular sampling (Figs. 4, 5)"),
          out / "fig4_5_canonic.png")
    entries.append(("fig4_5_canonic.png", "the canonic basis function of one vertex with the linear (B := I) and "
                    "the weighted kernel, each at its own scales t1 and t5 (t_i = (i/10)/λ_k of its spectrum)"))
    # Figs. 6-7: feature-driven approximation with all vs simplified critical points
    d = persistence(S, f)
    A_all = simplify_critical_points(S, f, diagram=d)
    A_few = simplify_critical_points(S, f, keep_fraction=0.1, diagram=d)
    ga, _ = feature_driven(K, f, A_all, t[0])
    gf, _ = feature_driven(K, f, A_few, t[0])
    pct = 100.0 * len(A_few) / max(len(A_all), 1)
    _save(_fields_up(up, (V, F), np.stack([f, ga, gf], 1), ncols=3, shared_range=False,
                 titles=["f", f"A = all {len(A_all)} critical points", f"A = δ-simplified ({pct:.0f}%)"],
                 suptitle=f"{name}: feature-driven approximation Φ_t(pr_A f), t1 (Figs. 6, 7)"),
          out / "fig6_7_feature.png")
    entries.append(("fig6_7_feature.png", "the global component Φ_t(pr_A f) with A all the critical points of f "
                    f"and A the most persistent ones (10% of the pairs, {pct:.0f}% of the points)"))
    lines = [f"# o3dheat figures: {name}", "",
             f"{len(V)} vertices, {len(F)} faces; k = {k}; field: "
             + ("given attribute" if field is not None else f"height + {noise:g} noise (seed {seed})"), ""]
    lines += [f"- `{fn}`: {text}" for fn, text in entries]
    index = out / "index.md"
    from .io import atomic_write_text

    atomic_write_text(index, "\n".join(lines) + "\n")
    return index


def study(table, descriptor="hks_density", metric="rel_l2", title=None):
    """Discrepancy against the reference sampling vs scale, one line per kernel and one panel per
    resampling kind (averaged over meshes and resamplings of that kind), from
    :func:`o3dheat.robustness_study`.

    Parameters
    ----------
    table : pandas.DataFrame
        The study's table.
    descriptor : str
        Which descriptor to draw ("eigenvalues": one bar per kernel).
    metric : {"rel_l2", "rel_linf"}
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    if metric not in ("rel_l2", "rel_linf"):
        raise MeshError(f"metric must be 'rel_l2' or 'rel_linf', got {metric!r}")
    t = table[(table["descriptor"] == descriptor) & (table["error"].fillna("") == "")]
    if t.empty:
        raise MeshError(f"the table has no successful rows for descriptor {descriptor!r}")
    kinds = sorted(t["kind"].unique())
    fig, axes = _figure(len(kinds), 1, 3.6, three_d=False)
    colors = {"weighted": "black", "linear": "tab:blue", "voronoi": "tab:orange", "lumped": "tab:green"}
    means = t.groupby(["kind", "kernel", "scale"])[metric].mean()
    positive = means[means > 0]
    lo, hi = (positive.min() / 1.5, positive.max() * 1.5) if len(positive) else (None, None)
    for ax, kind in zip(axes, kinds):
        mean = means.loc[kind].reset_index()
        if (mean["scale"] == 0).all():
            kernels = list(mean["kernel"])
            ax.bar(kernels, mean[metric], color=[colors.get(k, "gray") for k in kernels])
            ax.set_ylim(0, means.max() * 1.1)  # bars on a linear axis, one range for all panels
        else:
            for kern, g in mean.groupby("kernel"):
                ax.plot(g["scale"], g[metric], "o-", color=colors.get(kern, "gray"), label=kern, ms=3)
            ax.set_xlabel("scale i (each kernel's own t_i)")
            ax.set_xticks(sorted(mean["scale"].unique()))
            ax.legend(fontsize=8)
            ax.set_yscale("log")
            if lo is not None:
                ax.set_ylim(lo, hi)  # one range for all panels: kinds compare at a glance
        ax.set_title(f"{kind}", fontsize=10)
        ax.set_ylabel(f"{metric} of {descriptor}")
    fig.suptitle(title or f"{descriptor}: discrepancy to the reference sampling", fontsize=11)
    fig.tight_layout()
    return fig
