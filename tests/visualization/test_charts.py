"""The charts' axes: scale-space ticks, the study's shared and symlog axes, the persistence
diagram above the diagonal, the lifetime chart's log axes (PAPER.md row P16)."""

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import icosphere, torus
from pictures import torus_tracks

import o3dheat
import o3dheat.visualization.charts as charts


def test_scale_space_ticks_sit_on_the_scales():
    V, F = icosphere(2)
    f = V[:, 2] + 0.2 * np.random.default_rng(1).standard_normal(len(V))
    K = o3dheat.HeatKernel(o3dheat.eigensolve((V, F), k=30))
    for grid in ("paper", "log"):
        ss = o3dheat.scale_space(K, f, scales=K.scales(10, grid=grid))
        fig = charts.scale_space(ss, title="Fig. 1c,d")
        fig.canvas.draw()
        for ax in fig.axes:
            labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
            assert 2 <= len(labels) <= 6 and not [t for t in ax.get_xticklabels(minor=True) if t.get_text()]
        counts = fig.axes[1].get_yticks()
        assert np.allclose(counts, np.round(counts))  # critical points are counted in whole numbers


def study_table(descriptor, scales):
    import pandas as pd

    rows = [dict(descriptor=descriptor, error="", kind=k, kernel=kern, scale=s, rel_l2=(0.01 + 0.01 * s) * m)
            for k, m in (("decimate", 1.0), ("jitter", 30.0)) for kern in ("weighted", "linear") for s in scales]
    return pd.DataFrame(rows)


def test_study_axes():
    fig = charts.study(study_table("hks_density", range(1, 11)))
    fig.canvas.draw()
    a, b = fig.axes
    assert a.get_yscale() == b.get_yscale() == "log" and a.get_ylim() == b.get_ylim()  # compared panels
    ticks = a.get_xticks()
    assert np.allclose(ticks, np.round(ticks))  # integer scales: no tick at 1.5
    fig = charts.study(study_table("eigenvalues", [0]), descriptor="eigenvalues")
    a, b = fig.axes
    assert a.get_yscale() == b.get_yscale() == "linear" and a.get_ylim()[0] == 0  # bars never on a log axis
    with pytest.raises(o3dheat.MeshError):
        charts.study(study_table("hks_density", [1]), descriptor="nope")


def test_study_keeps_zero_discrepancies_on_the_chart():
    """Equal critical-point counts give a discrepancy of exactly 0: a log axis would drop those
    points off the chart; the axis becomes symlog and the points sit at 0, in view."""
    t = study_table("critical_points", range(1, 11))
    t.loc[(t["kernel"] == "weighted") & (t["scale"] <= 3), "rel_l2"] = 0.0
    fig = charts.study(t, descriptor="critical_points")
    fig.canvas.draw()
    a = fig.axes[0]
    assert a.get_yscale() == "symlog" and a.get_ylim()[0] == 0
    y = [line.get_ydata() for line in a.get_lines() if line.get_label() == "weighted"][0]
    assert (np.asarray(y) == 0).sum() == 3
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["linear", "weighted"]  # one legend, below
    assert all(ax.get_legend() is None for ax in fig.axes)


def test_a_study_of_zeros_only_is_drawn_at_zero(recwarn):
    t = study_table("critical_points", range(1, 11))
    t["rel_l2"] = 0.0
    fig = charts.study(t, descriptor="critical_points")
    fig.canvas.draw()
    assert fig.axes[0].get_yscale() == "linear" and fig.axes[0].get_ylim() == (0.0, 1.0)
    assert not [w for w in recwarn if "no positive values" in str(w.message)]


def test_persistence_diagram_draws_sublevel_persistence_above_the_diagonal():
    """Dimension 1 is stored as (maximum, saddle) pairs of the superlevel sets, below the
    diagonal; drawn as the sublevel sets' (saddle, maximum), on or above it like dimension 0,
    with a legend that says how each reads; the classes that never die on the row ∞."""
    V, F = torus(1.0, 0.4, 40, 20)
    f = V[:, 0] + 0.1 * np.random.default_rng(0).standard_normal(len(V))
    d = o3dheat.persistence((V, F), f)
    stored = d.intervals(1)
    assert len(stored) > 5 and np.all(stored[:, 1] <= stored[:, 0])  # as stored: below
    fig = charts.persistence_diagram(d, f)
    ax = fig.axes[0]
    dim0, dim1 = (np.asarray(c.get_offsets()) for c in ax.collections[:2])
    np.testing.assert_array_equal(dim0, d.intervals(0))
    np.testing.assert_array_equal(dim1, stored[:, ::-1])  # (saddle, maximum)
    for pts in (dim0, dim1):
        assert np.all(pts[:, 1] >= pts[:, 0])
    np.testing.assert_allclose(dim1[:, 1] - dim1[:, 0], d.persistence[d.dimension == 1])  # the same distance
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts[0].startswith("dim 0: born at a minimum, dies at a saddle")
    assert texts[1].startswith("dim 1: born at a saddle, dies at a maximum")
    essential = np.concatenate([np.asarray(c.get_offsets()) for c in ax.collections[2:]])
    assert len(essential) == len(d.essential) == 4  # minimum, two saddles of the genus, maximum
    assert np.all(essential[:, 1] > max(dim0.max(), dim1.max()))
    assert ax.get_yticklabels()[-1].get_text() == "∞"
    with pytest.raises(o3dheat.MeshError, match="PersistenceDiagram"):
        charts.persistence_diagram(d.intervals(0))


def bars(ax):
    """(x, y, width, height) of each bar of a lifetime chart (drawn as polygon collections)."""
    from matplotlib.collections import PolyCollection

    boxes = [p.vertices[:4] for c in ax.collections if isinstance(c, PolyCollection) for p in c.get_paths()]
    return [SimpleNamespace(x=b[:, 0].min(), y=b[:, 1].min(), w=np.ptp(b[:, 0]), h=np.ptp(b[:, 1])) for b in boxes]


def test_lifetime_chart_one_bar_per_track_on_a_log_axis_with_t0():
    mesh, Ft, tr = torus_tracks()
    fig = charts.lifetime_chart(tr)
    ax = fig.axes[0]
    assert ax.get_xscale() == "log" and len(bars(ax)) == len(tr)
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels[0] == "0"  # t = 0, one grid step left of the first positive time
    x0 = ax.get_xticks()[0]
    assert np.isclose(x0, tr.times[1] ** 2 / tr.times[2]) and ax.get_xlim()[0] < x0
    # bars start at their first scale; the tracks alive at the end run past the last scale
    alive = tr.last == len(tr.times) - 1
    ends = sorted(b.x + b.w for b in bars(ax))
    assert sum(e > tr.times[-1] * 1.01 for e in ends) == alive.sum()
    lives_on = [c for c in ax.collections if c.get_offsets().shape[0] == alive.sum()
                and np.allclose(c.get_offsets()[:, 0], ends[-1])]
    assert lives_on, "a marker says that they live on"
    assert any("lives on" in t.get_text() for t in ax.get_legend().get_texts())
    # the longest-lived at the top (rank 1), sorted by lifetime
    rank = {int(round(b.y + b.h / 2)): b.w for b in bars(ax)}
    widths = [rank[r] for r in sorted(rank)]
    assert widths == sorted(widths, reverse=True)
    # into a given axes; no t = 0: no "0" tick
    from matplotlib.figure import Figure

    _, _, tr2 = torus_tracks(t=(0.01, 0.05, 0.1))
    own = Figure()
    ax2 = own.subplots()
    assert charts.lifetime_chart(tr2, ax=ax2) is own and len(bars(ax2)) == len(tr2)
    assert "0" not in [t.get_text() for t in ax2.get_xticklabels()]


def test_lifetime_chart_of_many_tracks_ranks_on_a_log_axis():
    """A noisy field has thousands of tracks: the rows are a log scale of the rank, so that the
    longest-lived keep rows of their own."""
    V, F = icosphere(4)
    f = V[:, 2] + 0.2 * np.random.default_rng(0).standard_normal(len(V))
    t = np.r_[0.0, np.geomspace(1e-3, 1.0, 12)]
    tr = o3dheat.track_critical_points((V, F), o3dheat.heat_flow((V, F), f, t), t)
    assert len(tr) > 100
    ax = charts.lifetime_chart(tr).axes[0]
    assert ax.get_yscale() == "log" and len(bars(ax)) == len(tr)
    top, bottom = ax.get_ylim()[1], ax.get_ylim()[0]
    assert top < 1 < len(tr) < bottom  # rank 1 at the top
