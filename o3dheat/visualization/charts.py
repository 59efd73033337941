"""Charts (plain matplotlib): :func:`scale_space`, :func:`persistence_diagram`, :func:`study`, :func:`lifetime_chart`.

:func:`scale_space` draws the variation and critical points across scales, :func:`study` a
robustness study's discrepancies, :func:`lifetime_chart` how long each track of critical points lives.

Nothing is shown on screen: each returns a ``matplotlib.figure.Figure`` (made without pyplot);
save it with ``fig.savefig("name.png")``. They are reachable from :mod:`o3dheat.visualization.plot`
too (``o3dheat.plot.study``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from o3dheat import checks
from o3dheat.errors import MeshError
from o3dheat.spectral import VARIANTS
from o3dheat.topology import PersistenceDiagram, ScaleSpace

from . import _layout

if TYPE_CHECKING:
    import pandas as pd
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from o3dheat.topology import Tracks
    from o3dheat.typing import FieldLike

__all__ = ["scale_space", "persistence_diagram", "study", "study_ranking", "lifetime_chart"]


def _scale_ticks(ax, t):
    """Ticks at the scales themselves (at most ~6 labelled), no minor labels: a log axis over
    less than a decade otherwise writes overlapping minor labels ('0.00010.0002')."""
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    step = max(1, -(-len(t) // 6))
    ticks = t[::step]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xticks(ticks, [f"{x:.2g}" for x in ticks], rotation=30, ha="right", fontsize=8)


def scale_space(ss: ScaleSpace, title: str | None = None) -> Figure:
    """The variation of ``Φ_t f`` and the number of critical points across scales (Fig. 1c,d).

    Parameters
    ----------
    ss : ScaleSpace
        From :func:`o3dheat.scale_space <o3dheat.topology.approximation.scale_space>`.
    title : str, optional
        Written above the chart.

    Returns
    -------
    matplotlib.figure.Figure
        Left: ``‖Φ_{t_{i+1}} f − Φ_{t_i} f‖∞`` and ε∞ against t; right: minima, saddles,
        maxima and their total against t. The stop scale is marked when a criterion held.
        The t axis is logarithmic on a log grid of times; ticks sit at the scales.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.charts as charts
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 10)
    >>> K = o3dheat.HeatKernel(o3dheat.eigensolve(m, k=20))
    >>> fig = charts.scale_space(o3dheat.scale_space(K, m.vertex.positions.numpy()[:, 0]))
    >>> len(fig.axes)
    2
    """
    from matplotlib.figure import Figure

    if not isinstance(ss, ScaleSpace):
        raise MeshError(f"expected a ScaleSpace (from o3dheat.scale_space), got {type(ss).__name__}")
    fig = Figure(figsize=(9.0, 3.9), dpi=100, layout="constrained")
    a1, a2 = fig.subplots(1, 2)
    t = ss.scales
    if len(t) > 1:
        a1.plot(t[1:], ss.variation, "o-", color="black",
                label=r"$\|\Phi_{t_{i+1}} f - \Phi_{t_i} f\|_\infty$ (at $t_{i+1}$)")
    a1.plot(t, ss.errors, "s--", color="gray", label=r"$\epsilon_\infty$ (relative)")
    a1.set_title(r"variation of $\Phi_t f$", fontsize=10)
    a1.legend(fontsize=8)
    c = ss.critical_counts
    if np.all(c >= 0):
        for j, (name, color) in enumerate([("minima", "blue"), ("saddles", "green"), ("maxima", "red")]):
            a2.plot(t, c[:, j], "o-", color=color, label=name)
        a2.plot(t, c.sum(axis=1), "k:", label="total")
        a2.legend(fontsize=8)
        from matplotlib.ticker import MaxNLocator

        a2.yaxis.set_major_locator(MaxNLocator(integer=True))
    a2.set_title(r"critical points of $\Phi_t f$", fontsize=10)
    if ss.stopped:
        for a in (a1, a2):
            a.axvline(t[ss.stop_index], color="orange", lw=1, label="stop")
    for a in (a1, a2):
        if t[0] > 0 and t[-1] > 20 * t[0]:  # a log grid of times
            a.set_xscale("log")
        _scale_ticks(a, t)
        a.set_xlabel("t")
        a.tick_params(axis="y", labelsize=8)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def persistence_diagram(diagram: PersistenceDiagram, f: FieldLike | None = None, title: str | None = None) -> Figure:
    """The persistence diagram of a field's sublevel sets, every point on or above the diagonal.

    One filtration throughout, the sublevel sets ``{f <= c}`` as ``c`` grows, and each point is
    ``(birth, death)`` of one homology class in it:

    - dimension 0 (blue): a component born at a minimum, dying at the saddle where it merges
      with an older one;
    - dimension 1 (red): a loop born at a saddle, dying at the maximum that fills it in. The
      diagram stores these pairs as ``(maximum, saddle)`` (:class:`o3dheat.topology.PersistenceDiagram <o3dheat.topology.diagrams.PersistenceDiagram>`:
      read on superlevel sets, a maximum's cap born at its value and merged at the saddle's,
      birth above death); by the duality of a surface that is the same pair, and drawn here as
      ``(saddle, maximum)``, birth and death exchanged back, it is the 1-dimensional sublevel
      persistence (as gudhi gives it): above the diagonal, at the same distance from it.

    Points near the diagonal are short-lived (noise); the features lie far from it. With ``f``
    the classes that never die (the global minimum of each component, the saddles of its genus
    and boundary, the maximum of a closed component: dimension 2, black) are drawn on a row "∞"
    above the others.

    Parameters
    ----------
    diagram : PersistenceDiagram
        From :func:`o3dheat.persistence <o3dheat.topology.diagrams.persistence>`.
    f : (n,) array_like, optional
        The field, to place the essential classes (their values are not in the diagram).
    title : str, optional
        Written above the diagram.

    Returns
    -------
    matplotlib.figure.Figure
        One axes: birth horizontally, death vertically, the diagonal, a legend saying how each
        dimension reads.

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.charts as charts
    >>> m = o3d.t.geometry.TriangleMesh.create_torus()
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> f = V[:, 0] + 0.05 * np.random.default_rng(0).standard_normal(len(V))
    >>> d = o3dheat.persistence(m, f)
    >>> fig = charts.persistence_diagram(d, f)
    >>> pts = fig.axes[0].collections[1].get_offsets()      # dimension 1, as drawn
    >>> bool(np.all(pts[:, 1] >= pts[:, 0])), bool(np.all(d.intervals(1)[:, 1] <= d.intervals(1)[:, 0]))
    (True, True)
    """
    from matplotlib.figure import Figure

    if not isinstance(diagram, PersistenceDiagram):
        raise MeshError(f"expected a PersistenceDiagram (from o3dheat.persistence), got {type(diagram).__name__}")
    d0 = diagram.intervals(0)
    d1 = diagram.intervals(1)[:, ::-1]  # (maximum, saddle) -> (saddle, maximum): sublevel persistence
    values = np.concatenate([d0.ravel(), d1.ravel()])
    essential = np.zeros((0, 2))
    if f is not None:
        f = np.asarray(checks.values(f), dtype=np.float64).ravel()
        idx = np.asarray(diagram.essential, dtype=np.int64)
        if len(idx) and (idx.max() >= len(f) or not np.all(np.isfinite(f[idx]))):
            raise MeshError("f must be the field of the diagram: one finite value per vertex")
        essential = np.c_[f[idx], np.asarray(diagram.essential_dimension)] if len(idx) else essential
        values = np.concatenate([values, essential[:, 0]])
    lo, hi = (float(values.min()), float(values.max())) if len(values) else (0.0, 1.0)
    pad = 0.04 * (hi - lo or 1.0)
    top = hi + 3 * pad  # the row of the classes that never die
    fig = Figure(figsize=(4.6, 4.6), dpi=100, layout="constrained")
    ax = fig.subplots()
    ax.scatter(d0[:, 0], d0[:, 1], s=10, c="tab:blue", label="dim 0: born at a minimum, dies at a saddle")
    ax.scatter(d1[:, 0], d1[:, 1], s=10, c="tab:red",
               label="dim 1: born at a saddle, dies at a maximum\n(stored as (maximum, saddle): exchanged)")
    ax.plot([lo - pad, top], [lo - pad, top], "k-", lw=0.8)
    ax.set_xlim(lo - pad, top + pad)
    ax.set_ylim(lo - pad, top + pad)
    if len(essential):
        label = "never dies (row ∞; dim 2 black)"
        for dim, color in ((0, "tab:blue"), (1, "tab:red"), (2, "black")):
            e = essential[essential[:, 1] == dim]
            if len(e):
                ax.scatter(e[:, 0], np.full(len(e), top), s=24, c=color, marker="v", label=label)
                label = None
        ax.axhline(top, color="0.6", lw=0.6, ls="--")
        ticks = [t for t in ax.get_yticks() if lo - pad <= t <= hi + pad]
        ax.set_yticks(ticks + [top], [f"{t:.3g}" for t in ticks] + ["∞"])
    ax.set_aspect("equal")
    ax.set(xlabel="birth (f)", ylabel="death (f)")
    ax.set_title(title or "persistence of the sublevel sets of f", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    return fig


def study_ranking(ranked: pd.DataFrame, metric: str = "rel_l2", title: str | None = None) -> Figure:
    """Descriptors and kernels ranked by stability, one panel per resampling kind: horizontal bars
    of the median discrepancy (log scale), the most stable at the top, from
    :func:`o3dheat.pipelines.study.ranking`.

    Parameters
    ----------
    ranked : pandas.DataFrame
        ``ranking(table)``: columns ``kind, rank, descriptor, kernel, median``.
    metric : str
        The metric ranked (the axis label).
    title : str, optional
        Written above the panels.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import pandas as pd, o3dheat.visualization.charts as charts
    >>> r = pd.DataFrame(dict(kind=["jitter"] * 2, rank=[1, 2], descriptor=["si_hks", "wks"],
    ...                       kernel="weighted", median=[0.05, 0.2]))
    >>> [t.get_text() for t in charts.study_ranking(r).axes[0].get_yticklabels()]
    ['si_hks · weighted', 'wks · weighted']
    """
    from matplotlib.figure import Figure

    kinds = list(dict.fromkeys(ranked["kind"]))
    if not kinds:
        raise MeshError("nothing to rank: the study has no successful row")
    rows = max(int((ranked["kind"] == k).sum()) for k in kinds)
    fig = Figure(figsize=(4.2 * len(kinds), 0.6 + 0.22 * rows), layout="constrained")
    floor = max(float(ranked["median"][ranked["median"] > 0].min()) / 3 if (ranked["median"] > 0).any() else 1e-12,
                1e-16)
    for i, kind in enumerate(kinds):
        ax = fig.add_subplot(1, len(kinds), i + 1)
        r = ranked[ranked["kind"] == kind].sort_values("rank")
        colors = [_kernel_color(k) for k in r["kernel"]]
        ax.barh(np.arange(len(r)), np.maximum(r["median"].to_numpy(), floor), color=colors, left=0)
        ax.set_yticks(np.arange(len(r)), [f"{d} · {k}" for d, k in zip(r["descriptor"], r["kernel"], strict=True)],
                      fontsize=7)
        ax.set_ylim(len(r) - 0.5, -0.5)
        ax.set_xscale("log")
        ax.set_title(kind, fontsize=9)
        ax.set_xlabel(f"median {metric}", fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
    fig.suptitle(title or "stability across resamplings (most stable at the top)", fontsize=10)
    return fig


def _kernel_color(kernel):
    """A kernel's colour, as :func:`study` draws it: the paper's black, the others in matplotlib's
    cycle in the order of :data:`o3dheat.spectral.variants.VARIANTS`."""
    names = list(VARIANTS)
    return "gray" if kernel not in names else "black" if names.index(kernel) == 0 else f"C{names.index(kernel) - 1}"


def study(table: pd.DataFrame, descriptor: str = "hks_density", metric: str = "rel_l2",
          title: str | None = None) -> Figure:
    """Discrepancy against the reference sampling vs scale, one line per kernel and one panel per
    resampling kind (averaged over meshes and resamplings of that kind), from
    :func:`o3dheat.robustness_study <o3dheat.pipelines.study.robustness_study>`.

    Line panels share one logarithmic y range (the kinds compare at a glance) and put their
    ticks on the integer scale indices; when some discrepancies are exactly 0 the axis is
    "symlog" (0 at the bottom, linear up to the decade of the smallest non-zero value) so that
    they stay on the chart. "eigenvalues" (scale 0 only) are bars on a linear axis shared by all
    panels. Kernels are coloured in the order of :data:`o3dheat.spectral.variants.VARIANTS` (the paper's
    weighted kernel black).

    Parameters
    ----------
    table : pandas.DataFrame
        The study's table.
    descriptor : str
        Which descriptor to draw ("eigenvalues": one bar per kernel).
    metric : {"rel_l2", "rel_linf"}
        The column drawn: the relative L2 or L∞ discrepancy.
    title : str, optional
        Written above the panels.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import pandas as pd, o3dheat.visualization.charts as charts
    >>> rows = [dict(descriptor="hks_density", error="", kind=k, kernel=kern, scale=s, rel_l2=0.01 * s + e)
    ...         for k in ("decimate", "jitter") for kern, e in (("weighted", 0.0), ("linear", 0.02))
    ...         for s in range(1, 11)]
    >>> fig = charts.study(pd.DataFrame(rows))
    >>> [a.get_yscale() for a in fig.axes], fig.axes[0].get_ylim() == fig.axes[1].get_ylim()
    (['log', 'log'], True)
    """
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    if metric not in ("rel_l2", "rel_linf"):
        raise MeshError(f"metric must be 'rel_l2' or 'rel_linf', got {metric!r}")
    t = table[(table["descriptor"] == descriptor) & (table["error"].fillna("") == "")]
    if t.empty:
        raise MeshError(f"the table has no successful rows for descriptor {descriptor!r}")
    kinds = sorted(t["kind"].unique())
    fig = Figure(figsize=(3.6 * len(kinds) + 0.4, 3.8), dpi=100, layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(kinds), sharey=True))
    # the paper's kernel black, the others in matplotlib's cycle, in the order of variants.VARIANTS
    colors = {v: _kernel_color(v) for v in VARIANTS}
    means = t.groupby(["kind", "kernel", "scale"])[metric].mean()
    bars = bool((t["scale"] == 0).all())
    positive = means[means > 0]
    for ax, kind in zip(axes, kinds, strict=True):
        mean = means.loc[kind].reset_index()
        if bars:
            kernels = list(mean["kernel"])
            ax.bar(kernels, mean[metric], color=[colors.get(k, "gray") for k in kernels])
            ax.tick_params(axis="x", labelrotation=30, labelsize=8)
        else:
            for kern, g in mean.groupby("kernel"):
                ax.plot(g["scale"], g[metric], "o-", color=colors.get(kern, "gray"), label=kern, ms=3)
            ax.set_xlabel("scale i (each kernel's own t_i)")
            ax.xaxis.set_major_locator(MaxNLocator(integer=True, nbins=10))
        ax.set_title(f"{kind}", fontsize=10)
    if bars:
        axes[0].set_ylim(0, float(means.max()) * 1.1 if len(means) else 1.0)  # linear: bars start at 0
    elif not len(positive):  # every discrepancy is 0 (or none is finite): a linear axis from 0
        axes[0].set_ylim(0, 1)
    elif len(positive) < len(means.dropna()):
        # some discrepancies are exactly 0 (e.g. the same number of critical points): a log axis
        # would drop them off the chart; symlog shows them at 0, linear up to the smallest non-zero
        # value's decade, logarithmic above
        lt = 10.0 ** np.floor(np.log10(positive.min()))
        axes[0].set_yscale("symlog", linthresh=lt, linscale=0.4)
        axes[0].set_ylim(0, positive.max() * 1.5)
    else:
        axes[0].set_yscale("log")
        if len(positive):
            axes[0].set_ylim(positive.min() / 1.5, positive.max() * 1.5)  # one range for all panels
    if not bars:  # one legend for every panel, below them: a legend inside would hide points
        handles = {h.get_label(): h for ax in axes for h in ax.get_lines()}
        fig.legend(handles=list(handles.values()), loc="outside lower center", ncols=len(handles), fontsize=8,
                   frameon=False)
    axes[0].set_ylabel(f"{metric} of {descriptor}")
    fig.suptitle(title or f"{descriptor}: discrepancy to the reference sampling", fontsize=11)
    return fig


def _time_positions(times):
    """``(x, zero)``: where each time is drawn on a log axis; ``t = 0`` (only the first can be)
    one grid step (the ratio of the first two positive times) left of the smallest positive
    time, or a decade without a second positive time; ``zero``: whether there is one."""
    x = np.asarray(times, dtype=np.float64).copy()
    zero = bool(len(x) and x[0] <= 0)
    if zero:
        pos = x[x > 0]
        x[0] = pos[0] ** 2 / pos[1] if len(pos) > 1 else (pos[0] / 10 if len(pos) else 1.0)
    return x, zero


def lifetime_chart(tracks: Tracks, ax: Axes | None = None, title: str | None = None) -> Figure:
    """How long each track lives: one horizontal bar per track from the scale it starts at to the
    scale it ends at, on a logarithmic time axis, the longest-lived at the top.

    Bars are coloured by kind (minima blue, saddles green, maxima red); a track alive at the last
    scale runs to the right edge, past the last scale (dotted line), and ends in a black "▶" that
    says it lives on. A track seen at one scale only (a zero-length bar) is marked by a short
    vertical tick. With many tracks (more than 80) the rows are on a log scale of their rank
    (1 at the top): the longest-lived stay readable one by one while the thousands of short
    ones (a noisy field's) show as a block at the bottom.

    **t = 0** (the field itself, as a grid starting at 0 has it) cannot sit on a log axis: it is
    drawn one grid step left of the smallest positive time (the ratio of the first two positive
    times), labelled "0", behind a dashed break line. Bars that start there start at "0".

    Parameters
    ----------
    tracks : Tracks
        From :func:`o3dheat.track_critical_points <o3dheat.topology.tracking.track_critical_points>`.
    ax : matplotlib.axes.Axes, optional
        Draw into this axes (default: a new figure).
    title : str, optional
        Default: how many tracks over how many scales.

    Returns
    -------
    matplotlib.figure.Figure
        The figure of the axes (its first axes is the chart).

    Examples
    --------
    >>> import numpy as np, open3d as o3d, o3dheat, o3dheat.visualization.charts as charts
    >>> m = o3d.t.geometry.TriangleMesh.create_sphere(1.0, 40)
    >>> V = m.vertex.positions.numpy().astype(float)
    >>> f = 0.2 * V[:, 2] + np.exp(-((V[:, 0] - 1) ** 2 + V[:, 1] ** 2) / 0.05)
    >>> t = np.r_[0.0, np.geomspace(1e-3, 1.0, 11)]
    >>> tr = o3dheat.track_critical_points(m, o3dheat.heat_flow(m, f, t), t)
    >>> fig = charts.lifetime_chart(tr)
    >>> ax = fig.axes[0]
    >>> sum(len(c.get_paths()) for c in ax.collections if c.get_gid() == "bars") == len(tr), ax.get_xscale()
    (True, 'log')
    """
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    tr = _layout.check_tracks(tracks)
    p, T = len(tr), len(tr.times)
    x, zero = _time_positions(tr.times)
    step = x[-1] / x[-2] if T > 1 else 10.0
    right = x[-1] * step ** 1.5  # the right edge: past the last scale
    order = _layout.by_lifetime(tr)
    first, last = tr.first[order], tr.last[order]
    kinds = np.asarray(tr.kind)[order]
    alive = last == T - 1
    many = p > 80
    if ax is None:
        fig = Figure(figsize=(7.0, 5.2 if many else min(1.6 + 0.2 * max(p, 1), 7.0)), dpi=100, layout="constrained")
        ax = fig.subplots()
    else:
        fig = ax.figure
    _lifetime_bars(ax, x[first], np.where(alive, right, x[last]), first == last, alive, right,
                   [_layout.KIND_COLORS[k] for k in kinds], many)
    ax.axvline(x[-1], color="0.5", lw=0.8, ls=":")
    ax.set_xscale("log")
    ax.set_xlim(x[0] / step ** 0.5, right * step ** 0.4)
    _lifetime_rows(ax, p, many, order)
    _time_axis(ax, x, zero, T)
    counts = {k: int((kinds == k).sum()) for k in _layout.KIND_COLORS}
    handles = [Line2D([], [], color=_layout.KIND_COLORS[k], lw=6, label=f"{_layout.PLURAL[k]} ({counts[k]:,})")
               for k in _layout.KIND_COLORS]
    handles.append(Line2D([], [], ls="", marker=">", color="black", label=f"lives on ({int(alive.sum()):,})"))
    ax.legend(handles=handles, fontsize=8, loc="lower right", framealpha=0.9)
    ax.set_title(title or f"lifetimes of {p:,} tracks of critical points over {T} scales", fontsize=10)
    ax.tick_params(axis="y", labelsize=8)
    return fig


def _lifetime_bars(ax, start, end, point, alive, right, color, many):
    """The bars from ``start`` to ``end`` (rank 1 at the top), a tick for the tracks at one scale
    (``point``), a "▶" at ``right`` for those alive at the last scale."""
    p = len(start)
    rank = np.arange(1, p + 1)
    fig = ax.figure
    # rows at least 4 pixels high get a white edge: neighbours of one kind stay apart
    height_px = 72.0 * fig.get_figheight() * 0.8 * (np.log((rank + 0.5) / (rank - 0.5)) / np.log(2 * p + 1) if many
                                                     else np.full(p, 1.0 / max(p, 1)))
    apart = height_px >= 4
    from matplotlib.collections import PolyCollection
    from matplotlib.colors import to_rgba_array

    half = 0.5 if many else 0.35
    rgba = to_rgba_array(list(color)) if p else np.zeros((0, 4))
    for sel, lw in ((~apart, 0.0), (apart, 0.6)):  # one artist per kind of edge: thousands of bars draw at once
        if sel.any():
            y0, y1, x0, x1 = rank[sel] - half, rank[sel] + half, start[sel], end[sel]
            boxes = np.stack([np.c_[x0, y0], np.c_[x1, y0], np.c_[x1, y1], np.c_[x0, y1]], axis=1)
            ax.add_collection(PolyCollection(boxes, facecolors=rgba[sel], edgecolors="white", linewidths=lw, gid="bars"))
    if p:
        ax.autoscale_view()
    if point.any():  # zero-length bars: a tick at their one scale
        ax.scatter(start[point], rank[point], marker="|", s=30 if not many else 12, c=np.asarray(color, object)[point],
                   linewidths=1.0)
    if alive.any():
        ax.scatter(np.full(int(alive.sum()), right), rank[alive], marker=">", s=28 if not many else 14, c="black",
                   zorder=3, clip_on=False)


def _lifetime_rows(ax, p, many, order):
    """The rows' axis: ranks on a log scale (``many``), the tracks' indices (up to 30), or ranks."""
    if many:
        ax.set_yscale("log")
    ax.set_ylim(p + 0.5, 0.5)
    if many:
        ax.set_ylabel("tracks by lifetime (rank, log scale)")
    elif p <= 30:
        ax.set_yticks(np.arange(1, p + 1), [str(i) for i in order], fontsize=7)
        ax.set_ylabel("track (its index), longest-lived first")
    else:
        from matplotlib.ticker import MaxNLocator

        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylabel("tracks by lifetime (rank)")


def _time_axis(ax, x, zero, T):
    """The log time axis' ticks at the decades (or the grid's ends), "0" at ``t = 0``'s place with
    a dashed break line."""
    from matplotlib.ticker import FixedLocator, NullFormatter, NullLocator

    pos = x[1:] if zero and T > 1 else x  # the positive times
    ticks, labels = ([x[0]], ["0"]) if zero else ([], [])
    decades = range(int(np.ceil(np.log10(pos[0]) - 1e-9)), int(np.floor(np.log10(pos[-1]) + 1e-9)) + 1)
    if len(decades) >= 2:
        ticks += [10.0 ** d for d in decades]
        labels += [f"$10^{{{d}}}$" for d in decades]
    else:  # less than a decade: the ends of the grid
        ticks += [pos[0], pos[-1]] if len(pos) > 1 else [pos[0]]
        labels += [f"{v:.2g}" for v in ticks[len(labels):]]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.set_xticklabels(labels, fontsize=8)
    ax.xaxis.set_minor_locator(NullLocator())
    ax.xaxis.set_minor_formatter(NullFormatter())
    if zero and T > 1:
        ax.axvline(np.sqrt(x[0] * x[1]), color="0.4", lw=0.8, ls="--")
    ax.set_xlabel("t (log scale" + ("; t = 0 drawn one grid step left of the smallest positive time)" if zero else ")"),
                  fontsize=9)
